"""Faults injected into the code-keyed caches (see fabricjax/studies/diagnostics/faults.py).

python -m experiments.faults --results=results   # regenerates results/faults.md
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import faults

FLAGS = absl_flags.FLAGS
absl_flags.DEFINE_string("load", None, "internal: one load of a case's sequences, folder,workdir,during[,other_code]")


def main(argv):
    del argv
    if FLAGS.load:
        faults.load_once(*faults.parse_load(FLAGS.load))
    else:
        faults.run(where=flags.location())


if __name__ == "__main__":
    flags.run(main)
