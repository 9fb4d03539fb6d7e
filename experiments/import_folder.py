"""Import one trial folder of WAV + CSV + video as a trial archive.

    python -m experiments.import_folder TRIAL_DIR --out=DIR --fabric=4 --day=1 --trial=0 --reference=reference.png
    python -m experiments.import_folder TRIAL_DIR --out=DIR --fabric=4 --day=1 --trial=0 --reference=pre_contact \\
        --reference_frames=5 --condition=cafe --session=monday --resample

The folder holds `internal.wav` and `external.wav`, `joints.csv` and `camera.avi` (or `camera/*.png`
with `frames.csv`), laid out as docs/data.md describes; alignment and errors are those of the bag
importer (`fabricjax.importers.alignment`); another rig's folder is a one-line error naming every
missing file and pointing to `experiments.import_manifest --rig`. The camera's
session reference is `--reference`: a file relative to TRIAL_DIR, or `pre_contact` (with
`--reference_frames`) for the trial's first frames (`fabricjax.importers.hand_folder`); without it the
import is a one-line error, before anything is read or written."""

from __future__ import annotations

from pathlib import Path

from absl import flags

from experiments import import_flags
from fabricjax import cli
from fabricjax.errors import UserError
from fabricjax.importers import hand_folder, mapping_file
from fabricjax.importers.alignment import parse_reference
from fabricjax.store import archive

FLAGS = flags.FLAGS
import_flags.define_out("the trial archive")
import_flags.define_trial(overrides=False, condition="lab")
import_flags.define_reference(
    "The camera's session reference: a file relative to TRIAL_DIR (image, video or .npy), or pre_contact.",
    "the trial's",
)
import_flags.define_resample("WAV files")


def main(argv):
    if len(argv) != 2:
        raise UserError("give exactly one trial folder: python -m experiments.import_folder TRIAL_DIR --out=DIR")
    trial = mapping_file.trial_fields({}, import_flags.trial_overrides(FLAGS), "command line")
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
