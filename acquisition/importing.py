"""Other labs' recordings (ROS 2 bags / MCAP) to trial archives, aligned as the recorder aligns.

The recorder's rule, applied to timestamped streams after the fact (`align`): one step per camera
frame; each microphone's window ends after the last audio sample received at or before the frame;
the joints are the latest reading at or before the frame. Frames before every microphone holds one
full window and before the first joint reading are dropped, as the recorder waits for a full window
before its first step; so are frames after the shorter microphone's end. The step rate is the
camera's frame rate (declared, or measured from the median frame interval), so a 30 fps camera
gives 30 Hz steps, not frame loss. Nothing is resampled silently: a microphone not at the archive's 48 kHz is an
error naming the topic and the rate, unless `resample=True` (`scipy.signal.resample_poly`, recorded
in meta.import.resampled). A gap between frames is kept, never filled, and listed in
meta.import.frame_gaps; missing audio (a hole between chunks) is an error, since every window after
it would silently be misplaced.

The mapping file (TOML) names the topics; see WORKSPACE.md, "Using your own recordings".
"""

from __future__ import annotations

import dataclasses
import tomllib
from fractions import Fraction
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from acquisition import ros_bag
from acquisition.camera import ForceProxy
from fabricjax import archive, catalog, integrity
from fabricjax.errors import UserError

TRIAL_KEYS = ("fabric_id", "day", "trial", "condition")


class RecordingImportError(UserError):
    """A recording cannot become an archive; the message names file, field and problem."""

    def __init__(self, path, field: str, problem: str):
        super().__init__(f"{path}: {field}: {problem}")


@dataclasses.dataclass
class Stream:
    """One microphone as recorded: its samples, and the times (s) at which it held `counts` of them
    (a bag: each message's receive time and the samples up to its end; a WAV file: every sample's time)."""

    name: str  # topic or file, for errors
    rate: int
    samples: np.ndarray  # (S,) int32 SPH0645-style words
    times: np.ndarray  # (K,) float64, increasing
    counts: np.ndarray  # (K,) int64, samples held at each time

    @classmethod
    def from_chunks(cls, name: str, rate: int, times, chunks: list[np.ndarray]) -> "Stream":
        """Messages in any order, each a chunk of samples stamped with its last sample's time."""
        if not chunks:
            raise RecordingImportError(name, "audio", "no messages")
        order = np.argsort(np.asarray(times, np.float64), kind="stable")
        ordered = [chunks[i] for i in order]
        counts = np.cumsum([len(c) for c in ordered]).astype(np.int64)
        return cls(name, rate, np.concatenate(ordered), np.asarray(times, np.float64)[order], counts)

    @classmethod
    def from_samples(cls, name: str, rate: int, samples: np.ndarray, start: float = 0.0) -> "Stream":
        """A continuous recording (a WAV file) whose first sample is at `start`."""
        if len(samples) == 0:
            raise RecordingImportError(name, "audio", "no samples")
        return cls(name, rate, samples, start + np.arange(len(samples)) / rate, np.arange(1, len(samples) + 1, dtype=np.int64))


def to_words(samples: np.ndarray, where, field: str) -> np.ndarray:
    """int16 samples move to the top 16 of the 18 valid SPH0645 bits; int32 words are kept as they are."""
    if samples.dtype == np.int16:
        return samples.astype(np.int32) << 16
    if samples.dtype == np.int32:
        return samples
    raise RecordingImportError(where, field, f"audio samples must be int16 or int32, got {samples.dtype}")


