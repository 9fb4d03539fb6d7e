"""Recordings of a rig unlike the paper's hand, as trial archives: its streams as it has them.

A rig file (TOML) says what one trial folder holds (docs/data.md, "Recordings from another rig"):

    [steps]
    rate = 50                      # Hz: the step clock when there is no camera (omit it to step
                                   # at the joint stream's timestamps)
    mic_window_s = 0.5             # optional: every microphone's step window in seconds (each
                                   # step's PSD), recorded in the archives and used when the data
                                   # is loaded unless `--set mic_window_s` says otherwise (omitted:
                                   # the paper's 2048 samples at 48 kHz, 42.67 ms)
    [[mics]]                       # any number, each a mono WAV at its own rate
    name = "vibration"
    file = "vibration.wav"
    role = "internal"              # the model input it feeds: "internal" (the sensor at the
                                   # contact), "external" (away from it), or omitted (none)
    [joints]                       # optional
    file = "joints.csv"            # a `time` column and one `<name>_<field>` column per value
    names = ["j1", "j2"]
    fields = ["angle", "torque"]
    units = ["rad", "N m"]
    [camera]                       # optional: camera.<video> or camera/ + frames.csv, as the
                                   # hand's folders; its frames are then the step clock
    reference = "reference.png"    # required with a camera: its session's no-contact frames, a
                                   # file relative to the trial folder (an image, a video or a
                                   # .npy of uint8 RGB frames, at the camera's size;
                                   # "../reference.png": one file beside a session's folders),
                                   # or "pre_contact": the trial's own first frames
    reference_frames = 5           # with "pre_contact": how many (default 5)

A camera whose table names no reference is an error (`alignment.parse_reference`): the importer
never takes one on its own. meta.reference.session is the manifest's `session` column, else the
trial's day and condition, else (no days) the trial's own name.

Alignment is the recorder's rule (`fabricjax.importers.alignment`): at each step, each microphone's
window ends after the last sample at or before it, the joints are the latest reading at or before
it; steps before every microphone holds a full window at its own rate (2048 samples, or the rig
file's mic_window_s where that is longer), before the
first joint reading, or after any stream's end are dropped and counted in meta.import; a hole in
the joints longer than `alignment.HOLE_STEPS` steps, where steps hold the last reading, is listed
in meta.import.joint_gaps. Timestamps are seconds (times spanning far more than the audio are an
error), and a WAV file cut off before its header's length makes the trial `complete: false`. Nothing is
resampled or invented: a rig without a camera has no frames and no force, one microphone is one
audio row. Columns of the joints file the rig file does not name are listed in
meta.import.ignored_columns (the batch importer reports them).
"""

from __future__ import annotations

import csv
import dataclasses
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from fabricjax.features import welch
from fabricjax.importers.alignment import (
    ImportedReference,
    ReferenceSource,
    check_seconds,
    file_reference,
    parse_reference,
    pre_contact,
    reference_meta,
    session_of,
    short_of_a_window,
    stream_gaps,
)
from fabricjax.importers.mapping_file import read_toml
from fabricjax.importers.streams import RecordingImportError, Stream
from fabricjax.importers.trial_files import read_camera, read_wav
from fabricjax.store import archive


@dataclasses.dataclass(frozen=True)
class RigMic:
    name: str
    file: str
    role: str | None


@dataclasses.dataclass(frozen=True)
class Rig:
    """What a trial folder of the rig holds (the rig file, checked)."""

    mics: tuple[RigMic, ...]
    joints_file: str | None
    joint_names: tuple[str, ...]
    joint_fields: tuple[str, ...]
    joint_units: tuple[str, ...]
    camera: bool
    step_rate: float | None
    mic_window_s: float | None = None  # the microphones' step window [s], None: not declared
    reference: ReferenceSource | None = None  # where the camera's session reference comes from; None: no camera


