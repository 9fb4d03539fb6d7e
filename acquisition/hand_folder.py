"""One trial folder of the hand's layout (WORKSPACE.md, "Using your own recordings") as a trial
archive: `internal.wav` and `external.wav`, `joints.csv` and the camera, read by
`acquisition.readers` and aligned by `acquisition.alignment.align`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from acquisition.alignment import align, check_seconds
from acquisition.readers import IMAGE_SUFFIXES, VIDEO_SUFFIXES, read_camera, read_joints_csv, read_wav
from acquisition.recording import RecordingImportError
from fabricjax import archive

JOINTS_FILE = "joints.csv"
OTHER_RIG = ("a folder of another rig imports with python -m acquisition.import_manifest MANIFEST.csv --out=DIR --rig=rig.toml "
             "(WORKSPACE.md, \"Recordings from another rig\")")


def missing_files(folder: Path) -> list[str]:
    """The files of the hand's layout that `folder` lacks (every one, not the first)."""
    missing = [f"{m}.wav" for m in archive.MIC_NAMES if not (folder / f"{m}.wav").is_file()]
    missing += [JOINTS_FILE] if not (folder / JOINTS_FILE).is_file() else []
    has_camera = any((folder / f"camera{s}").is_file() for s in VIDEO_SUFFIXES) or (folder / "camera").is_dir()
    return missing + ([f"camera{{{','.join(VIDEO_SUFFIXES)}}} or camera/*{{{','.join(IMAGE_SUFFIXES)}}}"] if not has_camera else [])


def check_layout(folder: Path) -> None:
    """A one-line error naming every missing file of the hand's layout, and how another rig's folder imports."""
    if not folder.is_dir():
        raise RecordingImportError(folder, "<folder>", "no such trial folder")
    missing = missing_files(folder)
    if missing:
        raise RecordingImportError(folder, "<folder>", f"not a trial folder of the hand's layout: missing {', '.join(missing)}; {OTHER_RIG}")


def import_folder(folder: str | Path, trial: dict[str, Any], *, resample: bool = False) -> archive.TrialArchive:
    """One trial folder (layout in WORKSPACE.md): `internal.wav` and `external.wav` starting at
    time 0, `joints.csv` and the camera on the same clock (seconds), aligned by `align`; a WAV file
    cut off before its header's length gives `complete: false`."""
    folder = Path(folder)
    check_layout(folder)
    mics = [read_wav(folder / f"{m}.wav", 0.0) for m in archive.MIC_NAMES]
    frame_times, images = read_camera(folder)
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
        resample=resample,
        complete=not truncated,
        notes={"truncated": truncated} if truncated else None,
    )
