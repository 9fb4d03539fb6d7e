"""How closely the JAX Farneback reproduces OpenCV's, and its speed
(see fabricjax/studies/diagnostics/flow_agreement.py).

    python -m experiments.flow_agreement                     # into workspace/results/
    python -m experiments.flow_agreement --results=results   # regenerates results/flow_agreement.md
    python -m experiments.flow_agreement --quick             # one trial and one texture per size

Under a minute on a 2-core laptop (the first run compiles more); its timings are only comparable on an otherwise idle
machine.
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import flow_agreement

FLAGS = absl_flags.FLAGS
absl_flags.DEFINE_bool("quick", False, "one trial and one natural texture per size, timings best of one")


def main(argv):
    del argv
    flow_agreement.run(quick=FLAGS.quick, where=flags.location())


if __name__ == "__main__":
    flags.run(main)