def _audio(stream: Stream, resample: bool, resampled: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 48 kHz samples, and the sample counts at the stream's times; lost samples are an error."""
    times, counts, audio = stream.times, stream.counts, stream.samples
    half_chunk = 0.5 * float(np.median(np.diff(counts, prepend=0))) / stream.rate
    # each chunk's end time against the clock of its samples: a late (jittered) chunk is followed by
    # punctual ones, lost samples shift every later chunk, so only a lasting step counts; a slow drift
    # between the two clocks moves it by far less than half a chunk per chunk
    drift = (times - times[0]) - (counts - counts[0]) / stream.rate
    lasting = np.minimum.accumulate(drift[::-1])[::-1]
    steps = np.diff(lasting)
    if steps.size and steps.max() > half_chunk:
        k = int(np.argmax(steps)) + 1
        raise RecordingImportError(
            stream.name, "audio", f"about {steps[k - 1]:.3f} s of samples missing before t={times[k] - times[0]:.3f} s "
            "(a message was lost; the windows after it cannot be placed)"
        )
    if stream.rate != archive.AUDIO_RATE:
        if not resample:
            raise RecordingImportError(
                stream.name, "rate", f"sample rate {stream.rate} Hz, archives hold {archive.AUDIO_RATE} Hz "
                "(pass --resample to convert with scipy.signal.resample_poly)"
            )
        from scipy.signal import resample_poly

        ratio = Fraction(archive.AUDIO_RATE, stream.rate)
        audio = np.round(resample_poly(audio.astype(np.float64), ratio.numerator, ratio.denominator))
        audio = np.clip(audio, np.iinfo(np.int32).min, np.iinfo(np.int32).max).astype(np.int32)
        counts = np.floor(counts * float(ratio)).astype(np.int64)
        resampled[stream.name] = {"from_hz": stream.rate, "to_hz": archive.AUDIO_RATE, "method": "scipy.signal.resample_poly"}
    return audio, times, counts


def align(
    *,
    frame_times: np.ndarray,
    images: np.ndarray,
    mics: list[Stream],
    joint_times: np.ndarray,
    joints: np.ndarray,
    trial: dict[str, Any],
    source: dict[str, Any],
    resample: bool = False,
    force_gain: float = ForceProxy.gain,
    force_deadband: float = ForceProxy.deadband,
    step_rate: float | None = None,
    joint_fields_absent: list[str] | tuple[str, ...] = (),
    clocks: dict[str, Any] | None = None,
) -> archive.TrialArchive:
    """The recorder's alignment (module docstring) of streams with timestamps in seconds.

    `step_rate`: the camera's frame rate, the archive's step rate; None measures it (`step_rate_of`).
    `joint_fields_absent`: JOINT_FIELDS the recording lacks (NaN in `joints`; meta.streams.joints.absent).
    `clocks`: how each stream was placed in time (meta.import.clocks)."""
    where = source.get("path", "<recording>")
    if len(mics) != len(archive.MIC_NAMES):
        raise RecordingImportError(where, "mics", f"need {len(archive.MIC_NAMES)} microphones {archive.MIC_NAMES}, got {len(mics)}")
    for name, times in (("camera", frame_times), ("joints", joint_times)):
        if len(times) == 0:
            raise RecordingImportError(where, name, "no messages")
    order = np.argsort(frame_times, kind="stable")
    frame_times, images = frame_times[order], images[order]
    keep = np.concatenate([[True], np.diff(frame_times) > 0])  # a repeated frame time is one frame
    duplicates = int(np.count_nonzero(~keep))
    frame_times, images = frame_times[keep], images[keep]
    jorder = np.argsort(joint_times, kind="stable")
    joint_times, joints = joint_times[jorder], joints[jorder]

    resampled: dict[str, Any] = {}
    audio, ends = [], []
    for mic in mics:
        samples, times, counts = _audio(mic, resample, resampled)
        k = np.searchsorted(times, frame_times, side="right") - 1
        ends.append(np.where(k >= 0, counts[np.maximum(k, 0)], 0))
        audio.append(samples)
    window_end = np.stack(ends, axis=1).astype(np.int64)
    jk = np.searchsorted(joint_times, frame_times, side="right") - 1
    usable = (window_end >= archive.WINDOW).all(axis=1) & (jk >= 0)
    if not usable.any():
        full = (window_end >= archive.WINDOW).all(axis=1)
        first_full = f"{frame_times[np.argmax(full)]:.3f} s" if full.any() else "none"
        raise RecordingImportError(
            where, "camera", f"no frame comes after a full audio window and a joint reading: frames span "
            f"{frame_times[0]:.3f}-{frame_times[-1]:.3f} s, the first with a full audio window: {first_full}, the first "
            f"joint reading: {joint_times[0]:.3f} s (streams on different clocks? see the mapping's clock keys)"
        )
    first = int(np.argmax(usable))
    frame_times, images, window_end, jk = frame_times[first:], images[first:], window_end[first:], jk[first:]

    # the archive's audio rows are equally long: frames whose window would reach past the shorter
    # microphone's end are dropped rather than given a misplaced window
    n_samples = min(len(a) for a in audio)
    inside = int(np.count_nonzero((window_end <= n_samples).all(axis=1)))
    dropped_at_end = len(frame_times) - inside
    if inside == 0:
        raise RecordingImportError(where, "audio", f"the microphones' recordings differ in length: the shorter ({n_samples} samples) ends before the first frame")
    frame_times, images, window_end, jk = frame_times[:inside], images[:inside], window_end[:inside], jk[:inside]
    rate, rate_from = (step_rate, "mapping camera.rate") if step_rate else step_rate_of(frame_times)
    gaps = integrity.frame_gaps(frame_times, rate)
    reference = images[0]
    proxy = ForceProxy(reference, gain=force_gain, deadband=force_deadband)
    try:
        fab = catalog.fabric(int(trial["fabric_id"]))
    except KeyError as e:
        raise RecordingImportError(where, "trial.fabric_id", e.args[0]) from None
    meta = archive.make_meta(
        fabric_id=int(trial["fabric_id"]),
        properties=fab.properties,
        day=int(trial["day"]),
        trial=int(trial["trial"]),
        condition=str(trial["condition"]),
        source=source,
        image_size=images.shape[1:3],
        streams=archive.hand_streams(images.shape[1:3], step_rate=rate, joint_fields_absent=joint_fields_absent),
        closing_steps=0,  # the procedure's phases are not in other labs' recordings: every step counts
        force_proxy={"gain": force_gain, "deadband": force_deadband, "reference": "first kept frame"},
        **{"import": {
            "step_rate_from": rate_from,
            "frames_dropped_before_start": first,
            "frames_dropped_at_end": dropped_at_end,
            "duplicate_frames_dropped": duplicates,
            "frame_gaps": [{"step": int(k), "seconds": round(float(frame_times[k] - frame_times[k - 1]), 6)} for k in gaps],
            "resampled": resampled,
            **({"clocks": clocks} if clocks else {}),
        }},
    )
    return archive.TrialArchive(
        meta=meta,
        timestamps=(frame_times - frame_times[0]).astype(np.float64),
        window_end=window_end,
        joints=joints[jk].astype(np.float32),
        force=np.array([proxy(im) for im in images], np.float32),
        audio=np.stack([a[:n_samples] for a in audio]),
        images=np.ascontiguousarray(images, dtype=np.uint8),
    )


def step_rate_of(frame_times: np.ndarray) -> tuple[float, str]:
    """The camera's frame rate from its median frame interval (lost frames do not move a median):
    the nearest whole rate when within 1 % of it (29.97 fps is 30), else to 0.01 Hz; and how it was found."""
    if len(frame_times) < 2:
        return archive.STEP_RATE, "a single frame: the recorder's rate"
    interval = float(np.median(np.diff(frame_times)))
    rate = 1.0 / interval
    whole = round(rate)
    return (int(whole) if abs(rate - whole) <= 0.01 * rate else round(rate, 2)), f"median frame interval {interval * 1e3:.2f} ms"


def read_toml(path: Path, what: str) -> dict[str, Any]:
    """A TOML file (`what`: "mapping", "rig", ...) as a dict; a missing or malformed file is a
    one-line error naming it."""
    try:
        return tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise RecordingImportError(path, "<file>", f"no such {what} file") from None
    except tomllib.TOMLDecodeError as e:
        raise RecordingImportError(path, "<file>", f"not valid TOML: {e}") from None


def load_mapping(path: str | Path) -> dict[str, Any]:
    """The mapping file, checked for the keys `import_bag` needs."""
    path = Path(path)
    mapping = read_toml(path, "mapping")
    for key in ("camera.topic", "joints.topic", *(f"mics.{m}.topic" for m in archive.MIC_NAMES)):
        node: Any = mapping
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                raise RecordingImportError(path, key, "missing")
            node = node[part]
    ros_bag.check_mapping(mapping, path)
    return mapping


def trial_fields(mapping: dict[str, Any], overrides: dict[str, Any], where) -> dict[str, Any]:
    """fabric_id, day, trial and condition: the command line wins over the mapping's [trial] table."""
    trial = dict(mapping.get("trial", {})) | {k: v for k, v in overrides.items() if v is not None}
    for key in TRIAL_KEYS:
        if key not in trial:
            raise RecordingImportError(where, f"trial.{key}", "missing (give it in the mapping's [trial] table or on the command line)")
    if trial["condition"] not in archive.CONDITIONS:
        raise RecordingImportError(where, "trial.condition", f"must be one of {archive.CONDITIONS}, got {trial['condition']!r}")
    return trial


def import_bag(
    bag: str | Path,
    mapping: dict[str, Any],
    trial: dict[str, Any],
    *,
    resample: bool = False,
) -> archive.TrialArchive:
    """Read a ROS 2 bag (sqlite3 or MCAP folder, or one storage file) with `rosbags`, each stream
    placed on the bag's receive clock by the mapping's clock policy (`acquisition.ros_bag`), and
    align it (module docstring)."""
    rec = ros_bag.read_bag(bag, mapping)
    mics = [Stream.from_chunks(c.topic, c.rate, c.times, [to_words(x, c.topic, "data") for x in c.chunks]) for c in rec.mics]
    return align(
        frame_times=rec.frame_times,
        images=rec.images,
        mics=mics,
        joint_times=rec.joint_times,
        joints=rec.joints,
        trial=trial,
        source=rec.source,
        resample=resample,
        force_gain=float(mapping.get("force", {}).get("gain", ForceProxy.gain)),
        force_deadband=float(mapping.get("force", {}).get("deadband", ForceProxy.deadband)),
        step_rate=rec.step_rate,
        joint_fields_absent=rec.joint_fields_absent,
        clocks=rec.clocks,
    )


VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")


def _read_wav(path: Path, start: float) -> Stream:
    from scipy.io import wavfile

    if not path.is_file():
        raise RecordingImportError(path, "<file>", "no such file (one WAV per microphone: " + ", ".join(f"{m}.wav" for m in archive.MIC_NAMES) + ")")
    try:
        rate, samples = wavfile.read(path)
    except ValueError as e:
        raise RecordingImportError(path, "<file>", f"not a readable WAV file: {e}") from None
    if samples.ndim != 1:
        raise RecordingImportError(path, "channels", f"{samples.shape[1]} channels, expected 1 (one file per microphone)")
    return Stream.from_samples(str(path), int(rate), to_words(samples, path, "samples"), start)


def _read_joints(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times and (N, 6, 3) joints from a CSV with a `time` column and `<joint>_<field>` columns."""
    if not path.is_file():
        raise RecordingImportError(path, "<file>", "no such file")
    try:
        table = np.genfromtxt(path, delimiter=",", names=True, dtype=np.float64, ndmin=1)
    except ValueError as e:
        raise RecordingImportError(path, "<file>", f"not a readable CSV: {e}") from None
    columns = ["time", *(f"{j}_{f}" for j in archive.JOINT_NAMES for f in archive.JOINT_FIELDS)]
    for col in columns:
        if table.dtype.names is None or col not in table.dtype.names:
            raise RecordingImportError(path, col, "column missing")
        if not np.all(np.isfinite(table[col])):
            raise RecordingImportError(path, col, "empty or non-numeric values")
    joints = np.stack([table[c] for c in columns[1:]], axis=1).reshape(-1, archive.N_JOINTS, 3)
    return table["time"], joints


def _read_camera(folder: Path) -> tuple[np.ndarray, np.ndarray]:
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


def import_folder(folder: str | Path, trial: dict[str, Any], *, resample: bool = False) -> archive.TrialArchive:
    """One trial folder (layout in WORKSPACE.md): `internal.wav` and `external.wav` starting at
    time 0, `joints.csv` and the camera on the same clock, aligned by `align`."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RecordingImportError(folder, "<folder>", "no such trial folder")
    frame_times, images = _read_camera(folder)
    joint_times, joints = _read_joints(folder / "joints.csv")
    return align(
        frame_times=frame_times,
        images=images,
        mics=[_read_wav(folder / f"{m}.wav", 0.0) for m in archive.MIC_NAMES],
        joint_times=joint_times,
        joints=joints,
        trial=trial,
        source={"kind": "folder", "path": str(folder)},
        resample=resample,
    )
