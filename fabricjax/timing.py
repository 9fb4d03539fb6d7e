"""Timing helpers shared by the speed benchmarks (`fabricjax.bench`) and the studies that report
a cost (`studies.diagnostics.cost`, `studies.diagnostics.flow_agreement`): below both, so neither imports the other.

    best_of            the shortest of some timed calls of a function
    predict_one_timer  one call of the compiled `predict_one` on one sequence, result on the host
    bench_flow         seconds per frame pair of dense Farneback flow: OpenCV on one thread, OpenCV
                       on every core, and the JAX reimplementation (features/farneback.py) batched
                       over JAX's CPU devices

Compilation is excluded from every time; nothing here asserts one. `bench_flow`'s frame pairs are
blurred noise moved by one pixel: Farneback's cost does not depend on the content.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import cv2
import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from fabricjax.features import farneback
from fabricjax.model import compile_predict_one


def best_of(fn, repeats: int) -> float:
    """The shortest of `repeats` timed calls of `fn`, in seconds."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def predict_one_timer(graphdef, params, inputs, warmup: int = 3) -> Callable[[], float]:
    """A warmed-up (`warmup` calls) callable returning the seconds of one `predict_one` call (the
    ahead-of-time compiled `model.compile_predict_one`) on one sequence `inputs` {modality: (N, ...)}:
    inputs already on the device, dropout off, logits fetched to the host."""
    device = jax.devices()[0]
    one = {m: jax.device_put(a, device) for m, a in inputs.items()}
    predict_one = compile_predict_one(graphdef, params, one, device)

    def run() -> float:
        t = time.perf_counter()
        jax.device_get(predict_one(one))
        return time.perf_counter() - t

    for _ in range(warmup):
        run()
    return run


def _pairs(size: tuple[int, int], n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    first = np.stack([cv2.GaussianBlur(rng.integers(0, 256, size, dtype=np.uint8), (0, 0), 1.5) for _ in range(n)])
    return first, np.roll(first, 1, axis=2)


def bench_flow(sizes=((308, 410), (60, 80)), batch: int = 8, repeats: int = 3, seed: int = 0) -> dict:
    """Per size, seconds per frame pair (best of `repeats` over `batch` pairs): OpenCV with
    cv2.setNumThreads(1), one pair at a time ("opencv_1_thread_s") and pairs in a pool of
    os.cpu_count() threads ("opencv_all_cores_s"); JAX after compilation ("jax_s", the batch split
    over the CPU devices where they divide it, "jax_compile_s" the first call)."""
    devices = jax.devices()
    n_dev = max(d for d in range(1, len(devices) + 1) if batch % d == 0)
    sharding = NamedSharding(Mesh(np.asarray(devices[:n_dev]), ("batch",)), P("batch"))
    threads = os.cpu_count() or 1
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    out = {
        "batch": batch,
        "jax_devices": n_dev,
        "device": str(devices[0].platform),
        "opencv_threads": threads,
        "sizes": {},
    }
    try:
        for size in sizes:
            first, second = _pairs(tuple(size), batch, seed)

            def one(i):
                return cv2.calcOpticalFlowFarneback(first[i], second[i], None, **farneback.FARNEBACK)

            serial = best_of(lambda: [one(i) for i in range(batch)], repeats)
            with ThreadPoolExecutor(threads) as pool:
                pooled = best_of(lambda: list(pool.map(one, range(batch))), repeats)
            a, b = jax.device_put(first, sharding), jax.device_put(second, sharding)
            t = time.perf_counter()
            farneback.farneback(a, b).block_until_ready()
            compile_s = time.perf_counter() - t
            jitted = best_of(lambda: farneback.farneback(a, b).block_until_ready(), repeats)
            out["sizes"][f"{size[0]}x{size[1]}"] = {
                "opencv_1_thread_s": serial / batch,
                "opencv_all_cores_s": pooled / batch,
                "jax_s": jitted / batch,
                "jax_compile_s": compile_s,
            }
    finally:
        cv2.setNumThreads(before)
    return out
