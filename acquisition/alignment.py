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
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

import numpy as np

from acquisition.camera import ForceProxy
from acquisition.recording import RecordingImportError, Stream
from fabricjax import archive, catalog, integrity

HOLE_STEPS = 3  # a stream silent for more than this many step periods has a hole (declared in meta.import)
SPAN_FACTOR = 10  # timestamps spanning this many times the audio's duration are not seconds


def check_seconds(times: np.ndarray, where, field: str, mics: list[Stream]) -> None:
    """Timestamps must be seconds on the microphones' clock: times spanning far more than the audio
    (milliseconds or microseconds put every step on the first reading) are an error."""
    if not mics or len(times) < 2:
        return
    audio_s = max(len(m.samples) / m.rate for m in mics)
    span = float(times[-1] - times[0])
    if span > SPAN_FACTOR * audio_s + 1.0:
        raise RecordingImportError(where, field, f"timestamps span {span:g}, but the microphones hold {audio_s:.2f} s of audio: "
                                   "timestamps must be seconds (these look like milliseconds or another clock)")


def stream_gaps(times: np.ndarray, steps: np.ndarray, period: float) -> list[dict[str, float]]:
    """The holes of a stream (readings at `times`) longer than HOLE_STEPS step periods within the
    steps' span: the steps inside one hold its last reading. Each: when it starts (s, on the
    recording's clock), how long it lasts, and how many steps hold the stale reading."""
    gaps = np.flatnonzero(np.diff(times) > HOLE_STEPS * period)
    out = []
    for k in gaps:
        inside = int(np.count_nonzero((steps > times[k]) & (steps < times[k + 1])))
        if inside:
            out.append({"from_s": round(float(times[k]), 6), "seconds": round(float(times[k + 1] - times[k]), 6), "steps": inside})
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
    complete: bool = True,
    notes: dict[str, Any] | None = None,
) -> archive.TrialArchive:
    """The recorder's alignment (module docstring) of streams with timestamps in seconds.

    `step_rate`: the camera's frame rate, the archive's step rate; None measures it (`step_rate_of`).
    `joint_fields_absent`: JOINT_FIELDS the recording lacks (NaN in `joints`; meta.streams.joints.absent).
    `clocks`: how each stream was placed in time (meta.import.clocks). `complete`: False for a
    recording cut off (meta.complete); `notes`: more of meta.import (e.g. the truncated files)."""
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
        samples, times, counts = _at_archive_rate(mic, resample, resampled)
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
        complete=complete,
        streams=archive.hand_streams(images.shape[1:3], step_rate=rate, joint_fields_absent=joint_fields_absent),
        closing_steps=0,  # the procedure's phases are not in other labs' recordings: every step counts
        force_proxy={"gain": force_gain, "deadband": force_deadband, "reference": "first kept frame"},
        **{"import": {
            "step_rate_from": rate_from,
            "frames_dropped_before_start": first,
            "frames_dropped_at_end": dropped_at_end,
            "duplicate_frames_dropped": duplicates,
            "frame_gaps": [{"step": int(k), "seconds": round(float(frame_times[k] - frame_times[k - 1]), 6)} for k in gaps],
            "joint_gaps": stream_gaps(joint_times, frame_times, 1.0 / rate),
            "resampled": resampled,
            **({"clocks": clocks} if clocks else {}),
            **(notes or {}),
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
