"""The trial archive: the one contract between acquisition / simulator and everything downstream.

One `.npz` per trial, loadable with `allow_pickle=False`:

==============  =====================  ======================================================
key             dtype, shape           meaning
==============  =====================  ======================================================
meta            0-d unicode            JSON object, see `REQUIRED_META`
timestamps      float64 (T,)           capture time of each step (Minsight frame), seconds
window_end      int64 (T, 2)           exclusive end index, in each raw mic stream, of the
                                       2048-sample window that belongs to the step
joints          float32 (T, 6, 3)      6 joints x (angle rad, velocity rad/s, current A);
                                       NaN in a field meta.joint_fields_absent lists
force           float32 (T,)           estimated normal force at the Minsight tip, N
audio           int32 (2, S)           raw SPH0645 I2S words, 48 kHz; row 0 = Minsound
                                       (internal), row 1 = palm (external)
images          uint8 (T, H, W, 3)     Minsight frames; absent when not recorded
==============  =====================  ======================================================

`write_archive` is atomic (temporary name in the same folder, fsync, rename); `read_archive`
validates every field and raises `ArchiveError` naming the file, the field and the problem.
A dataset is a folder of archives plus an index (see `build_index`, `load_index`) recording each
archive's meta, size, mtime and sha256: `index.json` beside the simulator's own archives, under the
workspace for any other folder, which is only read. `fabricjax.integrity` checks a dataset against it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from fabricjax import workspace
from fabricjax.atomic import atomic_open
from fabricjax.errors import UserError

FORMAT_VERSION = 1
# The time base and sample format every archive shares (the paper's rig; the SPH0645 datasheet).
# This is their one definition: the simulator, acquisition and features import them from here
# (only the stdlib-only Pi side, `acquisition.wire.RATE`, repeats AUDIO_RATE; a test checks it).
WINDOW = 2048  # audio samples per step (the Welch window)
AUDIO_RATE = 48000  # Hz, every microphone stream
STEP_RATE = 50  # Hz, one step per Minsight frame
VALID_BITS = 18  # valid bits of an SPH0645 I2S word, in bits 31..14
FULL_SCALE = 2.0 ** (VALID_BITS - 1)  # a signed 18-bit sample of this magnitude is full scale (+-1)
N_JOINTS = 6
JOINT_FIELDS = ("angle", "velocity", "current")
JOINT_NAMES = ("thumb_base", "thumb_mid", "thumb_tip", "middle_base", "middle_tip", "palm")
MIC_NAMES = ("internal", "external")
UNITS = {
    "timestamps": "s",
    "joints": ["rad", "rad/s", "A"],
    "force": "N",
    "audio": "SPH0645 I2S word (int32; 18 valid bits in bits 31..14)",
}
REQUIRED_META = {
    "format_version": int,
    "fabric_id": int,
    "label": int,
    "properties": dict,
    "day": int,
    "trial": int,
    "condition": str,
    "source": dict,
    "sample_rates": dict,
    "image_size": (list, type(None)),
    "joint_names": list,
    "units": dict,
    "complete": bool,
}
CONDITIONS = ("lab", "cafe")
PROPERTY_NAMES = ("stretchiness", "roughness", "thickness")


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
class TrialArchive:
    """One recorded or simulated trial, validated."""

    meta: dict[str, Any]
    timestamps: np.ndarray
    window_end: np.ndarray
    joints: np.ndarray
    force: np.ndarray
    audio: np.ndarray
    images: np.ndarray | None = None

    @property
    def n_steps(self) -> int:
        return int(self.timestamps.shape[0])

    def arrays(self) -> dict[str, np.ndarray]:
        out = {k: getattr(self, k) for k in ("timestamps", "window_end", "joints", "force", "audio")}
        if self.images is not None:
            out["images"] = self.images
        return out


_SPEC = {  # field -> (dtype, shape with None for free dims, 'T' for the step count)
    "timestamps": (np.float64, ("T",)),
    "window_end": (np.int64, ("T", 2)),
    "joints": (np.float32, ("T", N_JOINTS, 3)),
    "force": (np.float32, ("T",)),
    "audio": (np.int32, (2, None)),
    "images": (np.uint8, ("T", None, None, 3)),
}


def make_meta(
    *,
    fabric_id: int,
    properties: dict[str, int | None],
    day: int,
    trial: int,
    condition: str,
    source: dict[str, Any],
    image_size: tuple[int, int] | None,
    complete: bool = True,
    label: int | None = None,
    step_rate: float = STEP_RATE,
    **extra: Any,
) -> dict[str, Any]:
    """Meta with every required field filled in the canonical way; `step_rate` is the camera's
    frame rate when a recording's camera does not run at the rig's 50 Hz."""
    return {
        "format_version": FORMAT_VERSION,
        "fabric_id": int(fabric_id),
        "label": int(fabric_id if label is None else label),
        "properties": {k: (None if properties.get(k) is None else int(properties[k])) for k in PROPERTY_NAMES},
        "day": int(day),
        "trial": int(trial),
        "condition": condition,
        "source": source,
        "sample_rates": {"audio": AUDIO_RATE, "steps": step_rate},
        "image_size": None if image_size is None else [int(image_size[0]), int(image_size[1])],
        "joint_names": list(JOINT_NAMES),
        "joint_fields": list(JOINT_FIELDS),
        "mic_names": list(MIC_NAMES),
        "units": UNITS,
        "complete": bool(complete),
        **extra,
    }


def validate_meta(meta: Any, path: os.PathLike | str) -> dict[str, Any]:
    if not isinstance(meta, dict):
        raise ArchiveError(path, "meta", f"expected a JSON object, got {type(meta).__name__}")
    if "format_version" not in meta:
        raise ArchiveError(path, "meta.format_version", "missing")
    if meta["format_version"] != FORMAT_VERSION:
        raise ArchiveError(
            path, "meta.format_version", f"unknown format version {meta['format_version']!r} (this code reads {FORMAT_VERSION})"
        )
    for key, typ in REQUIRED_META.items():
        if key not in meta:
            raise ArchiveError(path, f"meta.{key}", "missing")
        if not isinstance(meta[key], typ) or (typ is int and isinstance(meta[key], bool)):
            raise ArchiveError(path, f"meta.{key}", f"wrong type {type(meta[key]).__name__}")
    if meta["condition"] not in CONDITIONS:
        raise ArchiveError(path, "meta.condition", f"must be one of {CONDITIONS}, got {meta['condition']!r}")
    if meta["fabric_id"] < 0:
        raise ArchiveError(path, "meta.fabric_id", f"must be >= 0, got {meta['fabric_id']}")
    for name in PROPERTY_NAMES:
        level = meta["properties"].get(name, "missing")
        if level == "missing":
            raise ArchiveError(path, f"meta.properties.{name}", "missing (use null when unknown)")
        if level is not None and (not isinstance(level, int) or level < 0):
            raise ArchiveError(path, f"meta.properties.{name}", f"must be a level >= 0 or null, got {level!r}")
    if meta["sample_rates"].get("audio") != AUDIO_RATE:
        raise ArchiveError(path, "meta.sample_rates.audio", f"must be {AUDIO_RATE}, got {meta['sample_rates'].get('audio')!r}")
    if len(meta["joint_names"]) != N_JOINTS:
        raise ArchiveError(path, "meta.joint_names", f"expected {N_JOINTS} names, got {len(meta['joint_names'])}")
    absent = meta.get("joint_fields_absent", [])
    if not isinstance(absent, list) or not set(absent) <= set(JOINT_FIELDS) or len(set(absent)) != len(absent):
        raise ArchiveError(path, "meta.joint_fields_absent", f"must list distinct fields of {list(JOINT_FIELDS)}, got {absent!r}")
    return meta


def absent_joint_fields(meta: dict[str, Any]) -> list[str]:
    """The JOINT_FIELDS a recording lacks (optional meta.joint_fields_absent, e.g. a position-only
    ROS JointState): NaN in `joints`, never zeros, which would read as a still, unpowered joint."""
    return list(meta.get("joint_fields_absent", []))


def _check_array(path, name: str, arr: np.ndarray, n_steps: int | None) -> None:
    dtype, shape = _SPEC[name]
    if arr.dtype != dtype:
        raise ArchiveError(path, name, f"dtype {arr.dtype}, expected {np.dtype(dtype)}")
    if arr.ndim != len(shape):
        raise ArchiveError(path, name, f"shape {arr.shape}, expected {len(shape)} dimensions {shape}")
    for size, want in zip(arr.shape, shape):
        if want == "T" and n_steps is not None and size != n_steps:
            raise ArchiveError(path, name, f"shape {arr.shape}: {size} steps, but timestamps has {n_steps}")
        if isinstance(want, int) and size != want:
            raise ArchiveError(path, name, f"shape {arr.shape}, expected {shape}")
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ArchiveError(path, name, f"{bad} non-finite values (NaN or Inf)")


def validate(archive: TrialArchive, path: os.PathLike | str = "<memory>") -> TrialArchive:
    """Raise `ArchiveError` unless every field is well-formed and consistent."""
    validate_meta(archive.meta, path)
    _check_array(path, "timestamps", archive.timestamps, None)
    n = archive.n_steps
    if n < 1:
        raise ArchiveError(path, "timestamps", "trial has no steps")
    for name in ("window_end", "force", "audio"):
        _check_array(path, name, getattr(archive, name), n)
    joints = archive.joints
    absent = [JOINT_FIELDS.index(f) for f in absent_joint_fields(archive.meta)]
    if absent and joints.ndim == 3 and joints.shape[2:] == (len(JOINT_FIELDS),):
        if not np.isnan(joints[..., absent]).all():
            raise ArchiveError(path, "joints", f"fields {absent_joint_fields(archive.meta)} are absent (meta.joint_fields_absent) but hold values")
        joints = np.where(np.isin(np.arange(len(JOINT_FIELDS)), absent), 0, joints).astype(joints.dtype)  # NaN checked above
    _check_array(path, "joints", joints, n)
    back = np.flatnonzero(np.diff(archive.timestamps) <= 0)
    if back.size:  # a repeated step (or one out of order) would count the same moment twice
        k = int(back[0]) + 1
        raise ArchiveError(path, "timestamps", f"not strictly increasing: step {k} ({archive.timestamps[k]} s) "
                           f"does not come after step {k - 1} ({archive.timestamps[k - 1]} s)")
    n_samples = archive.audio.shape[1]
    we = archive.window_end
    if we.size and (we.min() < 0 or we.max() > n_samples):
        raise ArchiveError(
            path, "window_end", f"indices must lie in [0, {n_samples}] (audio length), found [{we.min()}, {we.max()}]"
        )
    if np.any(np.diff(we, axis=0) < 0):
        raise ArchiveError(path, "window_end", "indices decrease between steps")
    if archive.images is not None:
        _check_array(path, "images", archive.images, n)
        size = archive.meta["image_size"]
        if size is None or list(archive.images.shape[1:3]) != list(size):
            raise ArchiveError(path, "images", f"shape {archive.images.shape} disagrees with meta.image_size {size}")
    return archive


def write_archive(path: os.PathLike | str, archive: TrialArchive) -> Path:
    """Validate, then write atomically: a reader never sees a half-written archive."""
    path = Path(path)
    validate(archive, path)
    with atomic_open(path) as f:
        np.savez(f, meta=np.array(json.dumps(archive.meta)), **archive.arrays())
    return path


def _open(path: Path):
    if not path.is_file():
        raise ArchiveError(path, "<file>", "no such file")
    try:
        return np.load(path, allow_pickle=False)
    except ValueError:  # neither zip nor .npy: numpy's message would suggest unpickling it
        raise ArchiveError(path, "<file>", "not a readable .npz archive (corrupt or truncated): not a zip file") from None
    except (zipfile.BadZipFile, OSError, EOFError) as e:
        raise ArchiveError(path, "<file>", f"not a readable .npz archive (corrupt or truncated): {e}") from None


def _load_field(path: Path, npz, name: str) -> np.ndarray:
    try:
        return npz[name]
    except KeyError:
        raise ArchiveError(path, name, "missing") from None
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, RuntimeError) as e:
        raise ArchiveError(path, name, f"unreadable (corrupt or truncated): {e}") from None


def _parse_meta(path: Path, npz) -> dict[str, Any]:
    raw = _load_field(path, npz, "meta")
    try:
        meta = json.loads(str(raw[()]))
    except (json.JSONDecodeError, TypeError, IndexError) as e:
        raise ArchiveError(path, "meta", f"not valid JSON: {e}") from None
    return validate_meta(meta, path)


def read_meta(path: os.PathLike | str) -> tuple[dict[str, Any], int]:
    """Meta and step count without loading the streams (cheap, for indexing)."""
    path = Path(path)
    with _open(path) as npz:
        meta = _parse_meta(path, npz)
        ts = _load_field(path, npz, "timestamps")
    return meta, int(ts.shape[0]) if ts.ndim == 1 else -1


def read_archive(path: os.PathLike | str, *, images: bool = True) -> TrialArchive:
    """Load and fully validate one archive. `images=False` skips the (large) image stream."""
    path = Path(path)
    with _open(path) as npz:
        meta = _parse_meta(path, npz)
        fields = {k: _load_field(path, npz, k) for k in ("timestamps", "window_end", "joints", "force", "audio")}
        imgs = _load_field(path, npz, "images") if images and "images" in npz.files else None
    return validate(TrialArchive(meta=meta, images=imgs, **fields), path)


def trial_filename(meta: dict[str, Any]) -> str:
    return f"fabric{meta['fabric_id']:02d}_day{meta['day']}_trial{meta['trial']:02d}_{meta['condition']}.npz"


@dataclasses.dataclass(frozen=True)
class IndexEntry:
    file: str
    meta: dict[str, Any]
    n_steps: int
    size: int
    mtime_ns: int
    sha256: str = ""  # "" in an index written before content hashes: such an index is rebuilt once

    @property
    def fingerprint(self) -> str:
        """Identifies the archive's contents for caches (changes whenever the file is rewritten)."""
        return f"{self.file}:{self.size}:{self.mtime_ns}"


