"""The file readers of a trial folder: a microphone's WAV file (`read_wav`), a joints CSV
(`read_joints_csv`) and the camera, a video or an image sequence (`read_camera`). The hand's
folders (`acquisition.hand_folder`) and other rigs' (`acquisition.rig`) share them."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np

from acquisition.recording import RecordingImportError, Stream, to_words
from fabricjax import archive

VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")


def read_wav(path: Path, start: float) -> Stream:
    """One microphone's mono WAV file, its first sample at `start` (s); a file cut off before the
    length its header declares is read as far as it goes and marked `truncated`."""
    from scipy.io import wavfile

    if not path.is_file():
        raise RecordingImportError(path, "<file>", "no such file (one WAV per microphone: " + ", ".join(f"{m}.wav" for m in archive.MIC_NAMES) + ")")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", wavfile.WavFileWarning)
        try:
            rate, samples = wavfile.read(path)
        except (ValueError, EOFError) as e:
            raise RecordingImportError(path, "<file>", f"not a readable WAV file: {e}") from None
    truncated = any("EOF prematurely" in str(w.message) for w in caught)
    if samples.ndim != 1:
        raise RecordingImportError(path, "channels", f"{samples.shape[1]} channels, expected 1 (one file per microphone)")
    return Stream.from_samples(str(path), int(rate), to_words(samples, path, "samples"), start, truncated)


def read_joints_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times and (N, 6, 3) joints from a CSV with a `time` column and `<joint>_<field>` columns."""
    if not path.is_file():
        raise RecordingImportError(path, "<file>", "no such file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an empty table is the error below, not a warning
            table = np.genfromtxt(path, delimiter=",", names=True, dtype=np.float64, ndmin=1, encoding="utf-8")
    except ValueError as e:  # also a file that is not UTF-8 (UnicodeDecodeError)
        raise RecordingImportError(path, "<file>", f"not a readable UTF-8 CSV: {e}") from None
    columns = ["time", *(f"{j}_{f}" for j in archive.JOINT_NAMES for f in archive.JOINT_FIELDS)]
    if table.size == 0:
        raise RecordingImportError(path, "<rows>", "no readings (a header row only)")
    for col in columns:
        if table.dtype.names is None or col not in table.dtype.names:
            raise RecordingImportError(path, col, "column missing")
        if not np.all(np.isfinite(table[col])):
            raise RecordingImportError(path, col, "empty or non-numeric values")
    joints = np.stack([table[c] for c in columns[1:]], axis=1).reshape(-1, archive.N_JOINTS, archive.N_JOINT_FIELDS)
    return table["time"], joints


def read_camera(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """RGB frames from `camera.<video>` or `camera/*.png`, placed by `frames.csv` (column `time`)
    when present, else by the video's frame rate."""
    videos = [folder / f"camera{s}" for s in VIDEO_SUFFIXES if (folder / f"camera{s}").is_file()]
    if videos:
        cap = cv2.VideoCapture(str(videos[0]))
        fps = cap.get(cv2.CAP_PROP_FPS)
        frames = []
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
        cap.release()
        where = videos[0]
    elif (folder / "camera").is_dir():
        where = folder / "camera"
        files = sorted(p for p in where.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        frames = []
        for p in files:
            img = cv2.imread(str(p), cv2.IMREAD_COLOR)
            if img is None:
                raise RecordingImportError(p, "<file>", "not a readable image")
            frames.append(cv2.cvtColor(img, cv2.COLOR_BGR2RGB))
        fps = 0.0
    else:
        raise RecordingImportError(folder, "camera", f"no camera video (camera{{{','.join(VIDEO_SUFFIXES)}}}) or image folder camera/")
    if not frames:
        raise RecordingImportError(where, "frames", "no frames could be read")
    if len({f.shape for f in frames}) > 1:
        raise RecordingImportError(where, "frames", f"frames of different sizes {sorted({f.shape for f in frames})}")
    times_csv = folder / "frames.csv"
    if times_csv.is_file():
        table = np.genfromtxt(times_csv, delimiter=",", names=True, dtype=np.float64, ndmin=1)
        if table.dtype.names is None or "time" not in table.dtype.names:
            raise RecordingImportError(times_csv, "time", "column missing")
        times = table["time"]
        if len(times) != len(frames):
            raise RecordingImportError(times_csv, "time", f"{len(times)} times for {len(frames)} frames in {where}")
    elif fps > 0:
        times = np.arange(len(frames)) / fps
    else:
        raise RecordingImportError(where, "time", "an image sequence needs frames.csv with a `time` column")
    return np.asarray(times, np.float64), np.stack(frames)
