"""Write a preset's simulated dataset (archives + index.json), resuming where a run stopped.

python -m experiments.simulate --preset=default [--streams=audio,proprio,images] [--workdir=...]
"""

from __future__ import annotations

from absl import flags

from fabricjax import cli, presets
from fabricjax.sim import ensure_dataset

FLAGS = flags.FLAGS
flags.DEFINE_enum("preset", "default", sorted(presets.PRESETS), "dataset preset (fabricjax/presets.py)")
flags.DEFINE_list("streams", ["audio", "proprio", "images"], "streams to record (audio and proprio are required)")
flags.DEFINE_string("workdir", None, "workspace root (default: $FABRICJAX_WORKDIR or ./workspace)")
flags.DEFINE_integer("workers", None, "simulation processes (default: one per core)")
flags.DEFINE_integer("seed", 0, "simulator seed")


def main(argv):
    del argv
    folder = ensure_dataset(
        FLAGS.preset, FLAGS.workdir, tuple(FLAGS.streams), progress=True, workers=FLAGS.workers, seed=FLAGS.seed
    )
    print(f"dataset ready: {folder}")


if __name__ == "__main__":
    cli.run(main)
