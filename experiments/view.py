"""One trial in Rerun (see fabricjax/inference/view.py for what is logged where).

    python -m experiments.view ARCHIVE                      # opens the Rerun viewer
    python -m experiments.view ARCHIVE --save=trial.rrd     # writes a recording (headless); open it
                                                            # later with `rerun trial.rrd`
    python -m experiments.view ARCHIVE --checkpoint=DIR     # with a streamable model's class
                                                            # probabilities as it slides its window

Needs the optional Rerun SDK: pip install -e ".[viz]".
"""

from absl import flags as absl_flags

from fabricjax import cli
from fabricjax.inference import view

FLAGS = absl_flags.FLAGS
absl_flags.DEFINE_string("save", None, "write the recording to this .rrd file instead of opening the viewer")
absl_flags.DEFINE_string(
    "checkpoint", None, "checkpoint directory of a streamable train_and_evaluate run (audio / proprioception)"
)


def main(argv):
    if len(argv) != 2:
        cli.fail(
            "give exactly one trial archive: python -m experiments.view ARCHIVE [--save=trial.rrd] [--checkpoint=DIR]"
        )
    doc = view.view_archive(argv[1], checkpoint=FLAGS.checkpoint, save=FLAGS.save)
    summary = f"{doc['archive']}: {doc['steps']} steps" + ("" if doc["frames"] else " (no camera frames)")
    if "accuracy_over_decided_steps" in doc:
        acc = doc["accuracy_over_decided_steps"]
        summary += f"; model right on {100 * (acc or 0):.1f} % of {doc['decided_steps']} decided steps"
    print(summary + (f"; wrote {doc['rrd']}" if doc["rrd"] else ""))


if __name__ == "__main__":
    cli.run(main)
