"""The trial archive: the one contract between acquisition / simulator and everything downstream.

One `.npz` per trial, loadable with `allow_pickle=False`. An archive holds the streams its rig has;
the meta's `streams` declares them (`Layout`, read with `layout(meta)`):

==============  =====================  ======================================================
key             dtype, shape           meaning
==============  =====================  ======================================================
meta            0-d unicode            JSON object, see `REQUIRED_META`
timestamps      float64 (T,)           time of each step, seconds (the step clock:
                                       streams.steps, a camera frame or a declared rate)
window_end      int64 (T, M)           exclusive end index, in each microphone's own stream, of
                                       the 2048-sample window that belongs to the step
audio           int32 (M, S)           raw SPH0645-style I2S words (18 valid bits in 31..14),
                                       row k = streams.mics[k] at its own rate; a mic with
                                       fewer samples than S is zero-padded at the end (no
                                       window reaches into the padding)
joints          float32 (T, J, F)      streams.joints: J named joints x F fields (units from
                                       the recording); absent when the rig has none; NaN in
                                       a field streams.joints.absent lists
force           float32 (T,)           estimated normal force at the Minsight tip, N; absent
                                       when the rig has no camera to estimate it from
images          uint8 (T, H, W, 3)     camera frames; absent when not recorded
reference       uint8 (R, H, W, 3)     the session's no-contact camera frames (format 3): what
                                       Minsight's own software reads every frame against;
                                       present exactly when meta.reference describes it
==============  =====================  ======================================================

The paper's hand (`hand_streams`: microphones "internal" and "external" at 48 kHz, 6 joints x
angle / velocity / current, Minsight at 50 Hz) is the default layout. Format version 1 (archives
written before layouts were declared) is read unchanged: its meta has no `streams`, and its layout
is the hand's, at meta.sample_rates.steps (the camera's frame rate; 50 unless an import recorded
another) and with NaN in the fields an optional top-level meta.joint_fields_absent lists (format
1's key for what format 2 writes as streams.joints.absent). Format version 2 adds to the meta:

    streams      {"mics": [{"name", "rate" (Hz), "role" ("internal" | "external" | null: which
                  model input it feeds)}], "joints": {"names", "fields", "units"} | null,
                  "camera": {"image_size": [H, W]} | null, "force": "N" | null,
                  "steps": {"clock": "camera" | "rate" | "joints", "rate": Hz}}
                 steps.mic_window_s (optional): every microphone's step window in seconds, the rig
                  file's choice, which loading uses unless the config sets one (absent: the paper's
                  2048 samples at 48 kHz, 42.67 ms)
                 joints.absent (optional, default []): fields the recording lacks, e.g. velocity
                  and current of a position-only ROS JointState; they are NaN in `joints`, never
                  zeros (which would read as a still, unpowered joint), and the proprio input is
                  not offered on such data. steps.rate is the camera's own frame rate when the
                  camera is the clock (a 30 fps camera: 30).
    label_map    optional {name: class}: the dataset's classes (0..K-1), set by the user; absent:
                  the catalog's 21 fabric classes (the paper's hand)
    label_name   optional, the trial's label as the user named it
    fabric_id    the catalog fabric the trial touched (the hand's and simulated trials); absent
                  where a label map names the trial's class (`label`, `label_name`): a rig's
                  recordings touch no catalog fabric. An archive carrying both reads the same
                  (its fabric_id is its label).
    condition    "lab" | "cafe", or null where the recording names none (a rig's manifest
                  without the column): the hand's protocol is not stamped on another rig's data
    split        optional "train" | "val" | "test" | "cafe" | "holdout": the user's split (absent:
                  by day, `splits.role_of`)
    day          int, or null for recordings without days
    properties   property levels only where known (a missing name or null: unknown)

Format version 3 adds the session reference: Minsight's camera node saves a no-contact frame after
its warm-up frames when it starts (and on a reset), and its force network reads every frame minus
that reference. The LED drive and the shell's seating move between sessions, so a frame means
little without the reference of its own session. An archive with frames may carry it as the
`reference` array and `meta.reference`:

    reference    {"how": how the frames were taken (one line), "session": the session's name
                  (trials of one session share it), "times_s": [R times on the trial's step clock,
                  before its first step when taken at the session's start] or null (not known)}

Archives of formats 1 and 2 have no reference and read unchanged (`reference_note` says so).

`write_archive` is atomic (temporary name in the same folder, fsync, rename); `read_archive`
validates every field by type and range and raises `ArchiveError` naming the file, the field and
the problem. It trusts no size a file declares: the meta JSON is bounded in length, nesting and
number size before it is parsed, each member's npy header is checked against the meta and the step
count before its data is inflated, inflation is bounded per member, and every member is checked
against its CRC-32.
A dataset is a folder of archives plus an index (`fabricjax.store.dataset_index`) recording each
archive's meta, size, mtime and sha256; `fabricjax.store.integrity` checks a dataset against it.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import time
import zipfile
import zlib
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from fabricjax.errors import UserError
from fabricjax.store.atomic import atomic_open

FORMAT_VERSION = 3  # what `write_archive` writes; READ_VERSIONS are read
READ_VERSIONS = (1, 2, 3)
REFERENCE_VERSION = 3  # the first format that can carry a session reference
# The time base and sample format of the paper's hand (the SPH0645 datasheet). This is their one
# definition: the simulator, acquisition and features import them from here (only the stdlib-only
# Pi side, `acquisition.wire.RATE`, repeats AUDIO_RATE; a test checks it). Other rigs declare their
# own rates in the meta (`streams`); WINDOW and the word format are every archive's.
WINDOW = 2048  # audio samples per step (the Welch window), at each microphone's own rate
AUDIO_RATE = 48000  # Hz, the hand's microphones
STEP_RATE = 50  # Hz, the hand: one step per Minsight frame
MINSIGHT_SIZE = (308, 410)  # H, W of a Minsight frame as its sensor code delivers it (cropped, resized)
# [protocol] no-contact frames a session's reference averages (recorder and simulator alike): one frame's
# shot noise would stay in every difference of that day, 30 frames cut it to 0.18 of that
REFERENCE_FRAMES = 30
VALID_BITS = 18  # valid bits of an SPH0645 I2S word, in bits 31..14
SAMPLE_SHIFT = 32 - VALID_BITS  # word = sample << SAMPLE_SHIFT; sample = word >> SAMPLE_SHIFT (arithmetic)
FULL_SCALE = 2.0 ** (VALID_BITS - 1)  # a signed 18-bit sample of this magnitude is full scale (+-1)
JOINT_NAMES = ("thumb_base", "thumb_mid", "thumb_tip", "middle_base", "middle_tip", "palm")
JOINT_FIELDS = ("angle", "velocity", "current")
N_JOINTS = len(JOINT_NAMES)
N_JOINT_FIELDS = len(JOINT_FIELDS)
N_PROPRIO = N_JOINTS * N_JOINT_FIELDS  # the proprio input: every joint's fields, flattened joint-major
MIC_NAMES = ("internal", "external")
# The model inputs a microphone can feed (its `role`): the one in the touching fingertip, and one
# away from the contact (the hand's palm). Their names are the hand's microphones'.
MIC_ROLES = MIC_NAMES
CAMERA_MODALITIES = ("image", "flow")  # the model inputs read from the camera's frames (rendered ones in simulation)
AUDIO_FORMAT = "SPH0645 I2S word (int32; 18 valid bits in bits 31..14)"
UNITS = {
    "timestamps": "s",
    "joints": ["rad", "rad/s", "A"],
    "force": "N",
    "audio": AUDIO_FORMAT,
}
STEP_CLOCKS = ("camera", "rate", "joints")
_COMMON_META = {
    "format_version": int,
    "label": int,
    "properties": dict,
    "trial": int,
    "source": dict,
    "complete": bool,
}
REQUIRED_META = {  # by format version; an int is never a bool, a float is finite
    1: {
        **_COMMON_META,
        "fabric_id": int,
        "condition": str,
        "day": int,
        "sample_rates": dict,
        "image_size": (list, type(None)),
        "joint_names": list,
        "units": dict,
    },
    2: {**_COMMON_META, "condition": (str, type(None)), "day": (int, type(None)), "streams": dict},
}
REQUIRED_META[3] = REQUIRED_META[2]  # format 3 adds the optional session reference
OPTIONAL_META = {
    "fabric_id": int,  # format 2: required unless a label map names the trial's class
    "closing_steps": int,
    "label_name": str,
    "label_map": dict,
    "split": (str, type(None)),
    "import": dict,
    "force_proxy": dict,
    "reference": dict,
}
# Bounds of what a reader accepts, checked before the bytes they bound are parsed or inflated: a
# damaged or hostile file is an ArchiveError, never a reader that runs out of memory or time.
MAX_META_CHARS = 1 << 20  # characters of meta JSON (a meta is a few kB)
MAX_JSON_DEPTH = 64  # nesting of meta JSON (a meta nests 5 deep)
MAX_NUMBER_CHARS = 32  # characters of one JSON number (an int64 has 19 digits)
MAX_INT = 2**63 - 1  # integers of the meta fit an int64
MAX_RATE = 10_000_000  # Hz, any stream's rate (no sensor here samples faster)
MAX_IMAGE_SIDE = 16384  # pixels, a frame's height or width
MAX_MEMBERS = 64  # zip members of one archive (it holds at most 8 arrays)
MAX_REFERENCE_FRAMES = 256  # no-contact frames of one session's reference
MAX_MEMBER_BYTES = 16 << 30  # inflated bytes of one member
# A compressed member may inflate to FREE_INFLATION bytes, beyond that to INFLATION_RATIO times its
# compressed size: recorded signals compress a few times, a zip bomb a thousand times.
FREE_INFLATION = 64 << 20
READ_CHUNK = 256 << 10  # bytes read from a member at a time (numpy's own read size: small reads stay in cache)
INFLATION_RATIO = 64
CONDITIONS = ("lab", "cafe")
PROPERTY_NAMES = ("stretchiness", "roughness", "thickness")
SPLITS = ("train", "val", "test", "cafe", "holdout")  # a user's split (meta.split), as `data` names them


def nyquist_khz(rate: float) -> float:
    """The Nyquist frequency [kHz] of audio sampled at `rate` Hz: the top of its PSD's full band."""
    return rate / 2000