def load_rig(path: str | Path) -> Rig:
    """The rig file, checked: a mistake is a one-line error naming the file and the key."""
    path = Path(path)
    doc = read_toml(path, "rig")
    known = {"steps", "mics", "joints", "camera"}
    if set(doc) - known:
        raise RecordingImportError(
            path, ", ".join(sorted(set(doc) - known)), f"unknown table (known: {', '.join(sorted(known))})"
        )
    mics = []
    for k, m in enumerate(doc.get("mics", [])):
        for key in ("name", "file"):
            if not isinstance(m.get(key), str):
                raise RecordingImportError(path, f"mics[{k}].{key}", "missing")
        if m.get("role") not in (*archive.MIC_ROLES, None):
            raise RecordingImportError(
                path, f"mics[{k}].role", f"must be one of {archive.MIC_ROLES} or omitted, got {m['role']!r}"
            )
        mics.append(RigMic(m["name"], m["file"], m.get("role")))
    roles = [m.role for m in mics if m.role]
    if len(roles) != len(set(roles)):
        raise RecordingImportError(path, "mics", f"two microphones feed the same input: roles {roles}")
    joints = doc.get("joints")
    if joints is not None:
        for key in ("file", "names", "fields", "units"):
            if key not in joints:
                raise RecordingImportError(path, f"joints.{key}", "missing")
        if len(joints["units"]) != len(joints["fields"]):
            raise RecordingImportError(
                path, "joints.units", f"{len(joints['units'])} units for {len(joints['fields'])} fields"
            )
    steps = doc.get("steps", {})
    rate = steps.get("rate")
    if rate is not None and (not isinstance(rate, (int, float)) or rate <= 0):
        raise RecordingImportError(path, "steps.rate", f"must be a rate in Hz > 0, got {rate!r}")
    window = steps.get("mic_window_s")
    if window is not None and (
        isinstance(window, bool) or not isinstance(window, (int, float)) or not 0 < window < float("inf")
    ):
        raise RecordingImportError(path, "steps.mic_window_s", f"must be a duration in seconds > 0, got {window!r}")
    unknown = set(steps) - {"rate", "mic_window_s"}
    if unknown:
        raise RecordingImportError(path, f"steps.{sorted(unknown)[0]}", "unknown key (known: rate, mic_window_s)")
    camera = "camera" in doc
    reference = None
    if camera:
        table = doc["camera"]
        if not isinstance(table, dict):
            raise RecordingImportError(path, "camera", f"must be a table ([camera]), got {table!r}")
        if set(table) - {"reference", "reference_frames"}:
            raise RecordingImportError(
                path,
                f"camera.{sorted(set(table) - {'reference', 'reference_frames'})[0]}",
                "unknown key (known: reference, reference_frames)",
            )
        reference = parse_reference(table, path)
    if not camera and rate is None and joints is None:
        raise RecordingImportError(
            path, "steps.rate", "missing: without a camera or joints, steps need a declared rate"
        )
    if not mics and joints is None and not camera:
        raise RecordingImportError(path, "<file>", "declares no stream (mics, joints or camera)")
    return Rig(
        mics=tuple(mics),
        joints_file=None if joints is None else joints["file"],
        joint_names=tuple(joints["names"]) if joints else (),
        joint_fields=tuple(joints["fields"]) if joints else (),
        joint_units=tuple(joints["units"]) if joints else (),
        camera=camera,
        step_rate=None if rate is None else float(rate),
        mic_window_s=None if window is None else float(window),
        reference=reference,
    )


def missing_files(folder: Path, rig: Rig) -> list[str]:
    """The files the rig file names that `folder` lacks (every one, not the first)."""
    files = [m.file for m in rig.mics] + ([rig.joints_file] if rig.joints_file else [])
    files += [rig.reference.name] if rig.reference is not None and rig.reference.name is not None else []
    return [f for f in files if not (folder / f).is_file()]


def check_layout(folder: Path, rig: Rig) -> None:
    """A one-line error naming every file of the rig file that the trial folder lacks."""
    if not folder.is_dir():
        raise RecordingImportError(folder, "<folder>", "no such trial folder")
    missing = missing_files(folder, rig)
    if missing:
        raise RecordingImportError(folder, "<folder>", f"missing {', '.join(missing)} (named by the rig file)")


