"""The feature cache: each trial's feature arrays on disk, so a second run does no feature work.

Layout under `workspace.features_dir(workdir)`:

    <feature name>-<key>/key.json          what the key stands for (feature, params, dataset, code)
    <feature name>-<key>/<archive stem>.npz    {"data": array, "fingerprint": archive fingerprint}

`key` hashes the feature's parameters, the dataset folder's absolute path and the features' code
(`source.fingerprint` of `features.extract`: every module it runs), so a changed parameter or a
change in how a feature is computed starts a new folder. Inside, a file is trusted only if its stored fingerprint equals
the archive's current `IndexEntry.fingerprint` (name, size, mtime): a rewritten archive is
recomputed and its entry overwritten. Files are written to a temporary name and renamed.

Trials whose features are missing are computed first, in a process pool over trials (default:
one process per core; each worker keeps XLA and OpenCV to one thread, so the cores go to trials,
not to contention), each trial read once, without its images unless a missing feature needs
them; workers write the cache files themselves, so no array crosses a process boundary. Every
feature is a function of its archive alone, so the pool returns exactly what the serial path
(`workers=1`, in this process) does (tested). The arrays are then read back from the cache in
order, read ahead by threads that only read and inflate the files; the consuming thread
parses them, so no lock is shared.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import os
import sys
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Iterator

import numpy as np
from tqdm import tqdm

from fabricjax import parallel, source
from fabricjax.features.extract import Feature, feature_named
from fabricjax.store import archive, dataset_index
from fabricjax.store.atomic import atomic_open

CODE = ("fabricjax.features.extract",)  # the module every feature is computed by, and what it runs


def folder(features_root: Path, dataset_root: Path, feature: Feature) -> Path:
    key = {
        "feature": feature.name,
        "params": feature.params,
        "dataset": str(Path(dataset_root).resolve()),
        "code": source.fingerprint(CODE)[:16],
    }
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]
    out = Path(features_root) / f"{feature.name}-{digest}"
    if not (out / "key.json").exists():
        out.mkdir(parents=True, exist_ok=True)
        _atomic_write(out / "key.json", lambda f: f.write(json.dumps(key, indent=1, sort_keys=True).encode()))
    return out


def _atomic_write(path: Path, write) -> None:
    with atomic_open(path, what="cached features") as f:
        write(f)


# what a missing, truncated or foreign cache file raises when opened: it is then recomputed
_UNREADABLE = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile)


def _members(path: Path) -> dict[str, bytes]:
    """A cache file's npy members as bytes, inflated: the file work, which threads may share.

    numpy parses each member's header with `ast.literal_eval`, and CPython 3.11's AST constructor
    keeps one recursion counter for every thread (python/cpython#106905): threads parsing at once
    fail now and then. Reader threads therefore only read and inflate (zlib releases the GIL);
    headers are parsed by the thread that consumes the arrays (`_array`), so no lock is needed."""
    with zipfile.ZipFile(path) as z:
        return {name: z.read(f"{name}.npy") for name in ("data", "fingerprint")}


def _array(member: bytes) -> np.ndarray:
    """The array an npy member holds, without a copy (read-only)."""
    stream = io.BytesIO(member)
    version = np.lib.format.read_magic(stream)
    header = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}.get(version)
    if header is None:
        raise ValueError(f"npy format version {version}, not one the cache writes")
    shape, fortran_order, dtype = header(stream)
    if dtype.hasobject:
        raise ValueError("object arrays are never cached")
    a = np.frombuffer(member, dtype, count=math.prod(shape), offset=stream.tell())
    return a.reshape(shape, order="F" if fortran_order else "C")


def _checked(members: dict[str, bytes] | None, fingerprint: str) -> np.ndarray | None:
    """The cached array, or None when unreadable or made from another archive version."""
    if members is None:
        return None
    try:
        return _array(members["data"]) if str(_array(members["fingerprint"])[()]) == fingerprint else None
    except _UNREADABLE:
        return None


def _read(path: Path) -> dict[str, bytes] | None:
    try:
        return _members(path)
    except _UNREADABLE:
        return None


def load(path: Path, fingerprint: str) -> np.ndarray | None:
    """The cached array, or None when absent, unreadable or made from another archive version."""
    return _checked(_read(path), fingerprint)


def save(path: Path, fingerprint: str, data: np.ndarray) -> None:
    """Features of 8 or 16 bits (frames, sparse flow) deflated (`archive.write_npz`): they shrink
    10-60x; 32-bit floats (PSDs, joints) stored, their noisy low mantissa bits deflate too little
    to pay for the time."""
    _atomic_write(
        path,
        lambda f: archive.write_npz(
            f, {"data": data, "fingerprint": np.array(fingerprint)}, deflate=lambda a: a.dtype.itemsize < 4
        ),
    )


def is_cached(path: Path, fingerprint: str) -> bool:
    """The cache file exists and was made from this archive version (reads only the fingerprint)."""
    try:
        with zipfile.ZipFile(path) as z:
            return str(_array(z.read("fingerprint.npy"))[()]) == fingerprint
    except _UNREADABLE:
        return False


def _compute(job: tuple[str, str, list[str], dict[str, str]]) -> dict[str, np.ndarray]:
    """Compute one trial's features and write the cached ones: (archive path, fingerprint,
    feature names, {feature name: cache file})."""
    path, fingerprint, names, files = job
    features = [feature_named(n) for n in names]
    needs_images = any(f.needs_images for f in features)
    trial = archive.read_archive(path, images=needs_images)
    if needs_images and trial.images is None:
        names = ", ".join(f.name for f in features if f.needs_images)
        raise archive.ArchiveError(path, "images", f"absent, but the features {names} need frames")
    if any(f.needs_reference for f in features) and trial.reference is None:
        raise archive.ArchiveError(
            path,
            "reference",
            f"absent ({archive.reference_note(trial.meta)}), but image_reference='session' reads every "
            "frame against its session's no-contact reference: re-simulate or re-import the data with its reference "
            "(docs/data.md), or read frames as they are: --set=image_reference=training_mean",
        )
    out = {}
    for f in features:
        out[f.name] = f.compute(trial)
        if f.cached:
            save(Path(files[f.name]), fingerprint, out[f.name])
    return out


def _compute_and_drop(job) -> None:
    _compute(job)  # the worker's result stays in its cache file


def _one_thread_per_worker() -> None:
    """Pool initializer: each process computes one trial at a time on one core, on the CPU.

    On a GPU machine every worker would otherwise start JAX's GPU backend and claim most of the
    GPU's memory (JAX preallocates), so all but the first run out of it. The worker has imported
    JAX already (unpickling this function imports the module), and JAX read JAX_PLATFORMS at its
    import: the platform is set in its config too."""
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_cpu_multi_thread_eigen=false").strip()
    os.environ["JAX_PLATFORMS"] = "cpu"
    if "jax" in sys.modules:
        sys.modules["jax"].config.update("jax_platforms", "cpu")
    import cv2

    cv2.setNumThreads(1)


# how many trials the reader threads read ahead of the consumer: enough to keep them busy, few
# enough that a dataset is never held twice in memory on its way into the training arrays
READ_AHEAD = 8


@contextlib.contextmanager
def trial_features(
    index: dataset_index.DatasetIndex,
    entries: list[dataset_index.IndexEntry],
    features: list[Feature],
    features_root: Path,
    *,
    workers: int | None = None,
    progress: bool = True,
) -> Iterator[Iterator[dict[str, np.ndarray]]]:
    """A context whose value gives, for each entry in order, {feature name: array}: from the cache
    where valid, else computed and cached first.

    A context, not a generator, so that its reader threads end on every path: when the caller
    stops early or raises, leaving the `with` cancels the reads not yet started and joins the
    threads, in the caller's thread. A generator left unfinished would leave that to the garbage
    collector, which may run it inside any thread, one of the readers included."""
    folders = {f.name: folder(features_root, index.root, f) for f in features if f.cached}
    for d in folders.values():  # what a killed writer left; the caller holds the cache's lock, so no writer is live
        for partial in d.glob(".*.partial"):
            partial.unlink(missing_ok=True)
    files = lambda e: {name: str(d / f"{Path(e.file).stem}.npz") for name, d in folders.items()}  # noqa: E731
    cached = [f for f in features if f.cached]
    jobs = []
    for e in entries:
        missing = [f for f in cached if not is_cached(Path(files(e)[f.name]), e.fingerprint)]
        if missing:
            jobs.append((str(index.path(e)), e.fingerprint, [f.name for f in missing], files(e)))
    workers = min(workers or os.cpu_count() or 1, max(len(jobs), 1))
    if jobs:
        bar = tqdm(
            total=len(jobs),
            desc=f"features ({', '.join(f.name for f in cached)}, {workers} processes)",
            unit="trial",
            disable=not progress,
        )
        with bar:
            parallel.run_jobs(_compute_and_drop, jobs, workers, bar.update, initializer=_one_thread_per_worker)

    def read(entry: dataset_index.IndexEntry) -> dict[str, dict[str, bytes] | None]:
        return {f.name: _read(Path(files(entry)[f.name])) for f in cached}

    def one(entry: dataset_index.IndexEntry, members: dict[str, dict[str, bytes] | None]) -> dict[str, np.ndarray]:
        out = {name: _checked(m, entry.fingerprint) for name, m in members.items()}
        redo = [f for f in features if out.get(f.name) is None]  # uncached features, or a file damaged since
        if redo:
            out.update(_compute((str(index.path(entry)), entry.fingerprint, [f.name for f in redo], files(entry))))
        return out

    pool = ThreadPoolExecutor(min(4, os.cpu_count() or 1), thread_name_prefix="feature-cache-reader")
    bar = tqdm(total=len(entries), desc="sequences", unit="trial", disable=not progress, leave=False)
    try:

        def trials() -> Iterator[dict[str, np.ndarray]]:
            for entry, members in zip(entries, parallel.ordered_ahead(pool, read, entries, READ_AHEAD)):
                yield one(entry, members)
                bar.update()

        yield trials()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        bar.close()