NYQUIST_KHZ = nyquist_khz(AUDIO_RATE)  # 24 kHz, the hand's microphones': the widest PSD bandwidth


class ArchiveError(UserError):
    """A trial archive or dataset index is unreadable or invalid."""

    def __init__(self, path: os.PathLike | str, field: str, problem: str):
        self.path, self.field, self.problem = str(path), field, problem
        super().__init__(f"{path}: field '{field}': {problem}")

    def __reduce__(self):
        # rebuilt from its three parts: a feature worker process raises it to the parent (the
        # default, cls(message), would fail to unpickle and hang the pool)
        return type(self), (self.path, self.field, self.problem)


@dataclasses.dataclass(frozen=True)
class Mic:
    name: str
    rate: int  # Hz
    role: str | None  # the model input it feeds (MIC_ROLES), None: none

    @property
    def nyquist_khz(self) -> float:
        return nyquist_khz(self.rate)


@dataclasses.dataclass(frozen=True)
class Layout:
    """The streams an archive holds, as its meta declares them."""

    mics: tuple[Mic, ...]
    joint_names: tuple[str, ...]
    joint_fields: tuple[str, ...]
    joint_units: tuple[str, ...]
    joint_fields_absent: tuple[str, ...]  # of joint_fields: not recorded, NaN in `joints`
    image_size: tuple[int, int] | None
    force: bool
    step_clock: str
    step_rate: float
    mic_window_s: float | None = None  # the microphones' step window [s] the data declares (None: not declared)

    @property
    def has_joints(self) -> bool:
        return bool(self.joint_names)

    def mic(self, role: str) -> int | None:
        """Index (row of `audio`) of the microphone feeding model input `role`, or None."""
        return next((k for k, m in enumerate(self.mics) if m.role == role), None)

    def modalities(self) -> tuple[str, ...]:
        """The model inputs (`config.MODALITIES`) this data can feed."""
        out = tuple(m.role for m in self.mics if m.role is not None)
        out += ("proprio",) if self.has_joints and not self.joint_fields_absent else ()  # NaN fields: no input
        return out + (CAMERA_MODALITIES if self.image_size is not None else ())

    def describe(self) -> str:
        """One line: what the data has."""
        mics = ", ".join(
            f"{m.name} ({m.rate} Hz" + (f", feeds {m.role})" if m.role else ", feeds no input)") for m in self.mics
        )
        fields = ", ".join(
            f"{f} [{u}]" + (" (not recorded)" if f in self.joint_fields_absent else "")
            for f, u in zip(self.joint_fields, self.joint_units)
        )
        joints = f"{len(self.joint_names)} joints x {fields}" if self.has_joints else "no joints"
        camera = f"camera {self.image_size[0]}x{self.image_size[1]}" if self.image_size else "no camera"
        return (
            f"microphones: {mics or 'none'}; {joints}; {camera}; steps at {self.step_rate:g} Hz "
            f"({self.step_clock} clock)"
        )


