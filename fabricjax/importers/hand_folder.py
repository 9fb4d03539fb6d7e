"""One trial folder of the hand's layout (docs/data.md) as a trial
archive: `internal.wav` and `external.wav`, `joints.csv` and the camera, read by
`fabricjax.importers.trial_files` and aligned by `fabricjax.importers.alignment.align`.

The layout names no session reference for the camera, so the command line must
(`alignment.parse_reference`; `import_folder` and `import_manifest` take the same flags):
`--reference=FILE`, a file relative to the trial folder (an image, a video or a .npy of uint8 RGB
frames at the camera's size; `../reference.png` for one file beside a session's trial folders), or
`--reference=pre_contact` with `--reference_frames=N` (default 5) for the trial's own first frames.
A trial's `session` (meta.reference.session) is `--session` or the manifest's column, else its day
and condition."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fabricjax.importers.alignment import ReferenceSource, align, check_seconds, file_reference
from fabricjax.importers.streams import RecordingImportError
from fabricjax.importers.trial_files import IMAGE_SUFFIXES, VIDEO_SUFFIXES, read_camera, read_joints_csv, read_wav
from fabricjax.store import archive

JOINTS_FILE = "joints.csv"
OTHER_RIG = (
    "a folder of another rig imports with python -m experiments.import_manifest MANIFEST.csv --out=DIR --rig=rig.toml "
    '(docs/data.md, "Recordings from another rig")'
)


def missing_files(folder: Path, reference: ReferenceSource | None = None) -> list[str]:
    """The files of the hand's layout, and the reference file `reference` names, that `folder`
    lacks (every one, not the first)."""
    missing = [f"{m}.wav" for m in archive.MIC_NAMES if not (folder / f"{m}.wav").is_file()]
    missing += [JOINTS_FILE] if not (folder / JOINTS_FILE).is_file() else []
    has_camera = any((folder / f"camera{s}").is_file() for s in VIDEO_SUFFIXES) or (folder / "camera").is_dir()
    missing += (
        [f"camera{{{','.join(VIDEO_SUFFIXES)}}} or camera/*{{{','.join(IMAGE_SUFFIXES)}}}"] if not has_camera else []
    )
    named = reference is not None and reference.name is not None and not (folder / reference.name).is_file()
    return missing + ([f"{reference.name} (the reference --reference names)"] if named else [])


def check_layout(folder: Path, reference: ReferenceSource | None = None) -> None:
    """A one-line error naming every missing file of the hand's layout (and the reference file
    `reference` names), and how another rig's folder imports."""
    if not folder.is_dir():
        raise RecordingImportError(folder, "<folder>", "no such trial folder")
    missing = missing_files(folder, reference)
    if missing:
        raise RecordingImportError(
            folder, "<folder>", f"not a trial folder of the hand's layout: missing {', '.join(missing)}; {OTHER_RIG}"
        )


def import_folder(
    folder: str | Path, trial: dict[str, Any], *, reference: ReferenceSource, resample: bool = False
) -> archive.TrialArchive:
    """One trial folder (layout in docs/data.md): `internal.wav` and `external.wav` starting at
    time 0, `joints.csv` and the camera on the same clock (seconds), aligned by `align`, with the
    session reference from `reference` (module docstring; a file's frames have no known times); a
    WAV file cut off before its header's length gives `complete: false`."""
    folder = Path(folder)
    check_layout(folder, reference)
    mics = [read_wav(folder / f"{m}.wav", 0.0) for m in archive.MIC_NAMES]
    frame_times, images = read_camera(folder)
    named = None if reference.name is None else file_reference(folder, reference, images.shape[1:3])
    joint_times, joints = read_joints_csv(folder / JOINTS_FILE)
    check_seconds(frame_times, folder / "frames.csv", "time", mics)
    check_seconds(joint_times, folder / JOINTS_FILE, "time", mics)
    truncated = [Path(m.name).name for m in mics if m.truncated]
    return align(
        frame_times=frame_times,
        images=images,
        mics=mics,
        joint_times=joint_times,
        joints=joints,
        trial=trial,
        source={"kind": "folder", "path": str(folder)},
        reference=reference,
        named=named,
        resample=resample,
        complete=not truncated,
        notes={"truncated": truncated} if truncated else None,
    )
