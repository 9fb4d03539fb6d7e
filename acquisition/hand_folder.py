"""One trial folder of the hand's layout (WORKSPACE.md, "Using your own recordings") as a trial
archive: `internal.wav` and `external.wav`, `joints.csv` and the camera, read by
`acquisition.readers` and aligned by `acquisition.alignment.align`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from acquisition.alignment import align
from acquisition.readers import read_camera, read_joints_csv, read_wav
from acquisition.recording import RecordingImportError
from fabricjax import archive


def import_folder(folder: str | Path, trial: dict[str, Any], *, resample: bool = False) -> archive.TrialArchive:
    """One trial folder (layout in WORKSPACE.md): `internal.wav` and `external.wav` starting at
    time 0, `joints.csv` and the camera on the same clock, aligned by `align`."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RecordingImportError(folder, "<folder>", "no such trial folder")
    frame_times, images = read_camera(folder)
    joint_times, joints = read_joints_csv(folder / "joints.csv")
    return align(
        frame_times=frame_times,
        images=images,
        mics=[read_wav(folder / f"{m}.wav", 0.0) for m in archive.MIC_NAMES],
        joint_times=joint_times,
        joints=joints,
        trial=trial,
        source={"kind": "folder", "path": str(folder)},
        resample=resample,
    )