def hand_streams(
    image_size: tuple[int, int] | None,
    step_rate: float = STEP_RATE,
    joint_fields_absent: list[str] | tuple[str, ...] = (),
) -> dict[str, Any]:
    """`meta.streams` of the paper's hand; `image_size` None when frames are not recorded;
    `step_rate` the camera's frame rate when an imported recording's camera does not run at 50 Hz;
    `joint_fields_absent` the JOINT_FIELDS a recording lacks (a position-only ROS JointState)."""
    joints = {"names": list(JOINT_NAMES), "fields": list(JOINT_FIELDS), "units": list(UNITS["joints"])}
    return {
        "mics": [{"name": m, "rate": AUDIO_RATE, "role": m} for m in MIC_NAMES],
        "joints": joints | ({"absent": list(joint_fields_absent)} if joint_fields_absent else {}),
        "camera": None if image_size is None else {"image_size": [int(image_size[0]), int(image_size[1])]},
        "force": UNITS["force"],
        "steps": {"clock": "camera", "rate": step_rate},
        "audio_format": AUDIO_FORMAT,
    }


def layout(meta: dict[str, Any]) -> Layout:
    """The streams of a validated meta (format 1: the hand's, with its recorded image size, step
    rate and absent joint fields)."""
    if meta["format_version"] == 1:
        s = hand_streams(
            meta["image_size"], meta["sample_rates"].get("steps", STEP_RATE), meta.get("joint_fields_absent", ())
        )
    else:
        s = meta["streams"]
    j = s["joints"] or {"names": [], "fields": [], "units": []}
    cam = s["camera"]
    return Layout(
        mics=tuple(Mic(m["name"], int(m["rate"]), m.get("role")) for m in s["mics"]),
        joint_names=tuple(j["names"]),
        joint_fields=tuple(j["fields"]),
        joint_units=tuple(j["units"]),
        joint_fields_absent=tuple(j.get("absent", ())),
        image_size=None if cam is None else (int(cam["image_size"][0]), int(cam["image_size"][1])),
        force=s["force"] is not None,
        step_clock=s["steps"]["clock"],
        step_rate=float(s["steps"]["rate"]),
        mic_window_s=s["steps"].get("mic_window_s"),
    )


def fabric_or_class(meta: dict[str, Any]) -> int:
    """What the trial touched, by number: its catalog fabric (`fabric_id`), or for a trial a label
    map names, its class (`label`)."""
    return meta["fabric_id"] if "fabric_id" in meta else meta["label"]


def n_classes(meta: dict[str, Any]) -> int | None:
    """Classes of the trial's label map (K: classes 0..K-1), None without one (the catalog's)."""
    label_map = meta.get("label_map")
    return None if label_map is None else max(label_map.values()) + 1


@dataclasses.dataclass(frozen=True)
class TrialArchive:
    """One recorded or simulated trial, validated."""

    meta: dict[str, Any]
    timestamps: np.ndarray
    window_end: np.ndarray
    joints: np.ndarray | None
    force: np.ndarray | None
    audio: np.ndarray
    images: np.ndarray | None = None
    reference: np.ndarray | None = None  # (R, H, W, 3) the session's no-contact frames (format 3)

    @property
    def n_steps(self) -> int:
        return int(self.timestamps.shape[0])

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: v for k in _ARRAYS if (v := getattr(self, k)) is not None}


_ARRAYS = ("timestamps", "window_end", "joints", "force", "audio", "images", "reference")


