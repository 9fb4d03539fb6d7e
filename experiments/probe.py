"""A linear probe per row of the modality ablation: what each input carries before any model (see fabricjax/studies/probe.py).

    python -m experiments.probe                     # default preset, into workspace/results/
    python -m experiments.probe --results=results   # regenerates the table published in the repository
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies import probe

flags.define_preset()
ROWS = absl_flags.DEFINE_list("rows", None, f"comma-separated rows, from: {', '.join(r.name for r in probe.ROWS)} (default: every row)")
flags.define_overrides()


def main(argv):
    del argv
    probe.run(preset=absl_flags.FLAGS.preset, rows=ROWS.value, overrides=flags.overrides(), **flags.location_kwargs())


if __name__ == "__main__":
    flags.run(main)
