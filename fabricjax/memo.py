"""Values derived from a large host array, kept while the array lives: what the rows of a study
share instead of recomputing (a camera row's frames on the devices, their input statistics).

A study trains many rows on the arrays it loaded once: every camera row reads the same GB of
frames, which training lays out as pixel rows and places on every device (`placement`) and whose
statistics it sums (`inputs.input_statistics`). An entry is keyed by the array's
identity (a view's: its root array's, with the view's offset, shape and strides, so that the PSD
cut to a row's bandwidth, a new view each row, is found again) and the caller's key, and dies
with the root array (a weak reference), so a new data set never meets an old entry. Loaded data
sets are read-only (`data.load_sequences` marks their arrays so): an array changed in place would
meet its old entries. Arrays under `MIN_BYTES` are not worth holding and are recomputed each time.
"""

from __future__ import annotations

import functools
import os
import weakref
from collections import OrderedDict
from typing import Callable, Hashable, TypeVar

import numpy as np

MIN_BYTES = 64 << 20  # below this an array's derived values are recomputed: cheap, and not worth memory

T = TypeVar("T")


def memory_budget(fraction: float = 0.25) -> int:
    """`fraction` of this machine's physical memory, in bytes (what kept values may hold)."""
    return int(fraction * os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))


class ByArray:
    """Values each made from one array (`get`), at most `max_entries` of them and `max_bytes` in
    all (as `size` counts a value), the least recently used dropped first."""

    def __init__(self, max_entries: int, max_bytes: int | None = None, size: Callable[[object], int] = lambda value: 0):
        self.max_entries, self.max_bytes, self.size = max_entries, max_bytes, size
        self._entries: OrderedDict[Hashable, tuple[weakref.ref, object, int]] = OrderedDict()

    def get(self, array, key: Hashable, make: Callable[[], T], keep: Callable[[T], bool] = lambda value: True) -> T:
        """`make()`'s value for (`array`, `key`): made once while `array` lives, then returned;
        a value that `keep` rejects is returned without being kept."""
        if not isinstance(array, np.ndarray) or array.nbytes < MIN_BYTES:  # device arrays: no identity to keep
            return make()
        root = array
        while isinstance(root.base, np.ndarray):
            root = root.base
        k = (id(root), array.__array_interface__["data"][0], array.shape, array.strides, array.dtype.str, key)
        held = self._entries.get(k)
        if held is not None and held[0]() is root:
            self._entries.move_to_end(k)
            return held[1]
        value = make()
        if not keep(value):
            return value
        self._entries[k] = (weakref.ref(root, functools.partial(self._drop, k)), value, self.size(value))
        while len(self._entries) > self.max_entries or (self.max_bytes is not None and self.nbytes > self.max_bytes):
            self._entries.popitem(last=False)
        return value

    def _drop(self, k: Hashable, _dead: weakref.ref) -> None:
        self._entries.pop(k, None)

    @property
    def nbytes(self) -> int:
        return sum(size for _, _, size in self._entries.values())

    def __len__(self) -> int:
        return len(self._entries)
