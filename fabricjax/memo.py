"""Values derived from a large host array, kept while the array lives: what the rows of a study
share instead of recomputing (a camera row's frames on the devices, their input statistics).

A study trains many rows on the arrays it loaded once: every camera row reads the same GB of
frames, which training moves onto every device in its own layout (~8 s a row) and whose
statistics it sums (~1 s). An entry is keyed by the array's identity and the caller's key and dies
with the array (a weak reference), so a new data set never meets an old entry. Loaded data sets
are read-only: nothing in fabricjax writes into one. Arrays under `MIN_BYTES` are not worth
holding and are recomputed each time.
"""

from __future__ import annotations

import functools
import weakref
from collections import OrderedDict
from typing import Callable, Hashable, TypeVar

import numpy as np

MIN_BYTES = 64 << 20  # below this an array's derived values are recomputed: cheap, and not worth memory

T = TypeVar("T")


class ByArray:
    """Up to `max_entries` values, each made from one array (`get`), the least recently used dropped first."""

    def __init__(self, max_entries: int):
        self.max_entries = max_entries
        self._entries: OrderedDict[tuple[int, Hashable], tuple[weakref.ref, object]] = OrderedDict()

    def get(self, array, key: Hashable, make: Callable[[], T]) -> T:
        """`make()`'s value for (`array`, `key`): made once while `array` lives, then returned."""
        if not isinstance(array, np.ndarray) or array.nbytes < MIN_BYTES:  # device arrays: no identity to keep
            return make()
        k = (id(array), key)
        held = self._entries.get(k)
        if held is not None and held[0]() is array:
            self._entries.move_to_end(k)
            return held[1]
        value = make()
        self._entries[k] = (weakref.ref(array, functools.partial(self._drop, k)), value)
        while len(self._entries) > self.max_entries:
            self._entries.popitem(last=False)
        return value

    def _drop(self, k: tuple[int, Hashable], _dead: weakref.ref) -> None:
        self._entries.pop(k, None)

    def __len__(self) -> int:
        return len(self._entries)