@dataclasses.dataclass(frozen=True)
class DatasetIndex:
    root: Path
    entries: tuple[IndexEntry, ...]

    def path(self, entry: IndexEntry) -> Path:
        return self.root / entry.file

    def select(self, **where: Any) -> list[IndexEntry]:
        return [e for e in self.entries if all(e.meta.get(k) == v for k, v in where.items())]


def sha256_file(path: os.PathLike | str) -> str:
    """Hex sha256 of a file's bytes, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _indexed_entries(ipath: Path) -> dict[str, IndexEntry]:
    """The hashed entries of an existing index, or none when it is absent or unreadable."""
    try:
        doc = json.loads(ipath.read_text())
        if doc.get("format_version") != FORMAT_VERSION:
            return {}
        return {e.file: e for e in (IndexEntry(**t) for t in doc["trials"]) if e.sha256}
    except (OSError, json.JSONDecodeError, KeyError, TypeError):
        return {}


def build_index(folder: os.PathLike | str, index_file: os.PathLike | str | None = None) -> DatasetIndex:
    """Scan a folder of archives (hardware or simulated) and write its index to `index_file`
    (default: `index.json` in the folder, as the simulator does for the datasets it writes).
    Each entry records the archive's sha256 (`fabricjax.integrity.verify` re-hashes against it); an
    entry of the existing index whose file kept its size and mtime is kept, so only new or rewritten
    archives are read and hashed (the simulator re-indexes its 11 GB dataset on every run)."""
    root = Path(folder)
    if not root.is_dir():
        raise ArchiveError(root, "<folder>", "dataset folder does not exist")
    ipath = Path(index_file) if index_file is not None else root / workspace.INDEX_NAME
    known = _indexed_entries(ipath)
    entries = []
    for p in sorted(root.glob("*.npz")):
        st = p.stat()
        old = known.get(p.name)
        if old is not None and (old.size, old.mtime_ns) == (st.st_size, st.st_mtime_ns):
            entries.append(old)
            continue
        meta, n = read_meta(p)
        entries.append(IndexEntry(p.name, meta, n, st.st_size, st.st_mtime_ns, sha256_file(p)))
    doc = {"format_version": FORMAT_VERSION, "folder": str(root.resolve()), "trials": [dataclasses.asdict(e) for e in entries]}
    ipath.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(ipath, "w") as f:
        f.write(json.dumps(doc, indent=1))
    return DatasetIndex(root, tuple(entries))


def load_index(folder: os.PathLike | str, workdir: os.PathLike | str | None = None) -> DatasetIndex:
    """Read the folder's index (where `workspace.index_file` puts it: never inside a folder outside
    the workspace), building it on first use and rebuilding it when archives were added or
    rewritten. A folder without archives, and an archive the index lists but the folder lacks
    (data went missing), are errors."""
    root = Path(folder)
    if not root.is_dir():
        raise ArchiveError(root, "<folder>", "dataset folder does not exist")
    on_disk = {p.name: p.stat() for p in root.glob("*.npz")}
    if not on_disk:
        raise ArchiveError(root, "<folder>", "the folder holds no trial archives (*.npz)")
    ipath = workspace.index_file(root, workdir)
    if not ipath.exists():
        return build_index(root, ipath)
    try:
        doc = json.loads(ipath.read_text())
        if doc.get("format_version") != FORMAT_VERSION:
            raise ArchiveError(ipath, "format_version", f"unknown index version {doc.get('format_version')!r}")
        entries = tuple(IndexEntry(**t) for t in doc["trials"])
    except (json.JSONDecodeError, KeyError, TypeError) as e:
        raise ArchiveError(ipath, "trials", f"malformed index: {e}") from None
    for e in entries:
        if e.file not in on_disk:
            raise ArchiveError(
                ipath, f"trials[{e.file}]", f"listed archive is missing from {root} (restore it, or delete {ipath} to re-index)"
            )
    stale = len(on_disk) != len(entries) or any(
        not e.sha256 or on_disk[e.file].st_size != e.size or on_disk[e.file].st_mtime_ns != e.mtime_ns for e in entries
    )
    return build_index(root, ipath) if stale else DatasetIndex(root, entries)
