"""Timing helpers for the training step and for inference (used by `fabricjax.studies.bench` and
the cost study).

They time the real programs: `Trainer.train_epoch` (a scan over minibatches, vmapped over seeds,
buffers donated) and the jitted `predict_one` (`predict_one_timer`), on synthetic data of the paper's shapes (320 PSD
bins = 15 kHz of 512, N=200 steps). Compilation is excluded; nothing here asserts a time.

An epoch is timed as one call of `STEPS_PER_EPOCH` steps, as training runs it (one call per epoch
or per run; a paper-preset epoch is ~46 steps). Each call of a compiled program gets its scratch
memory fresh from the OS (at 5 seeds ~1.2 GB, ~300,000 page faults), so very short epochs
overstate the cost of a step: at 4 steps per call, 5 seeds measured ~10 % slower per step.
`compare_with_torch` times ours and the optional PyTorch twin (`fabricjax.torch_twin`)
interleaved in one process and reports the ratios.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Callable, Sequence

import jax
import numpy as np

from fabricjax import sharding, stats, synthetic
from fabricjax.config import Config
from fabricjax.model import feature_shapes, make_predict_one
from fabricjax.train import make_trainer, seed_keys, select

STEPS_PER_EPOCH = 16


def train_step_runner(
    config: Config, n_seeds: int, batch: int = 32, seq_len: int = 200, psd_bins: int = 320, steps: int = STEPS_PER_EPOCH
) -> Callable[[], float]:
    """A compiled, warmed-up callable that runs one epoch of `steps` vmapped training steps (the real
    `Trainer.train_epoch` scan, parameters and optimiser state donated) and returns seconds per step.

    Seeds and samples are split over the devices as in training (`sharding.training_mesh`): with
    one CPU device per core (`sharding.use_cpu_cores`), seeds or each minibatch's samples run on
    separate cores."""
    cfg = dataclasses.replace(config, seq_len=seq_len, batch_size=batch)
    mesh = sharding.training_mesh(n_seeds, batch)
    train = jax.device_put(select(cfg, synthetic.data_set(cfg, batch * steps, psd_bins=psd_bins)), sharding.replicated(mesh))
    trainer = make_trainer(cfg, feature_shapes(train["inputs"]), mesh=mesh)
    per_seed = sharding.by_seed(mesh)
    states = jax.jit(sharding.vmap_seeds(trainer.init), out_shardings=per_seed)(jax.device_put(seed_keys(range(n_seeds)), per_seed))
    epoch = jax.jit(sharding.vmap_seeds(lambda c, k, d: trainer.train_epoch(*c, k, d), in_axes=(0, 0, None)), donate_argnums=0)
    keys = states["key"]
    carry = [(states["params"], states["opt_state"])]
    del states

    def run() -> float:
        t = time.perf_counter()
        params, opt_state, curves = epoch(carry[0], keys, train)
        jax.block_until_ready(curves)
        seconds = time.perf_counter() - t
        carry[0] = (params, opt_state)
        return seconds / steps

    run()  # compile and warm up
    return run


def bench_train_step(
    config: Config, n_seeds: int, batch: int = 32, seq_len: int = 200, psd_bins: int = 320, steps: int = STEPS_PER_EPOCH, repeats: int = 3
) -> dict[str, float]:
    """Best-of-`repeats` time of `steps` vmapped training steps: seconds per step and sequences/s per seed."""
    run = train_step_runner(config, n_seeds, batch=batch, seq_len=seq_len, psd_bins=psd_bins, steps=steps)
    per_step = min(run() for _ in range(repeats))
    return {"n_seeds": n_seeds, "seconds_per_step": per_step, "sequences_per_s_per_seed": batch / per_step}


def predict_one_timer(graphdef, params, inputs, warmup: int = 3) -> Callable[[], float]:
    """A compiled, warmed-up (`warmup` calls) callable returning the seconds of one jitted
    `predict_one` call (`model.make_predict_one`) on one sequence `inputs` {modality: (N, ...)}:
    inputs already on the device, dropout off, logits fetched to the host."""
    predict_one = make_predict_one(graphdef)
    one = {m: jax.device_put(a) for m, a in inputs.items()}

    def run() -> float:
        t = time.perf_counter()
        jax.device_get(predict_one(params, one))
        return time.perf_counter() - t

    for _ in range(warmup):
        run()
    return run


def inference_runner(config: Config, seq_len: int = 200, psd_bins: int = 320) -> Callable[[], float]:
    """`predict_one_timer` of an untrained model of `config` on one synthetic sequence."""
    cfg = dataclasses.replace(config, seq_len=seq_len)
    inputs = select(cfg, synthetic.data_set(cfg, 1, psd_bins=psd_bins))["inputs"]
    trainer = make_trainer(cfg, feature_shapes(inputs))
    params = jax.jit(trainer.init)(seed_keys([0])[0])["params"]
    return predict_one_timer(trainer.graphdef, params, {k: v[0] for k, v in inputs.items()})


def bench_inference(config: Config, seq_len: int = 200, psd_bins: int = 320, repeats: int = 200) -> dict[str, float]:
    """p50 / p99 latency in ms of `predict_one` on one sequence (dropout off, result on the host)."""
    run = inference_runner(config, seq_len=seq_len, psd_bins=psd_bins)
    return stats.percentiles_ms([run() for _ in range(repeats)])


# The PyTorch comparison's workload: the paper's model on two microphones (320 bins) + joints.
COMPARE_CONFIG = Config.from_preset("paper", modalities=("internal", "external", "proprio"))


def compare_with_torch(
    config: Config | None = None,
    *,
    seeds: Sequence[int] = (1, 5),
    batch: int = 32,
    seq_len: int = 200,
    psd_bins: int = 320,
    steps: int = STEPS_PER_EPOCH,
    rounds: int = 5,
    inference_rounds: int = 10,
    inference_calls: int = 20,
    pause_s: float = 1.0,
) -> dict[str, Any]:
    """Our training step and inference against the PyTorch twin's, interleaved in one process.

    Every program is built and warmed up first; then each round times ours and the twin's
    back to back for every seed count (who goes first alternates between rounds), so machine load
    hits both alike. Ours trains `n` seeds in one vmapped program, the twin `n` models one after
    another. Ratios are ours / twin (below 1: we are faster): `ratio` is the median of the
    per-round ratios, `ratio_of_medians` the ratio of the median times. Inference alternates
    blocks of `inference_calls` single-sequence calls. `pause_s` separates the two sides: a
    5-seed step of ours measured ~7 % slower 50 ms after the twin's run than 1 s after it. Needs torch (`pip install -e ".[compare]"`; ImportError without it): the twin
    (`fabricjax.torch_twin`) imports torch when called, never at module import.
    """
    from fabricjax import torch_twin as twin

    torch = twin.require()
    config = config or COMPARE_CONFIG
    cfg = dataclasses.replace(config, seq_len=seq_len, batch_size=batch)
    ours = {n: train_step_runner(cfg, n, batch=batch, seq_len=seq_len, psd_bins=psd_bins, steps=steps) for n in seeds}
    theirs = {n: twin.train_step_runner(cfg, n_seeds=n, batch=batch, n_bins=psd_bins, steps=steps) for n in seeds}
    times: dict[str, dict[int, list[float]]] = {"ours": {n: [] for n in seeds}, "torch": {n: [] for n in seeds}}
    for r in range(rounds):
        for n in seeds:
            order = (("ours", ours[n]), ("torch", theirs[n]))
            for side, run in order if r % 2 == 0 else order[::-1]:
                time.sleep(pause_s)
                times[side][n].append(run())
    training: dict[str, Any] = {}
    for n in seeds:
        o, t = np.asarray(times["ours"][n]), np.asarray(times["torch"][n])
        training[f"{n}_seed"] = {
            "ours_s_per_step": float(np.median(o)),
            "torch_s_per_step": float(np.median(t)),
            "ours_min_s": float(o.min()),
            "torch_min_s": float(t.min()),
            "ratio": float(np.median(o / t)),
            "ratio_of_medians": float(np.median(o) / np.median(t)),
            "ratio_of_mins": float(o.min() / t.min()),
            "rounds": {"ours": o.tolist(), "torch": t.tolist()},
        }
    if 1 in seeds:
        for n in seeds:
            if n > 1:
                # Our vmapped n seeds against n times one seed of ours (1.0: vmapping is free).
                ratio = np.asarray(times["ours"][n]) / (n * np.asarray(times["ours"][1]))
                training[f"{n}_seed"]["ours_per_seed_vs_1_seed"] = float(np.median(ratio))
    del ours, theirs
    run_ours = inference_runner(cfg, seq_len=seq_len, psd_bins=psd_bins)
    run_theirs = twin.inference_runner(cfg, n_bins=psd_bins)
    lat: dict[str, list[float]] = {"ours": [], "torch": []}
    for r in range(inference_rounds):
        order = (("ours", run_ours), ("torch", run_theirs))
        for side, run in order if r % 2 == 0 else order[::-1]:
            time.sleep(pause_s)
            lat[side].extend(run() for _ in range(inference_calls))
    p = {k: stats.percentiles_ms(v) for k, v in lat.items()}
    inference = {
        **{f"{k}_p50_ms": v["p50_ms"] for k, v in p.items()},
        **{f"{k}_p99_ms": v["p99_ms"] for k, v in p.items()},
        "ratio_p50": p["ours"]["p50_ms"] / p["torch"]["p50_ms"],
    }
    return {
        "shapes": {"batch": batch, "seq_len": seq_len, "psd_bins": psd_bins, "modalities": list(cfg.modalities)},
        "steps_per_timing": steps,
        "rounds": rounds,
        "torch_threads": torch.get_num_threads(),
        "training": training,
        "inference": inference,
    }
