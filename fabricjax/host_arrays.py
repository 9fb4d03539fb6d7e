"""Host arrays that CPU devices read in place.

XLA's CPU client places a C-contiguous NumPy array whose data starts on a 64-byte boundary
without copying it: the device buffer is the array's own memory (`jax.device_put` on CPU
devices; PjRt's zero-copy host buffers), on every device of a replicated placement. NumPy's own
large allocations start 16 bytes past such a boundary, so they are copied, once per device. The
sets a study trains on are GBs (a camera row's training frames, replicated on every CPU device),
so the arrays made to be placed (loaded sequences, pixel rows, padded evaluation sets) are
allocated here: their placement then costs no copy and no memory on CPU devices. On accelerators
they are copied into device memory either way.

Aliasing is safe only for arrays nobody writes after placing them: loaded data sets are read-only
(`data.load_sequences`), and the copies made for placement are never written again.
"""

from __future__ import annotations

import math
import mmap
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import jax

ALIGNMENT = 64  # bytes: the boundary XLA:CPU's buffers start on (its minimum alignment)


def empty(shape: tuple[int, ...], dtype) -> np.ndarray:
    """A zeroed C-contiguous array in memory of its own (an anonymous mapping, which starts on a
    page boundary, so on an `ALIGNMENT`-byte one), freed with the array.

    Not NumPy's allocation for another reason too: NumPy asks the kernel for transparent huge
    pages for large arrays (`madvise`), and where memory is fragmented (after a data set's GBs
    went through the page cache) the kernel may compact memory to find them, synchronously, at
    the first write of each page, which makes writing a fresh array erratically slow. These arrays
    are read in blocks of whole sequences, for which ordinary pages do as well."""
    dtype = np.dtype(dtype)
    count = math.prod(shape)
    return np.frombuffer(mmap.mmap(-1, max(count * dtype.itemsize, 1)), dtype, count).reshape(shape)


def placed_in_place(placed: jax.Array, host: np.ndarray) -> bool:
    """Whether every device's part of `placed` is `host`'s own memory (a placement without copy)."""
    address = host.__array_interface__["data"][0]
    return all(s.data.unsafe_buffer_pointer() == address for s in placed.addressable_shards)


def whole_minibatches(n: int, batch_size: int) -> int:
    """Sequences of an evaluation set of `n` run in whole minibatches: padding with zero inputs and
    unknown (-1) labels, which every metric ignores, up to this many."""
    return n + -n % batch_size


def padded(a: np.ndarray, length: int, fill) -> np.ndarray:
    """`a` with rows of `fill` appended up to `length` rows, as a new array of this module's (`a`
    itself where it has them already)."""
    if len(a) == length:
        return a
    out = empty((length, *a.shape[1:]), a.dtype)
    out[: len(a)], out[len(a) :] = a, fill
    return out
