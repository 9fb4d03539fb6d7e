"""What Minsight's camera sees of a stroke, on four fabrics and on three days of one (see
fabricjax/studies/diagnostics/camera_frames.py).

    python -m experiments.camera_frames                     # default preset's scenes, into workspace/results/
    python -m experiments.camera_frames --results=results   # regenerates results/camera_frames.{md,png}

Ten frames rendered in this process (nothing is written to the dataset folder); seconds on one core.
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import camera_frames

flags.define_preset()
flags.define_overrides()


def main(argv):
    del argv
    camera_frames.run(preset=absl_flags.FLAGS.preset, overrides=flags.overrides(), where=flags.location())


if __name__ == "__main__":
    flags.run(main)