def read_joints(path: Path, rig: Rig) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Times, (N, J, F) values and the columns not used, from a UTF-8 CSV with a header row."""
    if not path.is_file():
        raise RecordingImportError(path, "<file>", "no such file")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            header = [h.strip() for h in next(csv.reader(f), [])]
    except UnicodeDecodeError as e:
        raise RecordingImportError(path, "<file>", f"not UTF-8 text: {e}") from None
    wanted = ["time", *(f"{j}_{f}" for j in rig.joint_names for f in rig.joint_fields)]
    for col in wanted:
        if col not in header:
            raise RecordingImportError(path, col, "column missing")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # no rows is the error below, not a warning
            table = np.loadtxt(
                path, delimiter=",", skiprows=1, usecols=[header.index(c) for c in wanted], ndmin=2, encoding="utf-8"
            )
    except ValueError as e:
        raise RecordingImportError(path, "<file>", f"not a numeric CSV: {e}") from None
    if len(table) == 0:
        raise RecordingImportError(path, "<rows>", "no readings (a header row only)")
    if not np.all(np.isfinite(table)):
        col = wanted[int(np.argmin(np.all(np.isfinite(table), axis=0)))]
        raise RecordingImportError(path, col, "empty or non-numeric values")
    values = table[:, 1:].reshape(-1, len(rig.joint_names), len(rig.joint_fields))
    return table[:, 0], values, [h for h in header if h not in wanted]


def step_times(
    rig: Rig, mics: list[Stream], joint_times: np.ndarray | None, frame_times: np.ndarray | None
) -> tuple[np.ndarray, str, float]:
    """The step clock: the camera's frames, else the declared rate from 0 to the end of the shortest
    stream, else the joint stream's timestamps. Returns (times, clock, nominal rate)."""
    if frame_times is not None:
        rate = 1.0 / float(np.median(np.diff(frame_times))) if len(frame_times) > 1 else archive.STEP_RATE
        return frame_times, "camera", rate
    if rig.step_rate is None:
        rate = 1.0 / float(np.median(np.diff(joint_times))) if len(joint_times) > 1 else 1.0
        return joint_times, "joints", rate
    ends = [m.times[-1] for m in mics] + ([joint_times[-1]] if joint_times is not None else [])
    return np.arange(int(np.floor(min(ends) * rig.step_rate)) + 1) / rig.step_rate, "rate", rig.step_rate


