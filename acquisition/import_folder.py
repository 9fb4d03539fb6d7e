"""Import one trial folder of WAV + CSV + video as a trial archive:
`python -m acquisition.import_folder TRIAL_DIR --out=DIR --fabric=4 --day=1 --trial=0 --reference=reference.png [--condition=lab] [--session=..] [--resample]`.

The folder holds `internal.wav` and `external.wav`, `joints.csv` and `camera.avi` (or `camera/*.png`
with `frames.csv`), laid out as docs/data.md describes; alignment and
errors are those of the bag importer (`acquisition.alignment`); another rig's folder is a one-line
error naming every missing file and pointing to `acquisition.import_manifest --rig`. The camera's
session reference is `--reference`: a file relative to TRIAL_DIR, or `pre_contact` (with
`--reference_frames`) for the trial's first frames (`acquisition.hand_folder`); without it the
import is a one-line error, before anything is read or written."""

from __future__ import annotations

from pathlib import Path

from absl import flags

from acquisition import hand_folder, mapping_file
from acquisition.alignment import parse_reference
from fabricjax import cli
from fabricjax import archive
from fabricjax.errors import UserError

FLAGS = flags.FLAGS
flags.DEFINE_string("out", None, "Folder to write the trial archive into.", required=True)
flags.DEFINE_integer("fabric", None, "Fabric id.")
flags.DEFINE_integer("day", None, "Recording day.")
flags.DEFINE_integer("trial", None, "Trial index.")
flags.DEFINE_enum("condition", "lab", list(archive.CONDITIONS), "Acoustic condition.")
flags.DEFINE_string("session", None, "Session whose camera reference the trial shares (default: day and condition).")
flags.DEFINE_string(
    "reference",
    None,
    "The camera's session reference: a file relative to TRIAL_DIR (image, video or .npy), or pre_contact.",
)
flags.DEFINE_integer(
    "reference_frames", None, "With --reference=pre_contact: how many of the trial's first frames (default 5)."
)
flags.DEFINE_bool(
    "resample", False, "Resample WAV files not at 48 kHz (scipy.signal.resample_poly; recorded in the meta)."
)


def main(argv):
    if len(argv) != 2:
        raise UserError("give exactly one trial folder: python -m acquisition.import_folder TRIAL_DIR --out=DIR")
    overrides = {
        "fabric_id": FLAGS.fabric,
        "day": FLAGS.day,
        "trial": FLAGS.trial,
        "condition": FLAGS.condition,
        "session": FLAGS.session,
    }
    trial = mapping_file.trial_fields({}, overrides, "command line")
    reference = parse_reference(
        {"reference": FLAGS.reference, "reference_frames": FLAGS.reference_frames}, argv[1], flags=True
    )
    result = hand_folder.import_folder(argv[1], trial, reference=reference, resample=FLAGS.resample)
    path = archive.write_archive(Path(FLAGS.out) / archive.trial_filename(result.meta), result)
    notes = result.meta["import"]
    print(
        f"{path}: {result.n_steps} steps"
        + (f", {len(notes['frame_gaps'])} frame gaps (see meta.import.frame_gaps)" if notes["frame_gaps"] else "")
        + (
            f", {len(notes['joint_gaps'])} holes in the joints (see meta.import.joint_gaps)"
            if notes["joint_gaps"]
            else ""
        )
        + (f", incomplete: {', '.join(notes['truncated'])} cut off" if not result.meta["complete"] else "")
    )


if __name__ == "__main__":
    cli.run(main)
