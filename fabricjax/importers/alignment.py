"""Timestamped streams of another lab's recording aligned into a trial archive as the recorder aligns.

The recorder's rule, applied after the fact (`align`): one step per camera frame; each
microphone's window ends after the last audio sample received at or before the frame; the joints
are the latest reading at or before the frame. Frames before every microphone holds one
full window and before the first joint reading are dropped, as the recorder waits for a full window
before its first step; so are frames after the shorter microphone's end. The step rate is the
camera's frame rate (declared, or measured from the median frame interval), so a 30 fps camera
gives 30 Hz steps, not frame loss. Nothing is resampled silently: a microphone not at the archive's 48 kHz is an
error naming the topic and the rate, unless `resample=True` (`scipy.signal.resample_poly`, recorded
in meta.import.resampled). A gap between frames is kept, never filled, and listed in
meta.import.frame_gaps; a hole in the joints longer than HOLE_STEPS frames, where steps hold the
last reading, is listed in meta.import.joint_gaps; missing audio (a hole between chunks) is an
error, since every window after it would silently be misplaced. Timestamps are seconds: times
spanning far more than the audio (milliseconds) are an error, and a WAV file cut off before its
header's length gives `complete: false` (meta.import.truncated names it).

The session reference (archive format 3: the no-contact frames Minsight's software reads every
frame against) is never made up: a camera's mapping, rig file or command line names where it comes
from (`parse_reference`), a topic of the bag or a file of the trial folder, or, only when asked,
`pre_contact`: the recording's first N frames (default `DEFAULT_REFERENCE_FRAMES`), which hold no
contact only if the fingers were open when the camera started. The importers cannot tell when the
fingers close (other labs' recordings carry no procedure phases: closing_steps is 0), which is why
this is taken only when asked, and `meta.reference.how` says so. `meta.reference.session` is the
session the manifest or mapping names, else the trial's day and condition (`day2_lab`), else, for
recordings without days, the trial's own name (`session_of`); `times_s` are the frames' times on
the trial's step clock where the recording gives them (a topic's stamps, the trial's own frames),
else null. The force proxy reads against the reference's first frame, as the recorder's does.
"""

from __future__ import annotations

import dataclasses
import json
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from fabricjax import catalog
from fabricjax.force_proxy import ForceProxy
from fabricjax.importers.streams import RecordingImportError, Stream
from fabricjax.importers.trial_files import REFERENCE_SUFFIXES, read_reference
from fabricjax.store import archive, integrity

HOLE_STEPS = 3  # a stream silent for more than this many step periods has a hole (declared in meta.import)
SPAN_FACTOR = 10  # timestamps spanning this many times the audio's duration are not seconds
# readings closer than this (s) are seconds whatever they span: every stream the importers align
# reads faster than 2 Hz, so such timestamps are right and the audio is what falls short
SECONDS_SPACING = 0.5
PRE_CONTACT = "pre_contact"  # a reference source: the trial's own first frames, only when asked
DEFAULT_REFERENCE_FRAMES = 5  # pre-contact frames taken when reference_frames is not given


@dataclasses.dataclass(frozen=True)
class ReferenceSource:
    """Where a trial's session reference comes from, as its mapping, rig file or command line names
    it: a topic of the bag or a file of the trial folder (`name`), or, asked for by `asked_by`, the
    trial's own first `frames` frames (`name` None)."""

    name: str | None
    frames: int = DEFAULT_REFERENCE_FRAMES
    asked_by: str = "the mapping"

    def describe(self) -> str:
        """What the reference is read from (meta.source.reference): the topic or file, or pre_contact."""
        return self.name if self.name is not None else f"{PRE_CONTACT}: the first {self.frames} frames"


@dataclasses.dataclass(frozen=True)
class ImportedReference:
    """A session reference as an importer read it (the recorder's is `acquisition.camera.Reference`):
    its frames, their times (s) on the recording's clock where the recording gives them, and how
    they were taken (meta.reference.how)."""

    frames: np.ndarray  # (R, H, W, 3) uint8
    times: np.ndarray | None
    how: str


