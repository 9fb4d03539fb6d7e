"""Live classification of one trial at 50 Hz
(fabricjax/studies/diagnostics/stream.py; streaming: fabricjax/inference/live.py)

    python -m experiments.stream                                  # quick default-preset model, first test trial
    python -m experiments.stream --archive=PATH --checkpoint=DIR  # any trial, any streamable checkpoint
    python -m experiments.stream --realtime=false                 # as fast as possible
    python -m experiments.stream --print_every=10                 # also every 10th step's prediction
    python -m experiments.stream --view                           # watch it in Rerun (pip install -e ".[viz]")
    python -m experiments.stream --view_save=stream.rrd           # or keep it as a Rerun recording
    python -m experiments.stream --set=modalities=internal,proprio --set=epochs=4   # another quick model

Without --checkpoint a one-seed model of --preset is trained on first use (about a minute on the
default preset) and checkpointed under the workspace; later runs restore it.
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import stream

FLAGS = absl_flags.FLAGS
absl_flags.DEFINE_string(
    "archive", None, "trial archive to replay (default: the first test-day trial of the model's dataset)"
)
absl_flags.DEFINE_string(
    "checkpoint", None, "checkpoint directory of a train_and_evaluate run (default: a quick model of --preset)"
)
flags.define_preset()
flags.define_overrides()
absl_flags.DEFINE_bool("realtime", True, "replay at 50 Hz; false: as fast as possible")
absl_flags.DEFINE_integer(
    "print_every", 0, "also print every k-th step's prediction (default 0: the summary only)", lower_bound=0
)
absl_flags.DEFINE_bool(
    "view", False, "stream the trial's sensors and each step's prediction, confidence and latency to the Rerun viewer"
)
absl_flags.DEFINE_string("view_save", None, "log what --view shows to this .rrd file instead (no viewer needed)")


def main(argv):
    del argv
    stream.run(
        archive_path=FLAGS.archive,
        checkpoint_dir=FLAGS.checkpoint,
        preset=FLAGS.preset,
        overrides=flags.overrides(),
        realtime=FLAGS.realtime,
        print_every=FLAGS.print_every,
        view=FLAGS.view,
        view_save=FLAGS.view_save,
        where=flags.location(),
    )


if __name__ == "__main__":
    flags.run(main, cpu_devices=1)  # one sequence at a time: a single device answers fastest
