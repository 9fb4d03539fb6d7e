"""Timing helpers for the training step and for inference (used by `experiments.bench`).

They time the real programs: `Trainer.train_epoch` (a scan over minibatches, vmapped over seeds,
buffers donated) and the jitted `predict_one`, on synthetic data of the paper's shapes (320 PSD
bins = 15 kHz of 512, N=200 steps). Compilation is excluded; nothing here asserts a time.
"""

from __future__ import annotations

import dataclasses
import time

import jax
import numpy as np

from fabricjax import synthetic
from fabricjax.config import Config
from fabricjax.model import feature_shapes, predict_one
from fabricjax.train import make_trainer, seed_keys, select


def bench_train_step(
    config: Config, n_seeds: int, batch: int = 32, seq_len: int = 200, psd_bins: int = 320, steps: int = 4, repeats: int = 3
) -> dict[str, float]:
    """Best-of-`repeats` time of `steps` vmapped training steps: seconds per step and sequences/s per seed."""
    cfg = dataclasses.replace(config, seq_len=seq_len, batch_size=batch)
    train = select(cfg, synthetic.data_set(cfg, batch * steps, psd_bins=psd_bins))
    trainer = make_trainer(cfg, feature_shapes(train["inputs"]))
    states = jax.jit(jax.vmap(trainer.init))(seed_keys(range(n_seeds)))
    carry = (states["params"], states["opt_state"])
    epoch = jax.jit(
        jax.vmap(lambda c, k, d: trainer.train_epoch(*c, k, d), in_axes=(0, 0, None)), donate_argnums=0
    )
    keys = states["key"]
    params, opt_state, loss = epoch(carry, keys, train)  # compile and warm up
    jax.block_until_ready(loss)
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        params, opt_state, loss = epoch((params, opt_state), keys, train)
        jax.block_until_ready(loss)
        best = min(best, time.perf_counter() - t)
    per_step = best / steps
    return {"n_seeds": n_seeds, "seconds_per_step": per_step, "sequences_per_s_per_seed": batch / per_step}


def bench_inference(config: Config, seq_len: int = 200, psd_bins: int = 320, repeats: int = 200) -> dict[str, float]:
    """p50 / p99 latency in ms of `predict_one` on one sequence (dropout off, result on the host)."""
    cfg = dataclasses.replace(config, seq_len=seq_len)
    inputs = select(cfg, synthetic.data_set(cfg, 1, psd_bins=psd_bins))["inputs"]
    trainer = make_trainer(cfg, feature_shapes(inputs))
    params = jax.jit(trainer.init)(seed_keys([0])[0])["params"]
    one = {k: v[0] for k, v in inputs.items()}
    jax.block_until_ready(predict_one(trainer.graphdef, params, one))
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(predict_one(trainer.graphdef, params, one))
        times.append(time.perf_counter() - t)
    ms = 1e3 * np.asarray(times)
    return {"p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99))}