def _spec(name: str, lay: Layout) -> tuple[Any, tuple]:
    """(dtype, shape with None for free dims and 'T' for the step count) of an array under `lay`."""
    return {
        "timestamps": (np.float64, ("T",)),
        "window_end": (np.int64, ("T", len(lay.mics))),
        "joints": (np.float32, ("T", len(lay.joint_names), len(lay.joint_fields))),
        "force": (np.float32, ("T",)),
        "audio": (np.int32, (len(lay.mics), None)),
        "images": (np.uint8, ("T", None, None, 3)),
        "reference": (np.uint8, (None, None, None, 3)),
    }[name]


def make_meta(
    *,
    fabric_id: int | None = None,
    properties: dict[str, int | None],
    day: int | None,
    trial: int,
    condition: str | None,
    source: dict[str, Any],
    image_size: tuple[int, int] | None,
    complete: bool = True,
    label: int | None = None,
    streams: dict[str, Any] | None = None,
    **extra: Any,
) -> dict[str, Any]:
    """Meta with every required field filled in the canonical way; `streams` defaults to the
    hand's (`hand_streams(image_size)`), and only the given property levels are kept. A catalog
    fabric's trial gives `fabric_id` (its label defaults to it), a trial of a label map its class
    `label` alone."""
    if fabric_id is None and label is None:
        raise ValueError("a trial needs its catalog fabric (fabric_id) or its class (label)")
    return {
        "format_version": FORMAT_VERSION,
        **({} if fabric_id is None else {"fabric_id": int(fabric_id)}),
        "label": int(fabric_id if label is None else label),
        "properties": {k: (None if v is None else int(v)) for k, v in properties.items()},
        "day": None if day is None else int(day),
        "trial": int(trial),
        "condition": condition,
        "source": source,
        "streams": hand_streams(image_size) if streams is None else streams,
        "complete": bool(complete),
        **extra,
    }


def _is(value: Any, typ) -> bool:
    """isinstance, where a bool is not an int and a float is finite."""
    types = typ if isinstance(typ, tuple) else (typ,)
    if isinstance(value, bool):
        return bool in types
    if isinstance(value, float):
        return float in types and bool(np.isfinite(value))
    return isinstance(value, types)


def _type_name(typ) -> str:
    types = typ if isinstance(typ, tuple) else (typ,)
    names = {
        int: "an integer",
        float: "a finite number",
        str: "a string",
        bool: "true or false",
        dict: "an object",
        list: "a list",
        type(None): "null",
    }
    return " or ".join(names[t] for t in types)


def _check_type(value: Any, typ, path, field: str) -> None:
    if not _is(value, typ):
        raise ArchiveError(path, field, f"must be {_type_name(typ)}, got {json.dumps(value)[:60]}")


def _check_count(value: Any, path, field: str, low: int = 0, high: int = MAX_INT) -> None:
    """An integer (never a bool) in [low, high]."""
    if not _is(value, int) or not low <= value <= high:
        raise ArchiveError(path, field, f"must be an integer in [{low}, {high}], got {json.dumps(value)[:60]}")


def _check_rate(value: Any, path, field: str, integer: bool = False) -> None:
    """A rate in Hz: finite, > 0, at most MAX_RATE (an integer where `integer`)."""
    if not _is(value, int if integer else (int, float)) or not 0 < value <= MAX_RATE:
        kind = "an integer rate" if integer else "a rate"
        raise ArchiveError(path, field, f"must be {kind} in Hz, > 0 and <= {MAX_RATE}, got {json.dumps(value)[:60]}")


def _check_image_size(size: Any, path, field: str) -> None:
    if not isinstance(size, list) or len(size) != 2 or not all(_is(x, int) and 1 <= x <= MAX_IMAGE_SIDE for x in size):
        raise ArchiveError(
            path, field, f"must be [H, W], two integers in [1, {MAX_IMAGE_SIDE}], got {json.dumps(size)[:60]}"
        )


def _check_strings(values: Any, path, field: str) -> None:
    if not isinstance(values, list) or not all(isinstance(x, str) for x in values):
        raise ArchiveError(path, field, f"must be a list of strings, got {json.dumps(values)[:60]}")


def _check_streams(streams: dict[str, Any], path) -> None:
    """The shape of a version-2 `meta.streams` (what `layout` reads)."""

    def need(cond: bool, field: str, problem: str) -> None:
        if not cond:
            raise ArchiveError(path, f"meta.streams.{field}", problem)

    for key in ("mics", "joints", "camera", "force", "steps"):
        need(key in streams, key, "missing (use null for a stream the rig does not have)")
    mics = streams["mics"]
    need(isinstance(mics, list), "mics", "must be a list")
    for k, m in enumerate(mics):
        need(isinstance(m, dict) and isinstance(m.get("name"), str), f"mics[{k}].name", "missing")
        _check_rate(m.get("rate"), path, f"meta.streams.mics[{k}].rate", integer=True)
        need(
            m.get("role") in (*MIC_ROLES, None),
            f"mics[{k}].role",
            f"must be one of {MIC_ROLES} or null, got {m.get('role')!r}",
        )
    roles = [m["role"] for m in mics if m.get("role")]
    need(len(roles) == len(set(roles)), "mics", f"two microphones feed the same input: roles {roles}")
    j = streams["joints"]
    need(j is None or isinstance(j, dict), "joints", 'must be null or {"names", "fields", "units"}')
    if j is not None:
        for key in ("names", "fields", "units"):
            _check_strings(j.get(key), path, f"meta.streams.joints.{key}")
        need(
            len(j["fields"]) == len(j["units"]),
            "joints.units",
            f"{len(j['units'])} units for {len(j['fields'])} fields",
        )
        need(len(j["names"]) > 0 and len(j["fields"]) > 0, "joints", "no names or no fields (use null for no joints)")
        _check_absent_fields(j.get("absent", []), j["fields"], path, "meta.streams.joints.absent")
    cam = streams["camera"]
    need(cam is None or isinstance(cam, dict), "camera", 'must be null or {"image_size": [H, W]}')
    if cam is not None:
        _check_image_size(cam.get("image_size"), path, "meta.streams.camera.image_size")
    need(
        streams["force"] is None or isinstance(streams["force"], str),
        "force",
        f'must be a unit ("N") or null, got {streams["force"]!r}',
    )
    steps = streams["steps"]
    need(isinstance(steps, dict) and steps.get("clock") in STEP_CLOCKS, "steps.clock", f"must be one of {STEP_CLOCKS}")
    _check_rate(steps.get("rate"), path, "meta.streams.steps.rate")
    window = steps.get("mic_window_s")
    need(
        window is None or (_is(window, (int, float)) and window > 0),
        "steps.mic_window_s",
        f"must be a duration in seconds > 0, got {json.dumps(window)[:60]}",
    )


