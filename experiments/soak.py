"""The install check run back to back (see fabricjax/studies/release/soak.py).

python -m experiments.soak --results=results   # regenerates results/soak.md: 50 runs each way
python -m experiments.soak --runs=6            # a short soak, into workspace/results/
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.release import soak

FLAGS = absl_flags.FLAGS
absl_flags.DEFINE_integer("runs", soak.RUNS, "runs of the install check each way (as processes, in one process)")


def main(argv):
    del argv
    if FLAGS.runs < 1:
        raise flags.UserError(f"--runs={FLAGS.runs}: at least one run")
    soak.run(runs=FLAGS.runs, where=flags.location())


if __name__ == "__main__":
    flags.run(main)