def parse_reference(given: dict[str, Any], where, *, topic: bool = False, flags: bool = False) -> ReferenceSource:
    """A camera's reference source from a mapping's or rig file's [camera] table or the command line
    (`flags`): `reference_topic` (bags, `topic`) or `reference` (a file of the trial folder), or
    `reference = "pre_contact"` with an optional `reference_frames`. Naming none is a one-line error
    saying how to name one, never a default: a reference made up from frames that hold a contact
    would read as no contact."""
    named = "reference_topic" if topic else "reference"
    field = (lambda k: f"--{k}") if flags else (lambda k: f"camera.{k}")
    spell = (lambda k, v: f"pass --{k}={v}") if flags else (lambda k, v: f"set {k} = {json.dumps(v)}")
    asked_by = "the command line" if flags else "the mapping" if topic else "the rig file"
    value, frames = given.get("reference"), given.get("reference_frames")
    name = given.get(named) if topic else value if value != PRE_CONTACT else None
    if topic and name is not None and value is not None:
        raise RecordingImportError(
            where, field(named), f"given with {field('reference')}: name one source of the reference"
        )
    if name is None and value is None:
        what = "the topic that carries it" if topic else "the file of the trial folder that holds it"
        example = "/minsight/reference" if topic else "reference.png"
        raise RecordingImportError(
            where,
            field(named),
            f"missing: a camera needs its session's no-contact reference: name {what} "
            f"({spell(named, example)}), or {spell('reference', PRE_CONTACT)} to use the trial's first frames",
        )
    if name is not None:
        if not isinstance(name, str) or not name.strip():
            raise RecordingImportError(
                where, field(named), f"must be a {'topic' if topic else 'file name'}, got {name!r}"
            )
        if not topic and Path(name).suffix.lower() not in REFERENCE_SUFFIXES:
            raise RecordingImportError(
                where,
                field(named),
                f"{name!r}: a reference file is an image, a video or a .npy of frames "
                f"({', '.join(REFERENCE_SUFFIXES)}), or {PRE_CONTACT!r} for the trial's first frames",
            )
        if frames is not None:
            raise RecordingImportError(
                where,
                field("reference_frames"),
                f"given with a named source ({name}), whose frames are all taken: "
                f"reference_frames counts the trial's first frames with reference = {PRE_CONTACT!r}",
            )
        return ReferenceSource(name)
    if value != PRE_CONTACT:
        raise RecordingImportError(
            where,
            field("reference"),
            f"must be {PRE_CONTACT!r} (the trial's first frames; a topic is named by "
            f"{field('reference_topic')}), got {value!r}",
        )
    if frames is not None and (
        isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= archive.MAX_REFERENCE_FRAMES
    ):
        raise RecordingImportError(
            where,
            field("reference_frames"),
            f"must be an integer in [1, {archive.MAX_REFERENCE_FRAMES}], got {frames!r}",
        )
    return ReferenceSource(None, DEFAULT_REFERENCE_FRAMES if frames is None else frames, asked_by)


def pre_contact(source: ReferenceSource, frame_times: np.ndarray, images: np.ndarray, where) -> ImportedReference:
    """The recording's first `source.frames` frames (before any dropped for alignment: the earliest
    hold a contact least), at their own times."""
    n = source.frames
    if n > len(images):
        raise RecordingImportError(
            where, "reference_frames", f"{n} pre-contact frames asked for, the recording has {len(images)}"
        )
    first = "frame" if n == 1 else f"{n} frames"
    return ImportedReference(
        images[:n].copy(),
        frame_times[:n].copy(),
        f"imported: the trial's first {first} (pre-contact, as {source.asked_by} asks)",
    )


def file_reference(folder: Path, source: ReferenceSource, size: tuple[int, int]) -> ImportedReference:
    """The frames of the reference file `source` names, relative to the trial folder, at the
    camera's frame size; a file holds no times."""
    frames = read_reference(folder / source.name, size)
    return ImportedReference(
        frames, None, f"imported: {_frames(len(frames))} of the file {source.name} (relative to the trial folder)"
    )