def validate_meta(meta: Any, path: os.PathLike | str) -> dict[str, Any]:
    """Raise `ArchiveError` unless every field of `meta` has its type and range (the step count,
    which bounds closing_steps, is checked by `validate`)."""
    if not isinstance(meta, dict):
        raise ArchiveError(path, "meta", f"expected a JSON object, got {type(meta).__name__}")
    if "format_version" not in meta:
        raise ArchiveError(path, "meta.format_version", "missing")
    version = meta["format_version"]
    if not _is(version, int) or version not in READ_VERSIONS:
        raise ArchiveError(
            path, "meta.format_version", f"unknown format version {version!r} (this code reads {READ_VERSIONS})"
        )
    for key, typ in REQUIRED_META[version].items():
        if key not in meta:
            raise ArchiveError(path, f"meta.{key}", "missing")
        _check_type(meta[key], typ, path, f"meta.{key}")
    for key, typ in OPTIONAL_META.items():
        if key in meta:
            _check_type(meta[key], typ, path, f"meta.{key}")
    for key in ("fabric_id", "label", "trial", "closing_steps"):
        if key in meta:
            _check_count(meta[key], path, f"meta.{key}")
    if meta["day"] is not None:
        _check_count(meta["day"], path, "meta.day")
    if meta["condition"] is not None and meta["condition"] not in CONDITIONS:
        raise ArchiveError(path, "meta.condition", f"must be one of {CONDITIONS} or null, got {meta['condition']!r}")
    unknown = sorted(set(meta["properties"]) - set(PROPERTY_NAMES))
    if unknown:
        raise ArchiveError(path, "meta.properties", f"unknown properties {unknown}; known: {PROPERTY_NAMES}")
    for name in PROPERTY_NAMES if version == 1 else meta["properties"]:
        level = meta["properties"].get(name, "missing")
        if level == "missing":
            raise ArchiveError(path, f"meta.properties.{name}", "missing (use null when unknown)")
        if level is not None:
            _check_count(level, path, f"meta.properties.{name}")
    if version == 1:
        if not _is(meta["sample_rates"].get("audio"), int) or meta["sample_rates"]["audio"] != AUDIO_RATE:
            raise ArchiveError(
                path, "meta.sample_rates.audio", f"must be {AUDIO_RATE}, got {meta['sample_rates'].get('audio')!r}"
            )
        _check_rate(meta["sample_rates"].get("steps", STEP_RATE), path, "meta.sample_rates.steps")
        if meta["image_size"] is not None:
            _check_image_size(meta["image_size"], path, "meta.image_size")
        _check_strings(meta["joint_names"], path, "meta.joint_names")
        if len(meta["joint_names"]) != N_JOINTS:
            raise ArchiveError(path, "meta.joint_names", f"expected {N_JOINTS} names, got {len(meta['joint_names'])}")
        _check_absent_fields(meta.get("joint_fields_absent", []), JOINT_FIELDS, path, "meta.joint_fields_absent")
        return meta
    if "joint_fields_absent" in meta:  # one representation per format
        raise ArchiveError(
            path,
            "meta.joint_fields_absent",
            "a format-1 key: format 2 lists absent joint fields in meta.streams.joints.absent",
        )
    _check_streams(meta["streams"], path)
    if meta.get("split") is not None and meta["split"] not in SPLITS:
        raise ArchiveError(path, "meta.split", f"must be one of {SPLITS} or absent, got {meta['split']!r}")
    if "label_map" in meta:
        label_map = meta["label_map"]
        ints = isinstance(label_map, dict) and all(_is(c, int) and 0 <= c < len(label_map) for c in label_map.values())
        classes = set(label_map.values()) if ints else None
        if not classes or classes != set(range(max(classes) + 1)):
            raise ArchiveError(path, "meta.label_map", "must map names to classes 0..K-1, every class named")
        if meta["label"] not in classes:
            raise ArchiveError(
                path, "meta.label", f"class {meta['label']} is not in the label map's classes 0..{max(classes)}"
            )
    elif "fabric_id" not in meta:
        raise ArchiveError(path, "meta.fabric_id", "missing (a trial without a label map is a catalog fabric's)")
    return meta


def _check_absent_fields(absent: Any, fields, path, field: str) -> None:
    if (
        not isinstance(absent, list)
        or not all(isinstance(x, str) for x in absent)
        or not set(absent) <= set(fields)
        or len(set(absent)) != len(absent)
    ):
        raise ArchiveError(path, field, f"must list distinct fields of {list(fields)}, got {absent!r}")


