"""Benchmarks of the feature stage, for the benchmark command (plain functions returning dicts).

`bench_welch` times `welch_psd` against `scipy.signal.welch` (same parameters, float32 input)
and against `jax.scipy.signal.welch` in one process; `bench_extraction` times a cold feature
extraction of a dataset folder and reports the process's peak resident memory.
"""

from __future__ import annotations

import resource
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np
import scipy.signal

from fabricjax.config import Config
from fabricjax.features import welch
from fabricjax.sequences import data
from fabricjax.store import archive
from fabricjax.timing import best_of


def bench_welch(n_windows: int = 4096, repeats: int = 5, seed: int = 0) -> dict:
    """Seconds per call (best of `repeats`, after compilation) on n_windows x 2048 windows."""
    rng = np.random.default_rng(seed)
    full_scale = int(archive.FULL_SCALE)
    words = (rng.integers(-full_scale, full_scale, size=(n_windows, archive.WINDOW)) << archive.SAMPLE_SHIFT).astype(
        np.int32
    )
    samples = np.asarray(welch.to_full_scale(words), np.float32)
    ours = jax.jit(lambda w: welch.welch_psd(w, bandwidth_khz=archive.NYQUIST_KHZ, log=False))
    theirs = jax.jit(lambda x: jax.scipy.signal.welch(x, **welch.SCIPY_KWARGS)[1])
    dev_words, dev_samples = jax.device_put(words), jax.device_put(samples)
    ours(dev_words).block_until_ready()
    theirs(dev_samples).block_until_ready()
    t_ours = best_of(lambda: ours(dev_words).block_until_ready(), repeats)
    t_jax = best_of(lambda: theirs(dev_samples).block_until_ready(), repeats)
    t_scipy = best_of(lambda: scipy.signal.welch(samples, **welch.SCIPY_KWARGS), repeats)
    return {
        "n_windows": n_windows,
        "welch_psd_s": t_ours,
        "jax_scipy_welch_s": t_jax,
        "scipy_welch_s": t_scipy,
        "speedup_vs_scipy": t_scipy / t_ours,
        "windows_per_s": n_windows / t_ours,
        "device": str(jax.devices()[0]),
    }


def _peak_rss_mb() -> float:
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 2**10  # bytes on macOS, KiB on Linux


def bench_extraction(config: Config, data_dir, workdir=None, workers: int | None = None) -> dict:
    """Cold-cache `data.load_sequences` of `data_dir` (a fresh temporary workdir unless given),
    then a warm one. Peak RSS is the whole process's, so run it in a fresh process."""
    with tempfile.TemporaryDirectory() as tmp:
        ws = Path(workdir or tmp)
        t = time.perf_counter()
        sets = data.load_sequences(config, data_dir, workdir=ws, workers=workers, progress=False)
        cold = time.perf_counter() - t
        sizes = {k: len(v) for k, v in sets.items()}
        del sets
        t = time.perf_counter()
        data.load_sequences(config, data_dir, workdir=ws, workers=workers, progress=False)
        warm = time.perf_counter() - t
    return {
        "modalities": list(config.modalities),
        "sequences": sizes,
        "cold_s": cold,
        "warm_s": warm,
        "peak_rss_mb": _peak_rss_mb(),
    }
