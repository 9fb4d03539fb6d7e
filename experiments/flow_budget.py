"""What moves Minsight's imaged wall over a stroke, effect by effect, and what optical flow sees of it
(see fabricjax/studies/diagnostics/flow_budget.py).

    python -m experiments.flow_budget                     # default preset's fabrics, into workspace/results/
    python -m experiments.flow_budget --results=results   # regenerates results/flow_budget.{md,json}

Frames rendered in this process (nothing is written to the dataset folder); minutes on two cores.
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import flow_budget

flags.define_preset()
flags.define_overrides()


def main(argv):
    del argv
    flow_budget.run(preset=absl_flags.FLAGS.preset, overrides=flags.overrides(), where=flags.location())


if __name__ == "__main__":
    flags.run(main)