def _check_form(path, name: str, dtype: np.dtype, shape: tuple[int, ...], n_steps: int | None, lay: Layout) -> None:
    """An array's dtype and shape against the declared streams (also on an npy header, before its data is read)."""
    want_dtype, want = _spec(name, lay)
    if dtype != want_dtype:
        raise ArchiveError(path, name, f"dtype {dtype}, expected {np.dtype(want_dtype)}")
    if len(shape) != len(want):
        raise ArchiveError(path, name, f"shape {shape}, expected {len(want)} dimensions {want}")
    for size, w in zip(shape, want):
        if w == "T" and n_steps is not None and size != n_steps:
            raise ArchiveError(path, name, f"shape {shape}: {size} steps, but timestamps has {n_steps}")
        if isinstance(w, int) and size != w:
            raise ArchiveError(path, name, f"shape {shape}, expected {want} (the streams meta.streams declares)")
    if name in ("images", "reference") and (lay.image_size is None or tuple(shape[1:3]) != lay.image_size):
        raise ArchiveError(path, name, f"shape {shape} disagrees with the declared image_size {lay.image_size}")
    if name == "reference" and not 1 <= shape[0] <= MAX_REFERENCE_FRAMES:
        raise ArchiveError(path, name, f"shape {shape}: {shape[0]} frames, expected 1 to {MAX_REFERENCE_FRAMES}")


def _check_array(path, name: str, arr: np.ndarray, n_steps: int | None, lay: Layout) -> None:
    _check_form(path, name, arr.dtype, arr.shape, n_steps, lay)
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ArchiveError(path, name, f"{bad} non-finite values (NaN or Inf)")


def validate(archive: TrialArchive, path: os.PathLike | str = "<memory>") -> TrialArchive:
    """Raise `ArchiveError` unless every field is well-formed and consistent with the declared streams."""
    validate_meta(archive.meta, path)
    lay = layout(archive.meta)
    _check_array(path, "timestamps", archive.timestamps, None, lay)
    n = archive.n_steps
    if n < 1:
        raise ArchiveError(path, "timestamps", "trial has no steps")
    declared = {"joints": lay.has_joints, "force": lay.force, "images": lay.image_size is not None}
    for name in ("window_end", "joints", "force", "audio"):
        arr = getattr(archive, name)
        if arr is None:
            if declared[name]:
                raise ArchiveError(path, name, "missing")
            continue
        if name in declared and not declared[name]:
            raise ArchiveError(path, name, f"present, but meta.streams declares no {name}")
        if name == "joints" and lay.joint_fields_absent and arr.ndim == 3 and arr.shape[2] == len(lay.joint_fields):
            absent = np.isin(lay.joint_fields, lay.joint_fields_absent)
            if not np.isnan(arr[..., absent]).all():
                raise ArchiveError(
                    path,
                    "joints",
                    f"fields {list(lay.joint_fields_absent)} are recorded as absent but hold values (NaN "
                    f"where not recorded)",
                )
            arr = np.where(absent, 0, arr).astype(
                arr.dtype
            )  # NaN where absent, checked above; finite elsewhere, checked next
        _check_array(path, name, arr, n, lay)
    back = np.flatnonzero(np.diff(archive.timestamps) <= 0)
    if back.size:  # a repeated step (or one out of order) would count the same moment twice
        k = int(back[0]) + 1
        raise ArchiveError(
            path,
            "timestamps",
            f"not strictly increasing: step {k} ({archive.timestamps[k]} s) "
            f"does not come after step {k - 1} ({archive.timestamps[k - 1]} s)",
        )
    n_samples = archive.audio.shape[1]
    we = archive.window_end
    if we.size and (we.min() < 0 or we.max() > n_samples):
        raise ArchiveError(
            path, "window_end", f"indices must lie in [0, {n_samples}] (audio length), found [{we.min()}, {we.max()}]"
        )
    if np.any(np.diff(we, axis=0) < 0):
        raise ArchiveError(path, "window_end", "indices decrease between steps")
    if archive.images is not None:
        _check_array(path, "images", archive.images, n, lay)
    _check_reference(archive, path, lay)
    closing = archive.meta.get("closing_steps", 0)
    # a trial interrupted while closing has no rubbing steps
    if closing > n or (closing == n and archive.meta["complete"]):
        raise ArchiveError(
            path, "meta.closing_steps", f"{closing} closing steps leave none of the trial's {n} steps to rub"
        )
    return archive


def _check_reference(archive: TrialArchive, path, lay: Layout) -> None:
    """The session reference: only in format 3 and later, only with a camera, its frames and
    `meta.reference` together, and as many times (or null) as frames."""
    described, ref = archive.meta.get("reference"), archive.reference
    if described is None and ref is None:
        return
    if archive.meta["format_version"] < REFERENCE_VERSION:
        raise ArchiveError(
            path,
            "reference",
            f"present, but format {archive.meta['format_version']} has no session reference (format "
            f"{REFERENCE_VERSION} has)",
        )
    if lay.image_size is None:
        raise ArchiveError(path, "reference", "present, but meta.streams declares no camera")
    if ref is None:
        raise ArchiveError(
            path, "reference", "missing: meta.reference describes a session reference the archive does not hold"
        )
    if described is None:
        raise ArchiveError(
            path, "meta.reference", "missing: the archive holds reference frames; say how and when they were taken"
        )
    _check_array(path, "reference", ref, None, lay)
    for key in ("how", "session"):
        if not isinstance(described.get(key), str) or not described[key]:
            raise ArchiveError(
                path, f"meta.reference.{key}", f"must be a non-empty string, got {json.dumps(described.get(key))[:60]}"
            )
    times = described.get("times_s", "missing")
    if times is not None and not (
        isinstance(times, list) and len(times) == len(ref) and all(_is(t, (int, float)) for t in times)
    ):
        raise ArchiveError(
            path,
            "meta.reference.times_s",
            f"must be null or {len(ref)} finite times in seconds (one per reference frame), got "
            f"{json.dumps(times)[:60]}",
        )


