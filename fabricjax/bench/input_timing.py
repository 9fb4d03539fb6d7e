"""Minibatch throughput of training fed from the host (`fabricjax.training.feed`): the same blocks of
shuffled sequences gathered from an array in memory, from a memory-mapped file whose pages the
kernel has just dropped (read from disk), and from the same file again (from the page cache).

The sequences are the paper preset's flow features (N=200 steps of 2x102x137 float16, 11 MB a
sequence), the input that outgrows memory at the paper's scale; a block is what one training
step of 5 vmapped seeds at batch 32 reads (each seed its own shuffle). A plain function returning a
dict, for the benchmark command.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from fabricjax import host_arrays
from fabricjax.features import flow
from fabricjax.training import feed

PAPER_FLOW_STEP = (2, *flow.pooled_shape(308, 410))


def _drop_from_page_cache(path: Path) -> None:
    """Ask the kernel to forget the file's cached pages, so the next reads go to the disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    finally:
        os.close(fd)


def bench_input(
    n_sequences: int = 96, seq_len: int = 200, batch: int = 32, n_seeds: int = 5, steps: int = 3, seed: int = 0
) -> dict:
    """Per source ("memory"; "disk_cold": the file's pages dropped before each step; "disk_warm":
    the file again, as the page cache holds it): seconds per training step's minibatches (every
    seed's, `steps` steps) gathered and laid out as training reads them, MB/s and sequences/s."""
    rng = np.random.default_rng(seed)
    shape = (n_sequences, seq_len, *PAPER_FLOW_STEP)
    in_memory = host_arrays.empty(shape, np.float16)
    for i in range(n_sequences):
        in_memory[i] = rng.standard_normal(shape[1:], np.float32)
    orders = [
        rng.integers(0, n_sequences, n_seeds * batch) for _ in range(steps)
    ]  # every seed draws its own minibatch; their draws overlap, as in training
    per_step = n_seeds * batch * in_memory[0].nbytes

    def timed(array, before=lambda: None) -> float:
        total = 0.0
        for rows in orders:
            before()
            t = time.perf_counter()
            feed._laid_out({"flow": array}, rows)
            total += time.perf_counter() - t
        return total / steps

    out = {
        "sequence_mb": in_memory[0].nbytes / 1e6,
        "step_mb": per_step / 1e6,
        "batch": batch,
        "n_seeds": n_seeds,
        "file_mb": in_memory.nbytes / 1e6,
        "sources": {},
    }
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "flow.npy"
        np.save(path, in_memory)
        on_disk = np.load(path, mmap_mode="r")
        seconds = {
            "memory": timed(in_memory),
            "disk_cold": timed(on_disk, lambda: _drop_from_page_cache(path)),
            "disk_warm": timed(on_disk),
        }
        del on_disk
    for source, s in seconds.items():
        out["sources"][source] = {
            "s_per_step": s,
            "mb_per_s": per_step / 1e6 / s,
            "sequences_per_s": n_seeds * batch / s,
        }
    return out