def _frames(n: int) -> str:
    return "1 frame" if n == 1 else f"{n} frames"


def session_of(fields: dict[str, Any]) -> str:
    """meta.reference.session: the session the manifest or mapping names, else the trial's day and
    condition (`day2_lab`, as the simulator names them), else, without days, the trial's own name:
    trials are said to share a session only where the data says so."""
    if fields.get("session"):
        return str(fields["session"])
    if fields.get("day") is not None:
        return f"day{fields['day']}" + ("" if fields.get("condition") is None else f"_{fields['condition']}")
    return Path(archive.trial_filename(fields)).stem


def reference_meta(reference: ImportedReference, session: str, t0: float) -> dict[str, Any]:
    """meta.reference of a trial whose step clock starts at `t0` on the recording's clock."""
    times = None if reference.times is None else [round(float(t - t0), 6) for t in reference.times]
    return {"how": reference.how, "session": session, "times_s": times}


def check_seconds(times: np.ndarray, where, field: str, mics: list[Stream]) -> None:
    """Timestamps must be seconds on the microphones' clock: times spanning far more than the audio
    (milliseconds or microseconds put every step on the first reading) are an error. Which file it
    names follows their spacing: readings closer than `SECONDS_SPACING` are seconds, so the audio is
    cut short and the error names the microphone's file; spaced wider, the timestamps are named."""
    if not mics or len(times) < 2:
        return
    longest = max(mics, key=lambda m: len(m.samples) / m.rate)
    audio_s = len(longest.samples) / longest.rate
    span = float(times[-1] - times[0])
    if span <= SPAN_FACTOR * audio_s + 1.0:
        return
    spacing = float(np.median(np.diff(np.sort(times))))
    if spacing < SECONDS_SPACING:
        raise RecordingImportError(
            longest.name,
            "samples",
            f"{len(longest.samples)} samples, {audio_s:.2f} s at {longest.rate} Hz, far less than the {span:.2f} s "
            f"that {Path(str(where)).name}'s {field} column spans (readings {spacing:g} s apart): the file is cut short"
            + ("" if len(mics) == 1 else " (no other microphone's file is longer)"),
        )
    raise RecordingImportError(
        where,
        field,
        f"timestamps span {span:g}, but the microphones hold {audio_s:.2f} s of audio: "
        "timestamps must be seconds (these look like milliseconds or another clock)",
    )


def short_of_a_window(
    mics: list[Stream], held: list[int], windows: list[int], rates: list[int]
) -> RecordingImportError | None:
    """The error naming the first microphone that holds fewer samples (`held`, at `rates`) than one
    step's window (`windows`, at the same rates), or None: such a recording gives no step at all,
    so it, not the stream left without audio, is what to name."""
    for mic, n, window, rate in zip(mics, held, windows, rates):
        if n < window:
            return RecordingImportError(
                mic.name,
                "samples",
                f"{len(mic.samples)} samples ({len(mic.samples) / mic.rate:.3f} s at {mic.rate} Hz), shorter than "
                f"one step's window ({window} samples at {rate} Hz, {window / rate:.3f} s): the recording is cut short",
            )
    return None


def stream_gaps(times: np.ndarray, steps: np.ndarray, period: float) -> list[dict[str, float]]:
    """The holes of a stream (readings at `times`) longer than HOLE_STEPS step periods within the
    steps' span: the steps inside one hold its last reading. Each: when it starts (s, on the
    recording's clock), how long it lasts, and how many steps hold the stale reading."""
    gaps = np.flatnonzero(np.diff(times) > HOLE_STEPS * period)
    out = []
    for k in gaps:
        inside = int(np.count_nonzero((steps > times[k]) & (steps < times[k + 1])))
        if inside:
            out.append(
                {
                    "from_s": round(float(times[k]), 6),
                    "seconds": round(float(times[k + 1] - times[k]), 6),
                    "steps": inside,
                }
            )
    return out


