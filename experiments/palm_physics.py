"""Each sound at each microphone by physics; fabric, day and condition (see fabricjax/studies/diagnostics/palm.py).

    python -m experiments.palm_physics                     # default preset's classes and days, into workspace/results/
    python -m experiments.palm_physics --results=results   # regenerates results/palm_physics.md

Short scenes simulated in this process (nothing is written to the dataset folder); a minute or two on one core.
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import palm

flags.define_preset()
CYCLES = absl_flags.DEFINE_integer("cycles", palm.CYCLES, "rubbing cycles per simulated scene")


def main(argv):
    del argv
    palm.run(preset=absl_flags.FLAGS.preset, cycles=CYCLES.value, where=flags.location())


if __name__ == "__main__":
    flags.run(main)