def align_rig(
    rig: Rig,
    *,
    mics: list[Stream],
    joint_times: np.ndarray | None,
    joints: np.ndarray | None,
    frame_times: np.ndarray | None,
    images: np.ndarray | None,
    meta_fields: dict[str, Any],
    source: dict[str, Any],
    ignored_columns: list[str],
    truncated: list[str] = (),
    named: ImportedReference | None = None,
    session: str | None = None,
) -> archive.TrialArchive:
    """The recorder's alignment (module docstring) of the rig's streams; `meta_fields` are the
    trial's label, label map, split, day, trial, condition and properties; `truncated`: the files
    cut off before their header's length (the trial is then `complete: false`). With a camera, the
    session reference is `named` (the rig file's reference file, as read) or the recording's first
    frames (pre_contact), of `session` (default: `alignment.session_of`)."""
    where = source.get("path", "<recording>")
    ref = None
    if images is not None:
        ref = named if rig.reference.name is not None else pre_contact(rig.reference, frame_times, images, where)
        source = {**source, "reference": rig.reference.describe()}
    times, clock, rate = step_times(rig, mics, joint_times, frame_times)
    n = len(times)
    usable = np.ones(n, bool)
    ends = []
    windows = [max(archive.WINDOW, welch.window_samples(rig.mic_window_s or 0, int(mic.rate))) for mic in mics]
    for mic, window in zip(mics, windows):
        k = np.searchsorted(mic.times, times, side="right") - 1
        end = np.where(k >= 0, mic.counts[np.maximum(k, 0)], 0)
        usable &= end >= window
        usable &= times <= mic.times[-1]  # after its last sample a window would be stale
        ends.append(end)
    if joint_times is not None:
        jk = np.searchsorted(joint_times, times, side="right") - 1
        usable &= (jk >= 0) & (times <= joint_times[-1])
    if not usable.any():
        if short := short_of_a_window(mics, [len(m.samples) for m in mics], windows, [int(m.rate) for m in mics]):
            raise short
        raise RecordingImportError(
            where,
            "steps",
            "no step has a full window of every microphone and a joint reading "
            f"(microphones need {archive.WINDOW} samples, or the rig file's mic_window_s where longer, at "
            f"their own rate before the first step)",
        )
    keep = np.flatnonzero(usable)
    first, last = int(keep[0]), int(keep[-1])
    if not usable[first : last + 1].all():
        raise RecordingImportError(
            where, "steps", "a stream stops and resumes within the recording (a hole): it cannot be aligned"
        )
    sel = slice(first, last + 1)
    n_samples = max((len(m.samples) for m in mics), default=0)
    audio = np.zeros((len(mics), n_samples), np.int32)  # a mic at a lower rate is zero-padded at the end
    for k, m in enumerate(mics):
        audio[k, : len(m.samples)] = m.samples
    streams = {
        "mics": [
            {"name": rm.name, "rate": int(m.rate), "role": rm.role}
            | ({"recorded_as": m.recorded_as} if m.recorded_as else {})
            for rm, m in zip(rig.mics, mics)
        ],
        "joints": {"names": list(rig.joint_names), "fields": list(rig.joint_fields), "units": list(rig.joint_units)}
        if rig.joints_file
        else None,
        "camera": None if images is None else {"image_size": [int(images.shape[1]), int(images.shape[2])]},
        "force": None,
        "steps": {"clock": clock, "rate": round(rate, 6)}
        | ({} if rig.mic_window_s is None else {"mic_window_s": rig.mic_window_s}),
        "audio_format": archive.AUDIO_FORMAT
        + "".join(f"; {rm.name}: from {m.recorded_as}" for rm, m in zip(rig.mics, mics) if m.recorded_as),
    }
    notes = {
        "steps_dropped_before_start": first,
        "steps_dropped_at_end": n - 1 - last,
        "ignored_columns": ignored_columns,
    }
    if joint_times is not None:
        notes["joint_gaps"] = stream_gaps(joint_times, times[sel], 1.0 / rate)
    if truncated:
        notes["truncated"] = list(truncated)
    described = (
        {}
        if ref is None
        else {"reference": reference_meta(ref, session_of({**meta_fields, "session": session}), float(times[first]))}
    )
    meta = archive.make_meta(
        **meta_fields,
        source=source,
        image_size=None,
        streams=streams,
        closing_steps=0,
        complete=not truncated,
        **{"import": notes},
        **described,
    )
    return archive.TrialArchive(
        meta=meta,
        timestamps=(times[sel] - times[first]).astype(np.float64),
        window_end=(np.stack(ends, axis=1)[sel] if mics else np.zeros((last + 1 - first, 0))).astype(np.int64),
        joints=None if joints is None else joints[jk[sel]].astype(np.float32),
        force=None,
        audio=audio,
        images=None if images is None else np.ascontiguousarray(images[sel], dtype=np.uint8),
        reference=None if ref is None else np.ascontiguousarray(ref.frames, dtype=np.uint8),
    )


def import_rig_folder(
    folder: str | Path, rig: Rig, meta_fields: dict[str, Any], *, session: str | None = None
) -> archive.TrialArchive:
    """One trial folder of the rig (module docstring) as an archive; `session`: the session whose
    camera reference the trial shares (meta.reference.session; default `alignment.session_of`)."""
    folder = Path(folder)
    check_layout(folder, rig)
    mics = [read_wav(folder / m.file, 0.0) for m in rig.mics]  # the hand folders' WAV reader
    joint_times = joints = None
    ignored: list[str] = []
    if rig.joints_file:
        joint_times, joints, ignored = read_joints(folder / rig.joints_file, rig)
        check_seconds(joint_times, folder / rig.joints_file, "time", mics)
        order = np.argsort(joint_times, kind="stable")
        joint_times, joints = joint_times[order], joints[order]
    frame_times = images = named = None
    if rig.camera:
        frame_times, images = read_camera(folder)  # the hand folders' camera reader
        check_seconds(frame_times, folder / "frames.csv", "time", mics)
        named = None if rig.reference.name is None else file_reference(folder, rig.reference, images.shape[1:3])
    return align_rig(
        rig,
        mics=mics,
        joint_times=joint_times,
        joints=joints,
        frame_times=frame_times,
        images=images,
        meta_fields=meta_fields,
        source={"kind": "rig_folder", "path": str(folder)},
        ignored_columns=ignored,
        truncated=[m.file for m, s in zip(rig.mics, mics) if s.truncated],
        named=named,
        session=session,
    )
