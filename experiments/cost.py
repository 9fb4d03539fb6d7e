"""What accuracy costs in touch time, training time and inference latency (see fabricjax/studies/diagnostics/cost.py).

python -m experiments.cost --seeds=5     # default preset: 15 points, <= 20 min on 2 CPU cores
python -m experiments.cost --set=seq_len=25 --set=epochs=4   # base point's N, any Config field
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.config import BACKBONES
from fabricjax.studies.diagnostics import cost

FLAGS = absl_flags.FLAGS
absl_flags.DEFINE_integer("seeds", 5, "seeds (0..n-1) trained together per point")
flags.define_preset()
flags.define_overrides()
absl_flags.DEFINE_list(
    "seq_lens", ["25", "50", "100", "200"], "sequence lengths N (steps at 50 Hz), each with every backbone"
)
absl_flags.DEFINE_list("backbones", list(BACKBONES), "backbones; the first is the base point's")
absl_flags.DEFINE_list("widths", ["32", "128"], "model widths varied alone (FFN = 2 x width); empty: none")
absl_flags.DEFINE_list("bandwidths", ["2.5", "24"], "PSD bandwidths [kHz] varied alone; empty: none")
absl_flags.DEFINE_list(
    "modality_sets",
    ["internal+external", "internal", "internal+external+proprio"],
    "modality sets joined by '+'; the first is the base point's, the others are varied alone",
)
absl_flags.DEFINE_bool(
    "paper",
    True,
    "add the paper's configuration (N=200 capped to the trials, attention, width 64, 15 kHz, internal+external)",
)
absl_flags.DEFINE_integer("latency_repeats", 100, "timed predict_one calls per point")


def main(argv):
    del argv
    cost.run(
        n_seeds=FLAGS.seeds,
        preset=FLAGS.preset,
        seq_lens=[int(n) for n in FLAGS.seq_lens],
        backbones=FLAGS.backbones,
        widths=[int(w) for w in FLAGS.widths],
        bandwidths=[float(b) for b in FLAGS.bandwidths],
        modality_sets=[tuple(s.split("+")) for s in FLAGS.modality_sets],
        paper=FLAGS.paper,
        overrides=flags.overrides(),
        latency_repeats=FLAGS.latency_repeats,
        where=flags.location(),
    )


if __name__ == "__main__":
    flags.run(main, cpu_devices=1)  # its latency column is one sequence's: a single device answers fastest
