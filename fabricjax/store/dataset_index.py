"""A dataset's index: every archive of a folder with its meta, step count, size, modification time
and sha256. It is `index.json` beside the simulator's own archives (`<workspace>/datasets/`), and under
`<workspace>/indexes/` for any other folder, even one inside the workspace: a folder of
recordings is only read (`workspace.index_file`). `load_index` builds it on first use and
rebuilds it when archives were added or rewritten, reading and hashing only those;
`fabricjax.store.integrity` re-hashes a dataset against it."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from pathlib import Path
from typing import Any

from fabricjax.store import workspace
from fabricjax.store.archive import ArchiveError, read_meta
from fabricjax.store.atomic import atomic_open

INDEX_VERSION = 1  # the index's own format (its entries hold each archive's meta)


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

    @property
    def content_hash(self) -> str:
        """Identifies the dataset by its contents (every archive's name and sha256), wherever its
        folder lies: what checkpoints are keyed by, so that a model is never reused on other data."""
        return hashlib.sha256("\n".join(f"{e.file} {e.sha256}" for e in self.entries).encode()).hexdigest()[:16]

    def identity(self) -> dict[str, str]:
        """The dataset as a checkpoint records it: its folder (as commands name it) and `content_hash`."""
        return {"folder": workspace.shown(self.root), "content": self.content_hash}


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
        if doc.get("format_version") != INDEX_VERSION:
            return {}
        return {e.file: e for e in (IndexEntry(**t) for t in doc["trials"]) if e.sha256}
    except (OSError, ValueError, KeyError, TypeError):  # ValueError: not JSON, or not UTF-8
        return {}


def build_index(folder: os.PathLike | str, index_file: os.PathLike | str | None = None) -> DatasetIndex:
    """Scan a folder of archives (hardware or simulated) and write its index to `index_file`
    (default: `index.json` in the folder, as the simulator does for the datasets it writes).
    Each entry records the archive's sha256 (`fabricjax.store.integrity.verify` re-hashes against it); an
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
    doc = {
        "format_version": INDEX_VERSION,
        "folder": str(root.resolve()),
        "trials": [dataclasses.asdict(e) for e in entries],
    }
    ipath.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(ipath, "w", what="the dataset index") as f:
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
        if doc.get("format_version") != INDEX_VERSION:
            raise ArchiveError(ipath, "format_version", f"unknown index version {doc.get('format_version')!r}")
        entries = tuple(IndexEntry(**t) for t in doc["trials"])
    except ArchiveError:
        raise
    except (ValueError, KeyError, TypeError) as e:  # ValueError: not JSON, or not UTF-8
        raise ArchiveError(ipath, "trials", f"malformed index: {e}") from None
    for e in entries:
        if e.file not in on_disk:
            raise ArchiveError(
                ipath,
                f"trials[{e.file}]",
                f"listed archive is missing from {root} (restore it, or delete {ipath} to re-index)",
            )
    stale = len(on_disk) != len(entries) or any(
        not e.sha256 or on_disk[e.file].st_size != e.size or on_disk[e.file].st_mtime_ns != e.mtime_ns for e in entries
    )
    return build_index(root, ipath) if stale else DatasetIndex(root, entries)
