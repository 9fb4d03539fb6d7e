"""The studies as library functions; `experiments/` holds their thin command lines.

The paper's tables and figures (`paper/`):

    ablation     modality ablation, 13 rows incl. TCN (Table ablation_table) + 9 step-LayerNorm variants
    bandwidth    PSD bandwidth 2.5 / 10 / 15 / 24 kHz (Table bandwidth_classification)
    noise        cafe-noise test set, Wilcoxon against the preceding row (Table new_noise_results)
    properties   property heads on training and holdout fabrics (Table property_perception)
    latents      t-SNE of latents, one point per fabric, from a restored checkpoint (Fig. latent_features)

Our diagnostics beyond the paper (`diagnostics/`):

    probe        a linear probe of each ablation row's inputs: what they carry before any model
    day_shift    per input: the per-trial variation the fabric, the day and the trial explain, and the
                 probe's training-day against new-day accuracy
    decide       restored checkpoints: calibration, when to stop rubbing, unknown fabrics
    cost         accuracy against touch time, training time and inference latency
    sweep        a recipe grid over Config fields on the ablation's rows, best point by mean validation
    palm         the palm microphone by physics: source levels at the palm, day against fabric (no model)
    sensitivity  which simulator estimates each finding depends on: a Morris screening over their ranges
    calibrate    the declared calibrations: each estimate fitted to the one measurement of the paper that pins it
    flow_agreement  how closely the JAX Farneback reproduces OpenCV's flow, and what each costs
    flow_budget     what moves Minsight's imaged wall over a stroke, effect by effect, and what optical flow sees
    camera_frames   what Minsight's camera sees of a stroke: four fabrics and three days of one, one moment
    stream       live classification of one trial (results/stream.json)
    variant      a variant of a training study against its baseline: two results files, row by row

The release tooling (`release/`): what regenerates and checks the published results folder:

    reproduce    every study of the paper's plan in order, skipping those up to date, into REPORT.md
      reproduce_plan    the plan: its studies in order, fitted to recorded data, each step's command
      staleness         which results are not today's: each study's key, stale studies and files, --check
      reproduce_report  REPORT.md: every study of the manifest in one page
      reproduce_readme  README's results block, as data (headline.json) and as Markdown

The speed benchmarks are a package of their own, `fabricjax.bench`; neither imports the other:
what both need lies beneath them (`fabricjax.timing`, `fabricjax.reporting.results_files`).

Each study's `run(...)` trains or measures, writes <study>.md and .json into its results folder
and returns the JSON document. The four training studies of the paper's tables (ablation,
bandwidth, noise, properties) are data: a `runner.Study` of `rows.RowSpec`s (name, the
`Config` fields the row sets, its label, the paper's numbers), run by `runner.run_study`. What
the studies are built of (`machinery/`), one concept per module:

    rows         RowSpec, a row of a study's table; which rows --rows names; --set against a row's fields
    loading      the data a study needs, loaded once for all its rows
    runner       Study and run_study: a training study from its rows to its results files
    row_training named rows -> trained seeds (`train_rows`), each row's recipe grid, in camera order
    trained      what training gives: TrainedRow (a row's seeds' metrics) and TrainingRun
    progress     row i/n with the elapsed time and an ETA
    checkpoints  where a row's models are kept: one folder per row, config, seeds, data and code
    wilcoxon     paired Wilcoxon tests of one trained row against another
    recipe       a row's grid of learning rates and widths, and the point the validation split prefers
    documents    the results layer: every results file's header (command, code, date, machine, data),
                 tables, per-row and per-sample records, atomic writing with the figures listed
    findings     the paper's claims as predicates over per-seed results: a study's checklist
    linear_probe the linear probe: per-sequence summaries of an input, standardised, a logistic regression
    plan         what a study will cost before it starts: disk and time per stage
    results      what a study measured, as a type its page reads back (the ablation's, the probe's)

and what two studies share, so that no study imports another:

    ablation_rows   the ablation's rows, which the probe and the recipe sweep read too
    probing         the probe's rows and its measurement (the probe, the day shift, the sensitivity)
    day_variation   the day shift's rows and shares (the day shift, the sensitivity)
    cafe            the cafe-noise protocol: its rows, splits and seeds (noise, calibrate)
    inference_cost  a trained row's size and latency, the data's step rate (cost, sweep, decide)
    quick_model     one seed of a preset trained once and kept (stream, decide)

The pages (`pages/`): a study's Markdown and figures drawn from its result alone (the ablation's
and the probe's so far), a package the code fingerprint leaves out, so that a page's edit stales
no number.
"""
