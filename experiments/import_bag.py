"""Import one ROS 2 bag (sqlite3 or MCAP) as a trial archive.

    python -m experiments.import_bag BAG --map=mapping.toml --out=DIR
    python -m experiments.import_bag BAG --map=mapping.toml --out=DIR --fabric=4 --day=1 --trial=0 --condition=lab
    python -m experiments.import_bag BAG --map=mapping.toml --out=DIR --session=monday --resample --overwrite

The mapping file names the camera, microphone and joint topics (format in docs/data.md, "From ROS 2
bags") and where the camera's session reference comes from (`reference_topic`, or
`reference = "pre_contact"`: `fabricjax.importers.ros_bag`); the trial's fabric, day, trial, condition and
optional session come from its [trial] table, and the flags override it. An archive already in DIR is not replaced
without --overwrite. Needs the optional `rosbags` package: pip install -e ".[bags]".
"""

from __future__ import annotations

from pathlib import Path

from absl import flags

from experiments import import_flags
from fabricjax import cli
from fabricjax.errors import UserError
from fabricjax.importers import mapping_file, ros_bag
from fabricjax.importers.streams import RecordingImportError
from fabricjax.store import archive

FLAGS = flags.FLAGS
import_flags.define_map("Mapping file (TOML) naming the topics.", required=True)
import_flags.define_out("the trial archive")
import_flags.define_trial(overrides=True)
import_flags.define_resample("microphones")
import_flags.define_overwrite("Replace an archive of the same fabric, day, trial and condition in --out.")


def main(argv):
    if len(argv) != 2:
        raise UserError("give exactly one bag: python -m experiments.import_bag BAG --map=mapping.toml --out=DIR")
    mapping = mapping_file.load_mapping(FLAGS.map)
    trial = mapping_file.trial_fields(mapping, import_flags.trial_overrides(FLAGS), FLAGS.map)
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
