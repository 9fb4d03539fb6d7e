"""Import every trial a manifest lists, in one process pool with one progress bar.

    python -m experiments.import_manifest MANIFEST.csv --out=DIR --rig=rig.toml --split=fraction:0.7,0.15,0.15
    python -m experiments.import_manifest MANIFEST.csv --out=DIR --rig=rig.toml --labels=labels.csv \\
        --split=trial:train=0-3,val=4,test=5-6 --overwrite --workers=2 --workdir=workspace
    python -m experiments.import_manifest MANIFEST.csv --out=DIR --map=mapping.toml --split=day
    python -m experiments.import_manifest MANIFEST.csv --out=DIR --reference=reference.png
    python -m experiments.import_manifest MANIFEST.csv --out=DIR --reference=pre_contact --reference_frames=5

Another rig's trial folders take `--rig`, ROS 2 bags `--map`, the hand's folders `--reference` (a
file relative to each trial folder, or pre_contact). The manifest's columns, the label map
(`--labels`, a CSV with columns name, class; without it the manifest's label names, sorted) and the
split rules (`--split`) are `fabricjax.importers.manifest_file`'s; the import itself, one
transaction that resumes and ends by indexing DIR in the workspace (`--workdir`), is
`fabricjax.importers.batch`'s (docs/data.md, "Recordings from another rig").
"""

from __future__ import annotations

from absl import flags

from experiments import import_flags
from fabricjax import cli
from fabricjax.errors import UserError
from fabricjax.importers import batch

FLAGS = flags.FLAGS


def main(argv):
    if len(argv) != 2:
        raise UserError("give exactly one manifest: python -m experiments.import_manifest MANIFEST.csv --out=DIR")
    batch.run(
        argv[1],
        FLAGS.out,
        rig=FLAGS.rig,
        mapping=FLAGS.map,
        labels=FLAGS.labels,
        split=FLAGS.split,
        overwrite=FLAGS.overwrite,
        workers=FLAGS.workers,
        reference=FLAGS.reference,
        reference_frames=FLAGS.reference_frames,
        workdir=FLAGS.workdir,
    )


if __name__ == "__main__":
    import_flags.define_out("the trial archives")
    flags.DEFINE_string(
        "rig", None, "Rig file (TOML): the streams of each trial folder (fabricjax/importers/rig_folder.py)."
    )
    import_flags.define_map("Mapping file (TOML) of ROS 2 bags (experiments/import_bag.py).")
    import_flags.define_reference(
        "The hand's trial folders' camera reference: a file relative to each trial folder, or pre_contact.",
        "each trial's",
    )
    flags.DEFINE_string(
        "labels", None, "Label map: CSV with columns name, class (default: the manifest's labels, sorted)."
    )
    flags.DEFINE_string(
        "split",
        None,
        "Split rule when the manifest has no split column: fraction:TRAIN,VAL,TEST, trial:SPLIT=FIRST-LAST,... or day.",
    )
    import_flags.define_overwrite(
        "Replace the dataset in --out by the manifest's (default: keep archives of the same rows, refuse "
        "anything else)."
    )
    flags.DEFINE_integer("workers", None, "Processes (default: one per core).", lower_bound=1)
    flags.DEFINE_string(
        "workdir",
        None,
        "Workspace that keeps DIR's index (default: $FABRICJAX_WORKDIR or ./workspace); give verify and the "
        "studies the same.",
    )
    cli.run(main)
