"""What a new recording day changes in each input, and the probe's gap from the training days to it (see fabricjax/studies/day_shift.py).

    python -m experiments.day_shift                     # default preset, into workspace/results/
    python -m experiments.day_shift --results=results   # regenerates the table published in the repository
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies import day_shift

flags.define_preset()
ROWS = absl_flags.DEFINE_list("rows", None, f"comma-separated inputs, from: {', '.join(r.name for r in day_shift.ROWS)} (default: every input)")
flags.define_overrides()


def main(argv):
    del argv
    day_shift.run(preset=absl_flags.FLAGS.preset, rows=ROWS.value, overrides=flags.overrides(), **flags.location_kwargs())


if __name__ == "__main__":
    flags.run(main)
