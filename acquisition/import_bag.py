"""Import one ROS 2 bag (sqlite3 or MCAP) as a trial archive:
`python -m acquisition.import_bag BAG --map=mapping.toml --out=DIR [--fabric=.. --day=.. --trial=.. --condition=.. --session=..] [--resample] [--overwrite]`.

The mapping file names the camera, microphone and joint topics (format in docs/data.md, "From ROS 2
bags") and where the camera's session reference comes from (`reference_topic`, or
`reference = "pre_contact"`: `acquisition.ros_bag`); the trial's fabric, day, trial, condition and
optional session come from its [trial] table, and the flags override it. An archive already in DIR is not replaced without --overwrite. Needs the optional `rosbags` package: pip install -e ".[bags]".
"""

from __future__ import annotations

from pathlib import Path

from absl import flags

from acquisition import mapping_file, ros_bag
from acquisition.recording import RecordingImportError
from fabricjax import cli
from fabricjax import archive
from fabricjax.errors import UserError

FLAGS = flags.FLAGS
flags.DEFINE_string("map", None, "Mapping file (TOML) naming the topics.", required=True)
flags.DEFINE_string("out", None, "Folder to write the trial archive into.", required=True)
flags.DEFINE_integer("fabric", None, "Fabric id (overrides the mapping's trial.fabric_id).")
flags.DEFINE_integer("day", None, "Recording day (overrides trial.day).")
flags.DEFINE_integer("trial", None, "Trial index (overrides trial.trial).")
flags.DEFINE_enum("condition", None, list(archive.CONDITIONS), "Acoustic condition (overrides trial.condition).")
flags.DEFINE_string(
    "session",
    None,
    "Session whose camera reference the trial shares (overrides trial.session; default: day and condition).",
)
flags.DEFINE_bool(
    "resample", False, "Resample microphones not at 48 kHz (scipy.signal.resample_poly; recorded in the meta)."
)
flags.DEFINE_bool("overwrite", False, "Replace an archive of the same fabric, day, trial and condition in --out.")


def main(argv):
    if len(argv) != 2:
        raise UserError("give exactly one bag: python -m acquisition.import_bag BAG --map=mapping.toml --out=DIR")
    mapping = mapping_file.load_mapping(FLAGS.map)
    overrides = {
        "fabric_id": FLAGS.fabric,
        "day": FLAGS.day,
        "trial": FLAGS.trial,
        "condition": FLAGS.condition,
        "session": FLAGS.session,
    }
    trial = mapping_file.trial_fields(mapping, overrides, FLAGS.map)
    result = ros_bag.import_bag(argv[1], mapping, trial, resample=FLAGS.resample)
    path = Path(FLAGS.out) / archive.trial_filename(result.meta)
    if path.exists() and not FLAGS.overwrite:  # two bags with the same [trial] table must not silently become one
        raise RecordingImportError(path, "<file>", "exists (pass --overwrite to replace it)")
    archive.write_archive(path, result)
    gaps = result.meta["import"]["frame_gaps"]
    print(
        f"{path}: {result.n_steps} steps" + (f", {len(gaps)} frame gaps (see meta.import.frame_gaps)" if gaps else "")
    )


if __name__ == "__main__":
    cli.run(main)