def reference_note(meta: dict[str, Any]) -> str | None:
    """Why an archive with frames has no session reference (None when it has one, or no camera)."""
    if layout(meta).image_size is None or "reference" in meta:
        return None
    if meta["format_version"] < REFERENCE_VERSION:
        return (
            f"a format-{meta['format_version']} archive: written before archives carried the session's "
            f"no-contact reference"
        )
    return "its recording took no no-contact reference"


def write_archive(path: os.PathLike | str, archive: TrialArchive) -> Path:
    """Validate, then write atomically: a reader never sees a half-written archive. Members up to
    `FREE_INFLATION` bytes are deflated (`write_npz`): every reader's bound admits them, and a
    simulated trial's frames shrink ~6x and its audio words ~2x; larger ones (long imported
    recordings) are stored, so no ratio bound can refuse them."""
    path = Path(path)
    validate(archive, path)
    with atomic_open(path, what="a trial archive") as f:
        write_npz(
            f,
            {"meta": np.array(json.dumps(archive.meta)), **archive.arrays()},
            deflate=lambda a: a.nbytes <= FREE_INFLATION,
        )
    return path


DEFLATE_LEVEL = (
    1  # zlib's fastest level: nearly all of level 6's saving on frames and audio words, at a few times its speed
)


def write_npz(f, arrays: Mapping[str, np.ndarray], deflate: Callable[[np.ndarray], bool]) -> None:
    """`np.savez` into the open binary file `f`, each member deflated at `DEFLATE_LEVEL` where
    `deflate(array)`, else stored; `np.load` and `read_archive` read both kinds of member."""
    with zipfile.ZipFile(f, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=DEFLATE_LEVEL, allowZip64=True) as z:
        for name, a in arrays.items():
            a = np.asanyarray(a)
            member = f"{name}.npy"
            if not deflate(a):
                member = zipfile.ZipInfo(member, date_time=time.localtime()[:6])
                member.compress_type = zipfile.ZIP_STORED
            with z.open(member, "w", force_zip64=True) as out:
                np.lib.format.write_array(out, a, allow_pickle=False)


class _Members:
    """The npy members of an archive's zip, each read only after its declared sizes and npy header
    are checked (so nothing is inflated beyond its bound), and CRC-checked as it is read."""

    def __init__(self, path: Path):
        if not path.is_file():
            raise ArchiveError(path, "<file>", "no such file")
        self.path = path
        try:
            self.zip = zipfile.ZipFile(path)
            infos = self.zip.infolist()
        except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError, RuntimeError) as e:
            raise ArchiveError(path, "<file>", f"not a readable .npz archive (corrupt or truncated): {e}") from None
        if len(infos) > MAX_MEMBERS:
            self.zip.close()
            raise ArchiveError(
                path, "<file>", f"{len(infos)} zip members, more than {MAX_MEMBERS}: not a trial archive"
            )
        self.infos = {i.filename[: -len(".npy")]: i for i in infos if i.filename.endswith(".npy")}
        self.size = path.stat().st_size

    def __enter__(self) -> "_Members":
        return self

    def __exit__(self, *exc) -> None:
        self.zip.close()

    def __contains__(self, name: str) -> bool:
        return name in self.infos

    def read(self, name: str, check: Callable[[np.dtype, tuple[int, ...]], None]) -> np.ndarray:
        """Member `name` as an array; `check(dtype, shape)` judges its npy header before its data is inflated."""
        path, info = self.path, self.infos.get(name)
        if info is None:
            raise ArchiveError(path, name, "missing")
        if info.compress_size > self.size:
            raise ArchiveError(
                path,
                name,
                f"declares {info.compress_size} bytes, the file holds {self.size} (truncated, or a damaged size)",
            )
        stored = info.compress_type == zipfile.ZIP_STORED
        if stored and info.file_size != info.compress_size:
            raise ArchiveError(
                path, name, f"a stored member declaring {info.file_size} bytes in {info.compress_size} (a damaged size)"
            )
        bound = (
            MAX_MEMBER_BYTES
            if stored
            else min(MAX_MEMBER_BYTES, max(FREE_INFLATION, INFLATION_RATIO * info.compress_size))
        )
        if info.file_size > bound:
            raise ArchiveError(
                path,
                name,
                f"declares {info.file_size} bytes inflated from {info.compress_size}, more than the {bound} "
                "a trial's member may hold (a zip bomb or a damaged size)",
            )
        try:
            with self.zip.open(info) as f:
                dtype, shape, fortran = _npy_header(f, path, name)
                if dtype.hasobject or dtype.kind not in "biufU":
                    raise ArchiveError(path, name, f"dtype {dtype}: not an array of numbers or text")
                check(dtype, shape)
                nbytes = int(np.prod(shape, dtype=np.uint64)) * dtype.itemsize
                if nbytes != info.file_size - f.tell():
                    raise ArchiveError(
                        path,
                        name,
                        f"the npy header's shape {shape} of {dtype} needs {nbytes} bytes, the zip member "
                        f"holds {info.file_size - f.tell()}",
                    )
                arr = np.empty(shape[::-1] if fortran else shape, dtype)
                view, done = memoryview(arr.reshape(-1).view(np.uint8)), 0
                while done < nbytes and (chunk := f.read(min(READ_CHUNK, nbytes - done))):
                    view[done : done + len(chunk)] = chunk
                    done += len(chunk)
                if done != nbytes or f.read(1):  # reading to the end checks the member's CRC
                    raise ArchiveError(path, name, "shorter or longer than its npy header declares")
        except ArchiveError:
            raise
        except (zipfile.BadZipFile, OSError, EOFError, ValueError, RuntimeError, NotImplementedError, zlib.error) as e:
            raise ArchiveError(path, name, f"unreadable (corrupt or truncated): {e}") from None
        return arr.T if fortran else arr


