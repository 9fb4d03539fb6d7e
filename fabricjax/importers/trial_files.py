"""The file readers of a trial folder: a microphone's WAV file (`read_wav`), a joints CSV
(`read_joints_csv`), the camera, a video or an image sequence (`read_camera`), and the camera's
session reference, a file the rig file or command line names (`read_reference`). The hand's
folders (`fabricjax.importers.hand_folder`) and other rigs' (`fabricjax.importers.rig_folder`) share them."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np

from fabricjax.importers.streams import RecordingImportError, Stream, recorded_as, to_words
from fabricjax.store import archive

VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")
REFERENCE_SUFFIXES = (
    *IMAGE_SUFFIXES,
    *VIDEO_SUFFIXES,
    ".npy",
)  # a reference file: one image, a video, or frames as saved by NumPy


def read_wav(path: Path, start: float) -> Stream:
    """One microphone's mono WAV file, its first sample at `start` (s); a file cut off before the
    length its header declares is read as far as it goes and marked `truncated`."""
    from scipy.io import wavfile

    if not path.is_file():
        raise RecordingImportError(
            path,
            "<file>",
            "no such file (one WAV per microphone: " + ", ".join(f"{m}.wav" for m in archive.MIC_NAMES) + ")",
        )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", wavfile.WavFileWarning)
        try:
            rate, samples = wavfile.read(path)
        except (ValueError, EOFError) as e:
            raise RecordingImportError(path, "<file>", f"not a readable WAV file: {e}") from None
    truncated = any("EOF prematurely" in str(w.message) for w in caught)
    if samples.ndim != 1:
        raise RecordingImportError(
            path, "channels", f"{samples.shape[1]} channels, expected 1 (one file per microphone)"
        )
    return Stream.from_samples(
        str(path), int(rate), to_words(samples, path, "samples"), start, truncated, recorded_as(samples, "WAV")
    )


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


def _video_frames(path: Path) -> tuple[list[np.ndarray], float]:
    """Every frame of a video, RGB, and its frame rate (0 when the container gives none)."""
    cap = cv2.VideoCapture(str(path))
    fps = cap.get(cv2.CAP_PROP_FPS)
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
    cap.release()
    return frames, fps


def _image(path: Path) -> np.ndarray:
    """One image file, RGB (a grey image as three equal channels)."""
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise RecordingImportError(path, "<file>", "not a readable image")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def read_camera(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """RGB frames from `camera.<video>` or `camera/*.png`, placed by `frames.csv` (column `time`)
    when present, else by the video's frame rate."""
    videos = [folder / f"camera{s}" for s in VIDEO_SUFFIXES if (folder / f"camera{s}").is_file()]
    if videos:
        frames, fps = _video_frames(videos[0])
        where = videos[0]
    elif (folder / "camera").is_dir():
        where = folder / "camera"
        frames = [_image(p) for p in sorted(p for p in where.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)]
        fps = 0.0
    else:
        raise RecordingImportError(
            folder, "camera", f"no camera video (camera{{{','.join(VIDEO_SUFFIXES)}}}) or image folder camera/"
        )
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


def read_reference(path: Path, size: tuple[int, int]) -> np.ndarray:
    """The session's no-contact frames from the file a rig file or command line names: an image or
    a video read as the camera's frames are read (RGB), or a .npy of uint8 RGB frames (H, W, 3) or
    (R, H, W, 3). They must be at the camera's frame size `size` (H, W): a reference is the camera's
    own frames, and one at another size would be resized into a guess."""
    if not path.is_file():
        raise RecordingImportError(path, "<file>", "no such reference file")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            frames = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as e:
            raise RecordingImportError(path, "<file>", f"not a readable .npy file: {e}") from None
        if frames.dtype != np.uint8 or frames.ndim not in (3, 4) or frames.shape[-1] != 3:
            raise RecordingImportError(
                path, "frames", f"{frames.dtype} {frames.shape}, expected uint8 RGB frames (H, W, 3) or (R, H, W, 3)"
            )
        frames = frames[None] if frames.ndim == 3 else frames
    elif suffix in VIDEO_SUFFIXES:
        video = _video_frames(path)[0]
        if not video or len({f.shape for f in video}) > 1:
            raise RecordingImportError(
                path,
                "frames",
                "no frames could be read"
                if not video
                else f"frames of different sizes {sorted({f.shape for f in video})}",
            )
        frames = np.stack(video)
    else:
        frames = _image(path)[None]
    if not 1 <= len(frames) <= archive.MAX_REFERENCE_FRAMES:
        raise RecordingImportError(
            path, "frames", f"{len(frames)} frames, expected 1 to {archive.MAX_REFERENCE_FRAMES}"
        )
    if tuple(frames.shape[1:3]) != tuple(size):
        raise RecordingImportError(
            path,
            "frames",
            f"{frames.shape[1]}x{frames.shape[2]} pixels, the camera's frames are {size[0]}x{size[1]}: "
            "a reference is the camera's own frames, at their size",
        )
    return np.ascontiguousarray(frames)
