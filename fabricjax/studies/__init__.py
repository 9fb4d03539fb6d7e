"""The paper's experiments as library functions; `experiments/` holds their thin command lines.

    ablation     modality ablation, 13 rows incl. TCN (Table ablation_table)
    bandwidth    PSD bandwidth 2.5 / 10 / 15 / 24 kHz (Table bandwidth_classification)
    noise        cafe-noise test set, Wilcoxon against the preceding row (Table new_noise_results)
    properties   property heads on training and holdout fabrics (Table property_perception)
    latents      t-SNE of per-trial mean latents from a restored checkpoint (Fig. latent_features)
    bench        every speed benchmark side by side (results/bench.json, the README's table)
    stream       live classification of one trial (results/stream.json)

Each module's `run(...)` trains, writes results/<study>.md and .json and returns the JSON document.
"""