def _npy_header(f, path: Path, name: str) -> tuple[np.dtype, tuple[int, ...], bool]:
    """(dtype, shape, fortran order) of an npy stream, which is left at the start of the data."""
    try:
        version = np.lib.format.read_magic(f)
        read = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}[version]
        shape, fortran, dtype = read(f)
    except KeyError:
        raise ArchiveError(path, name, "unknown npy format version") from None
    # numpy parses the header with ast and tokenize: any damage is a broken header, not a bug of ours
    except Exception as e:
        raise ArchiveError(path, name, f"not an npy array (its header is damaged): {type(e).__name__}: {e}") from None
    if any(d > MAX_INT for d in shape) or np.prod([float(d) for d in shape]) * dtype.itemsize > MAX_MEMBER_BYTES:
        raise ArchiveError(
            path, name, f"the npy header declares shape {shape} of {dtype}, more than {MAX_MEMBER_BYTES} bytes"
        )
    return dtype, tuple(int(d) for d in shape), bool(fortran)


_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')


def parse_json(text: str, path, field: str) -> Any:
    """JSON whose size, nesting depth and numbers are bounded before it is parsed (a hostile file
    cannot exhaust memory, the stack or time); NaN and Infinity are not JSON."""
    if len(text) > MAX_META_CHARS:
        raise ArchiveError(path, field, f"{len(text)} characters of JSON, more than {MAX_META_CHARS}")
    brackets = np.frombuffer(_JSON_STRING.sub('""', text).encode("utf-8", "replace"), np.uint8)
    depth = np.cumsum(
        np.isin(brackets, (ord("["), ord("{"))).astype(np.int64) - np.isin(brackets, (ord("]"), ord("}")))
    )
    if depth.size and depth.max() > MAX_JSON_DEPTH:
        raise ArchiveError(path, field, f"JSON nested {int(depth.max())} deep, more than {MAX_JSON_DEPTH}")

    def number(kind):
        def parse(s: str):
            if len(s) > MAX_NUMBER_CHARS:
                raise ArchiveError(path, field, f"a number of {len(s)} characters, more than {MAX_NUMBER_CHARS}")
            return kind(s)

        return parse

    def constant(name: str):
        raise ArchiveError(path, field, f"{name} is not a JSON number (values are finite)")

    try:
        return json.loads(text, parse_int=number(int), parse_float=number(float), parse_constant=constant)
    except (json.JSONDecodeError, RecursionError) as e:
        raise ArchiveError(path, field, f"not valid JSON: {e}") from None


def _parse_meta(path: Path, members: _Members) -> dict[str, Any]:
    def check(dtype: np.dtype, shape: tuple[int, ...]) -> None:
        if dtype.kind != "U" or shape != () or dtype.itemsize > 4 * MAX_META_CHARS:
            raise ArchiveError(
                path,
                "meta",
                f"must be one JSON string (0-d unicode) of at most {MAX_META_CHARS} characters, got {dtype} {shape}",
            )

    return validate_meta(parse_json(str(members.read("meta", check)[()]), path, "meta"), path)


def _read_streams(
    path: Path, members: _Members, names: tuple[str, ...]
) -> tuple[dict[str, Any], dict[str, np.ndarray | None]]:
    """The validated meta and the arrays `names` (None where absent), each header checked against
    the meta's layout and the step count before its data is read."""
    meta = _parse_meta(path, members)
    lay = layout(meta)
    ts = members.read("timestamps", lambda dtype, shape: _check_form(path, "timestamps", dtype, shape, None, lay))
    out: dict[str, np.ndarray | None] = {"timestamps": ts}
    for name in names:
        # `validate` says "missing" for a declared stream the file lacks
        if name in members or name in (
            "window_end",
            "audio",
        ):
            out[name] = members.read(
                name, lambda dtype, shape, name=name: _check_form(path, name, dtype, shape, ts.shape[0], lay)
            )
        else:
            out[name] = None
    return meta, out


def read_meta(path: os.PathLike | str) -> tuple[dict[str, Any], int]:
    """Meta and step count without loading the other streams (cheap, for indexing)."""
    path = Path(path)
    with _Members(path) as members:
        meta, fields = _read_streams(path, members, ())
    return meta, int(fields["timestamps"].shape[0])


def read_archive(path: os.PathLike | str, *, images: bool = True) -> TrialArchive:
    """Load and fully validate one archive. `images=False` skips the (large) image stream."""
    path = Path(path)
    with _Members(path) as members:
        meta, fields = _read_streams(
            path, members, ("window_end", "audio", "joints", "force", "reference") + (("images",) if images else ())
        )
    return validate(TrialArchive(meta=meta, images=fields.pop("images", None), **fields), path)


def trial_filename(meta: dict[str, Any]) -> str:
    """`fabric04_day1_trial00_lab.npz`; a trial labelled by name, without a day or a condition:
    `<label name>_trial000.npz` (characters other than letters, digits, '-' and '.' become '_')."""
    if "label_name" in meta or "fabric_id" not in meta:
        who = re.sub(r"[^A-Za-z0-9.-]+", "_", meta.get("label_name", "")).strip("_") or f"class{meta['label']:02d}"
        when = "" if meta["day"] is None else f"_day{meta['day']}"
        condition = "" if meta["condition"] is None else f"_{meta['condition']}"
        return f"{who}{when}_trial{meta['trial']:03d}{condition}.npz"
    return f"fabric{meta['fabric_id']:02d}_day{meta['day']}_trial{meta['trial']:02d}_{meta['condition']}.npz"
