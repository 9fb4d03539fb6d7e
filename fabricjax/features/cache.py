"""The feature cache: each trial's feature arrays on disk, so a second run does no feature work.

Layout under `workspace.features_dir(workdir)`:

    <feature name>-<key>/key.json          what the key stands for (feature, params, dataset)
    <feature name>-<key>/<archive stem>.npz    {"data": array, "fingerprint": archive fingerprint}

`key` hashes the feature's parameters and the dataset folder's absolute path, so a changed
parameter starts a new folder. Inside, a file is trusted only if its stored fingerprint equals
the archive's current `IndexEntry.fingerprint` (name, size, mtime): a rewritten archive is
recomputed and its entry overwritten. Files are written to a temporary name and renamed.

Trials whose features are missing are computed in parallel threads (OpenCV, XLA and file reads
release the GIL), each trial read once, without its images unless a missing feature needs them.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Iterator

import numpy as np
from tqdm import tqdm

from fabricjax import archive
from fabricjax.atomic import atomic_open
from fabricjax.features.extract import Feature


def folder(features_root: Path, dataset_root: Path, feature: Feature) -> Path:
    key = {"feature": feature.name, "params": feature.params, "dataset": str(Path(dataset_root).resolve())}
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]
    out = Path(features_root) / f"{feature.name}-{digest}"
    if not (out / "key.json").exists():
        out.mkdir(parents=True, exist_ok=True)
        _atomic_write(out / "key.json", lambda f: f.write(json.dumps(key, indent=1, sort_keys=True).encode()))
    return out


def _atomic_write(path: Path, write) -> None:
    with atomic_open(path) as f:
        write(f)


def load(path: Path, fingerprint: str) -> np.ndarray | None:
    """The cached array, or None when absent, unreadable or made from another archive version."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return z["data"] if str(z["fingerprint"]) == fingerprint else None
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):  # a damaged file is recomputed
        return None


def save(path: Path, fingerprint: str, data: np.ndarray) -> None:
    _atomic_write(path, lambda f: np.savez(f, data=data, fingerprint=np.array(fingerprint)))


def trial_features(
    index: archive.DatasetIndex,
    entries: list[archive.IndexEntry],
    features: list[Feature],
    features_root: Path,
    *,
    workers: int | None = None,
    progress: bool = True,
) -> Iterator[dict[str, np.ndarray]]:
    """For each entry in order, {feature name: array}, from the cache where valid, else computed
    and cached. A generator, so the caller can keep only what it needs of each trial."""
    folders = {f.name: folder(features_root, index.root, f) for f in features if f.cached}

    def one(entry: archive.IndexEntry) -> dict[str, np.ndarray]:
        stem = Path(entry.file).stem
        out = {f.name: load(folders[f.name] / f"{stem}.npz", entry.fingerprint) for f in features if f.cached}
        missing = [f for f in features if out.get(f.name) is None]
        if missing:
            needs_images = any(f.needs_images for f in missing)
            trial = archive.read_archive(index.path(entry), images=needs_images)
            if needs_images and trial.images is None:
                names = ", ".join(f.name for f in missing if f.needs_images)
                raise archive.ArchiveError(index.path(entry), "images", f"absent, but the features {names} need frames")
            for f in missing:
                out[f.name] = f.compute(trial)
                if f.cached:
                    save(folders[f.name] / f"{stem}.npz", entry.fingerprint, out[f.name])
        return out

    with ThreadPoolExecutor(workers or os.cpu_count() or 1) as pool:
        yield from tqdm(pool.map(one, entries), total=len(entries), desc="features", unit="trial", disable=not progress)
