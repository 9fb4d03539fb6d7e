"""Loaded sequences as memory-mapped files: data larger than memory, read a minibatch at a time.

`data.load_sequences` fills a split's arrays in memory where they fit; where they would take
more than `data.MEMORY_FRACTION` of this machine's memory (or `Config.input_source` is "disk") it
fills `.npy` files here instead, and training reads them from the host (`fabricjax.training.feed`):
the page cache holds what was read recently, and the process holds only its blocks.

Layout under `workspace.sequences_dir(workdir)`:

    <key>/key.json                  what the sequences were made from (features, N, band, trials)
    <key>/<split>.<modality>.npy    (S, N, ...) in the loaded dtype, read with mmap_mode="r"

`key` hashes key.json's contents, so other features, sequence lengths or trial versions (a
fingerprint) make another folder, and a second load of the same sequences (a study's next run,
a resumed run) reads the files without touching the features. A folder is written under a
`.partial` name and renamed when complete: a killed load leaves no folder that looks whole.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from fabricjax.errors import UserError
from fabricjax.store import disk


class SequenceStore:
    """The files of one set of loaded sequences (see the module docstring)."""

    def __init__(self, root: Path, key: Mapping[str, Any]):
        self.key = json.loads(json.dumps(key, sort_keys=True))
        digest = hashlib.sha256(json.dumps(self.key, sort_keys=True).encode()).hexdigest()[:16]
        self.folder = Path(root) / digest
        self._partial = self.folder.with_name(digest + ".partial")

    def _arrays(
        self, folder: Path, arrays: Mapping[str, list[str]], mode: str | None = "r"
    ) -> dict[str, dict[str, np.ndarray]]:
        return {s: {m: np.load(folder / f"{s}.{m}.npy", mmap_mode=mode) for m in ms} for s, ms in arrays.items()}

    def load(self) -> dict[str, dict[str, np.ndarray]] | None:
        """The stored sequences, memory-mapped read-only, or None where this key has none."""
        try:
            saved = json.loads((self.folder / "key.json").read_text())
            return self._arrays(self.folder, saved["arrays"]) if saved["key"] == self.key else None
        except (OSError, ValueError, KeyError):
            return None

    def create(
        self, shapes: Mapping[str, Mapping[str, tuple[tuple[int, ...], Any]]]
    ) -> dict[str, dict[str, np.memmap]]:
        """Zeroed writable files {split: {modality: (shape, dtype)}} to fill, then `finish`; a
        one-line `UserError`, having written nothing, where the disk has not the room."""
        shutil.rmtree(self._partial, ignore_errors=True)
        need = sum(math.prod(shape) * np.dtype(dtype).itemsize for d in shapes.values() for shape, dtype in d.values())
        self.folder.parent.mkdir(parents=True, exist_ok=True)
        free = shutil.disk_usage(self.folder.parent).free
        if need > free:
            raise UserError(
                f"{self.folder.parent}: the loaded sequences need {disk.size(need)} of memory-mapped files, "
                f"only {disk.size(free)} free "
                "(free disk space, give --workdir on a larger disk, or --set=input_source=memory where "
                "memory holds them)"
            )
        self._partial.mkdir(parents=True)
        return {
            s: {
                m: np.lib.format.open_memmap(self._partial / f"{s}.{m}.npy", mode="w+", dtype=dtype, shape=shape)
                for m, (shape, dtype) in d.items()
            }
            for s, d in shapes.items()
        }

    def finish(self, arrays: Mapping[str, Mapping[str, np.memmap]]) -> dict[str, dict[str, np.ndarray]]:
        """Flush the filled files, make the folder whole, and read it back read-only."""
        for d in arrays.values():
            for a in d.values():
                a.flush()
        listing = {s: sorted(d) for s, d in arrays.items()}
        (self._partial / "key.json").write_text(
            json.dumps({"key": self.key, "arrays": listing}, indent=1, sort_keys=True)
        )
        shutil.rmtree(self.folder, ignore_errors=True)
        self._partial.rename(self.folder)
        return self._arrays(self.folder, listing)