def _at_archive_rate(stream: Stream, resample: bool, resampled: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
            stream.name,
            "audio",
            f"about {steps[k - 1]:.3f} s of samples missing before t={times[k] - times[0]:.3f} s "
            "(a message was lost; the windows after it cannot be placed)",
        )
    if stream.rate != archive.AUDIO_RATE:
        if not resample:
            raise RecordingImportError(
                stream.name,
                "rate",
                f"sample rate {stream.rate} Hz, archives hold {archive.AUDIO_RATE} Hz "
                "(pass --resample to convert with scipy.signal.resample_poly)",
            )
        from scipy.signal import resample_poly

        ratio = Fraction(archive.AUDIO_RATE, stream.rate)
        audio = np.round(resample_poly(audio.astype(np.float64), ratio.numerator, ratio.denominator))
        audio = np.clip(audio, np.iinfo(np.int32).min, np.iinfo(np.int32).max).astype(np.int32)
        counts = np.floor(counts * float(ratio)).astype(np.int64)
        resampled[stream.name] = {
            "from_hz": stream.rate,
            "to_hz": archive.AUDIO_RATE,
            "method": "scipy.signal.resample_poly",
        }
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
    reference: ReferenceSource,
    named: ImportedReference | None = None,
    resample: bool = False,
    force_gain: float = ForceProxy.gain,
    force_deadband: float = ForceProxy.deadband,
    step_rate: float | None = None,
    joint_fields_absent: list[str] | tuple[str, ...] = (),
    clocks: dict[str, Any] | None = None,
    complete: bool = True,
    notes: dict[str, Any] | None = None,
) -> archive.TrialArchive:
    """The recorder's alignment (module docstring) of streams with timestamps in seconds.

    `reference`: where the session reference comes from; `named`: its frames as read from the
    named topic or file (None for pre_contact: the recording's first frames). `trial`: fabric_id,
    day, trial, condition and optionally the session (meta.reference.session).
    `step_rate`: the camera's frame rate, the archive's step rate; None measures it (`step_rate_of`).
    `joint_fields_absent`: JOINT_FIELDS the recording lacks (NaN in `joints`; meta.streams.joints.absent).
    `clocks`: how each stream was placed in time (meta.import.clocks). `complete`: False for a
    recording cut off (meta.complete); `notes`: more of meta.import (e.g. the truncated files)."""
    where = source.get("path", "<recording>")
    if len(mics) != len(archive.MIC_NAMES):
        raise RecordingImportError(
            where, "mics", f"need {len(archive.MIC_NAMES)} microphones {archive.MIC_NAMES}, got {len(mics)}"
        )
    for name, times in (("camera", frame_times), ("joints", joint_times)):
        if len(times) == 0:
            raise RecordingImportError(where, name, "no messages")
    order = np.argsort(frame_times, kind="stable")
    frame_times, images = frame_times[order], images[order]
    keep = np.concatenate([[True], np.diff(frame_times) > 0])  # a repeated frame time is one frame
    duplicates = int(np.count_nonzero(~keep))
    frame_times, images = frame_times[keep], images[keep]
    ref = named if reference.name is not None else pre_contact(reference, frame_times, images, where)
    jorder = np.argsort(joint_times, kind="stable")
    joint_times, joints = joint_times[jorder], joints[jorder]

    resampled: dict[str, Any] = {}
    audio, ends, held = [], [], []
    for mic in mics:
        samples, times, counts = _at_archive_rate(mic, resample, resampled)
        k = np.searchsorted(times, frame_times, side="right") - 1
        ends.append(np.where(k >= 0, counts[np.maximum(k, 0)], 0))
        audio.append(samples)
        held.append(int(counts[-1]))
    window_end = np.stack(ends, axis=1).astype(np.int64)
    jk = np.searchsorted(joint_times, frame_times, side="right") - 1
    usable = (window_end >= archive.WINDOW).all(axis=1) & (jk >= 0)
    if not usable.any():
        if short := short_of_a_window(mics, held, [archive.WINDOW] * len(mics), [archive.AUDIO_RATE] * len(mics)):
            raise short
        full = (window_end >= archive.WINDOW).all(axis=1)
        first_full = f"{frame_times[np.argmax(full)]:.3f} s" if full.any() else "none"
        raise RecordingImportError(
            where,
            "camera",
            f"no frame comes after a full audio window and a joint reading: frames span "
            f"{frame_times[0]:.3f}-{frame_times[-1]:.3f} s, the first with a full audio window: "
            f"{first_full}, the first "
            f"joint reading: {joint_times[0]:.3f} s (streams on different clocks? see the mapping's clock keys)",
        )
    first = int(np.argmax(usable))
    frame_times, images, window_end, jk = frame_times[first:], images[first:], window_end[first:], jk[first:]

    # the archive's audio rows are equally long: frames whose window would reach past the shorter
    # microphone's end are dropped rather than given a misplaced window
    n_samples = min(len(a) for a in audio)
    inside = int(np.count_nonzero((window_end <= n_samples).all(axis=1)))
    dropped_at_end = len(frame_times) - inside
    if inside == 0:
        raise RecordingImportError(
            where,
            "audio",
            f"the microphones' recordings differ in length: the shorter ({n_samples} samples) ends before "
            f"the first frame",
        )
    frame_times, images, window_end, jk = frame_times[:inside], images[:inside], window_end[:inside], jk[:inside]
    rate, rate_from = (step_rate, "mapping camera.rate") if step_rate else step_rate_of(frame_times)
    gaps = integrity.frame_gaps(frame_times, rate)
    proxy = ForceProxy(
        ref.frames[0], gain=force_gain, deadband=force_deadband
    )  # as the recorder's, against the session's reference
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
        source={**source, "reference": reference.describe()},
        image_size=images.shape[1:3],
        complete=complete,
        streams=archive.hand_streams(images.shape[1:3], step_rate=rate, joint_fields_absent=joint_fields_absent),
        closing_steps=0,  # the procedure's phases are not in other labs' recordings: every step counts
        force_proxy={
            "gain": force_gain,
            "deadband": force_deadband,
            "reference": "the session reference's first frame",
        },
        reference=reference_meta(ref, session_of(trial), float(frame_times[0])),
        **{
            "import": {
                "step_rate_from": rate_from,
                "frames_dropped_before_start": first,
                "frames_dropped_at_end": dropped_at_end,
                "duplicate_frames_dropped": duplicates,
                "frame_gaps": [
                    {"step": int(k), "seconds": round(float(frame_times[k] - frame_times[k - 1]), 6)} for k in gaps
                ],
                "joint_gaps": stream_gaps(joint_times, frame_times, 1.0 / rate),
                "resampled": resampled,
                **({"clocks": clocks} if clocks else {}),
                **(notes or {}),
            }
        },
    )
    return archive.TrialArchive(
        meta=meta,
        timestamps=(frame_times - frame_times[0]).astype(np.float64),
        window_end=window_end,
        joints=joints[jk].astype(np.float32),
        force=np.array([proxy(im) for im in images], np.float32),
        audio=np.stack([a[:n_samples] for a in audio]),
        images=np.ascontiguousarray(images, dtype=np.uint8),
        reference=np.ascontiguousarray(ref.frames, dtype=np.uint8),
    )


def step_rate_of(frame_times: np.ndarray) -> tuple[float, str]:
    """The camera's frame rate from its median frame interval (lost frames do not move a median):
    the nearest whole rate when within 1 % of it (29.97 fps is 30), else to 0.01 Hz; and how it was found."""
    if len(frame_times) < 2:
        return archive.STEP_RATE, "a single frame: the recorder's rate"
    interval = float(np.median(np.diff(frame_times)))
    rate = 1.0 / interval
    whole = round(rate)
    return (
        int(whole) if abs(rate - whole) <= 0.01 * rate else round(rate, 2)
    ), f"median frame interval {interval * 1e3:.2f} ms"
