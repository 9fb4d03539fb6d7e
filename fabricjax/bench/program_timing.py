"""Timing helpers for the training step and for inference (used by `fabricjax.bench.suite` and
the cost study).

They time the real programs: `Trainer.train_epoch` (a scan over minibatches, vmapped over seeds,
buffers donated) and the compiled `predict_one` (`timing.predict_one_timer`), on synthetic data of the paper's shapes
(320 PSD
bins = 15 kHz of 512, N=200 steps). Compilation is excluded; nothing here asserts a time.

An epoch is timed as one call of `STEPS_PER_EPOCH` steps, as training runs it (one call per epoch
or per run). Each call of a compiled program gets its scratch memory fresh from the OS, so very
short epochs would overstate the cost of a step.
`compare_with_torch` times ours and the optional PyTorch twin (`fabricjax.bench.torch_twin`), eager and
`torch.compile`d, interleaved in one process and reports the ratios.

Ours runs in each compute dtype (`Config.compute_dtype`, `DTYPES`), the twin in float32 and under
its bfloat16 autocast. How close a program comes to the machine: `xla_flops` counts a compiled
program's FLOPs with XLA's own cost analysis, `matmul_peak` measures the practical peak of one
operand dtype (a dense matmul over the same devices, accumulating in float32), and `utilisation`
divides the rates, against the float32 and the bfloat16 peak alike.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from typing import Any, Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.model import compile_predict_one
from fabricjax.reporting import stats
from fabricjax.sequences.inputs import feature_shapes, training_layout
from fabricjax.timing import predict_one_timer
from fabricjax.training import sharding
from fabricjax.training.placement import select
from fabricjax.training.feed import DeviceFeed
from fabricjax.training.trainer import make_trainer, seed_keys

STEPS_PER_EPOCH = 16
MATMUL_N = 2048  # the practical peak's matmul: (N x N) @ (N x N), large enough to run at the BLAS's best
DTYPES = ("float32", "bfloat16")  # the compute dtypes the benchmarks time ours in, and the peaks they measure


def xla_flops(jitted, *args) -> float:
    """FLOPs of one call of `jitted` (a `jax.jit` function) on `args`, by XLA's cost analysis of
    the compiled program, summed over the devices it runs on.

    The analysis is of the per-device program after SPMD partitioning, so it is multiplied by the
    number of devices the program's shardings span (replicated work counts once per device: the
    machine does it). `cost_analysis()` is a dict in recent JAX, a list of dicts (one per module)
    in older ones. A loop's body is counted once, whatever its trip count: time a program
    without a loop, or one with a single trip, to count a step."""
    return compiled_flops(jitted.lower(*args).compile())


def compiled_flops(compiled: jax.stages.Compiled) -> float:
    """FLOPs of one call of an ahead-of-time compiled program, as `xla_flops` counts them."""
    costs = compiled.cost_analysis()
    per_device = sum(float(c.get("flops", 0.0)) for c in (costs if isinstance(costs, (list, tuple)) else [costs]))
    shardings = jax.tree.leaves((compiled.input_shardings, compiled.output_shardings))
    devices = set().union(*(s.device_set for s in shardings)) if shardings else {None}
    return per_device * len(devices)


def matmul_peak(n: int = MATMUL_N, repeats: int = 5, dtype: str = "float32") -> dict[str, Any]:
    """The practical peak of the devices for `dtype` operands: a jitted (n x n) @ (n x n) matmul
    accumulating in float32 (`preferred_element_type`, as the model's products), its rows split
    over every JAX device (as training splits its batch), timed after warm-up, best of `repeats`.
    Its FLOPs are XLA's count (`xla_flops`), so a utilisation divides like by like."""
    devices = jax.devices()
    n = -(-n // len(devices)) * len(devices)  # rows divide evenly over the devices
    mesh = jax.sharding.Mesh(np.asarray(devices), ("rows",))
    a = jax.device_put(
        jax.random.normal(jax.random.PRNGKey(0), (n, n), dtype),
        jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("rows")),
    )
    b = jax.device_put(
        jax.random.normal(jax.random.PRNGKey(1), (n, n), dtype),
        jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec()),
    )
    matmul = jax.jit(lambda x, y: jnp.dot(x, y, preferred_element_type=jnp.float32))
    flops = xla_flops(matmul, a, b)
    jax.block_until_ready(matmul(a, b))  # compile and warm up

    def once() -> float:
        t = time.perf_counter()
        jax.block_until_ready(matmul(a, b))
        return time.perf_counter() - t

    seconds = min(once() for _ in range(repeats))
    return {
        "n": n,
        "devices": len(devices),
        "dtype": dtype,
        "flops": flops,
        "seconds": seconds,
        "gflop_per_s": flops / seconds / 1e9,
    }


def utilisation(flops: float, seconds: float, peaks: dict[str, float]) -> dict[str, Any]:
    """FLOPs of one step or call taking `seconds`: achieved GFLOP/s and its fraction of each matmul
    peak (`peaks`: operand dtype -> GFLOP/s, `matmul_peak`)."""
    achieved = flops / seconds / 1e9
    return {
        "flops_per_step": flops,
        "gflop_per_s": achieved,
        "fraction_of_peak": {k: achieved / v for k, v in peaks.items()},
    }


def _epoch_program(
    config: Config,
    n_seeds: int,
    batch: int,
    seq_len: int,
    psd_bins: int,
    steps: int,
    image_hw: tuple[int, int] | None = None,
):
    """The jitted, vmapped `Trainer.train_epoch` and its arguments (the seeds' states, the
    training set) on synthetic data of `psd_bins` and `image_hw` frames (`_epoch_program_on`)."""
    cfg = dataclasses.replace(config, seq_len=seq_len, batch_size=batch)
    frames = {} if image_hw is None else {"image_hw": tuple(image_hw)}  # None: synthetic's own frame size
    return _epoch_program_on(cfg, n_seeds, synthetic.data_set(cfg, batch * steps, psd_bins=psd_bins, **frames))


def _epoch_program_on(config: Config, n_seeds: int, data: dict[str, Any]):
    """The jitted, vmapped `Trainer.train_epoch` of `config` over the whole of `data` (one epoch of
    its minibatches), the seeds' states and the training set, placed as training places them
    (`sharding.training_mesh`)."""
    mesh = sharding.training_mesh(config.batch_size)
    chosen = select(config, data)
    n_train = len(next(iter(chosen["inputs"].values())))
    trainer = make_trainer(config, feature_shapes(chosen["inputs"]), mesh=mesh, n_train=n_train)
    train = jax.device_put({**chosen, "inputs": training_layout(chosen["inputs"])}, sharding.replicated(mesh))
    per_seed = sharding.replicated(mesh)
    states = jax.jit(sharding.vmap_seeds(trainer.init), out_shardings=per_seed)(
        jax.device_put(seed_keys(range(n_seeds)), per_seed)
    )
    on_devices = DeviceFeed()
    epoch = jax.jit(
        sharding.vmap_seeds(lambda s, d: trainer.train_epoch(s, d, on_devices), in_axes=(0, None)), donate_argnums=0
    )
    return epoch, states, train, trainer


@dataclasses.dataclass(frozen=True)
class RowCost:
    """What one row's programs cost on this host, vmapped over its seeds: a training step (one
    minibatch per seed), a validation minibatch, their FLOPs (XLA's cost analysis) and the seconds
    to compile both."""

    s_per_step: float
    s_per_eval_batch: float
    flops_per_step: float
    flops_per_eval_batch: float
    compile_s: float


def row_cost(
    config: Config,
    n_seeds: int,
    arrays: dict[str, tuple[tuple[int, ...], Any]],
    steps: int = 8,
    repeats: int = 2,
) -> RowCost:
    """`config`'s training step and validation minibatch timed on this host on inputs of per-step
    `arrays` ({modality: (shape, dtype)}, `Feature.step_array`), `steps` of each per call, best of
    `repeats` calls after a first that warms up. The real programs (`Trainer.train_epoch`,
    `Trainer.predict`), compiled once each; XLA counts a loop's body once, so the compiled epoch's
    and prediction's FLOPs are one step's and one minibatch's."""
    n = config.batch_size * steps
    data = synthetic.shaped({m: arrays[m] for m in config.modalities}, n, config.seq_len, n_classes=config.n_classes)
    t0 = time.perf_counter()
    epoch, states, train, trainer = _epoch_program_on(config, n_seeds, data)
    compiled = epoch.lower(states, train).compile()
    predict = jax.jit(sharding.vmap_seeds(trainer.predict, in_axes=(0, None)))
    params = states.params
    predict_compiled = predict.lower(params, train["inputs"]).compile()
    compile_s = time.perf_counter() - t0

    def timed(call) -> float:
        t = time.perf_counter()
        jax.block_until_ready(call())
        return time.perf_counter() - t

    state = [states]

    def one_epoch():
        state[0], summary = compiled(state[0], train)
        return summary

    step_s = min(timed(one_epoch) for _ in range(repeats + 1)) / steps
    eval_s = min(timed(lambda: predict_compiled(state[0].params, train["inputs"])) for _ in range(repeats + 1)) / steps
    return RowCost(step_s, eval_s, compiled_flops(compiled), compiled_flops(predict_compiled), compile_s)


def train_step_runner(
    config: Config,
    n_seeds: int,
    batch: int = 32,
    seq_len: int = 200,
    psd_bins: int = 320,
    steps: int = STEPS_PER_EPOCH,
    image_hw: tuple[int, int] | None = None,
) -> Callable[[], float]:
    """A compiled, warmed-up callable that runs one epoch of `steps` vmapped training steps (the real
    `Trainer.train_epoch` scan, parameters and optimiser state donated) and returns seconds per step.

    Seeds and samples are split over the devices as in training (`sharding.training_mesh`): with
    one CPU device per core (`runtime.use_cpu_cores`), seeds or each minibatch's samples run on
    separate cores. `image_hw` is the size of the synthetic camera frames (image rows only; None:
    `synthetic.data_set`'s)."""
    epoch, first, train, _ = _epoch_program(config, n_seeds, batch, seq_len, psd_bins, steps, image_hw)
    state = [first]
    del first

    def run() -> float:
        t = time.perf_counter()
        trained, summary = epoch(state[0], train)
        jax.block_until_ready(summary)
        seconds = time.perf_counter() - t
        state[0] = trained
        return seconds / steps

    run()  # compile and warm up
    return run


def bench_train_step(
    config: Config,
    n_seeds: int,
    batch: int = 32,
    seq_len: int = 200,
    psd_bins: int = 320,
    steps: int = STEPS_PER_EPOCH,
    repeats: int = 3,
) -> dict[str, float]:
    """Best-of-`repeats` time of `steps` vmapped training steps: seconds per step and sequences/s per seed."""
    run = train_step_runner(config, n_seeds, batch=batch, seq_len=seq_len, psd_bins=psd_bins, steps=steps)
    per_step = min(run() for _ in range(repeats))
    return {"n_seeds": n_seeds, "seconds_per_step": per_step, "sequences_per_s_per_seed": batch / per_step}


def train_step_flops(config: Config, n_seeds: int, batch: int = 32, seq_len: int = 200, psd_bins: int = 320) -> float:
    """FLOPs of one training step of `n_seeds` vmapped seeds over all their devices (`xla_flops`),
    counted on an epoch of one step: XLA counts the epoch's scan body once, whatever its length."""
    epoch, state, train, _ = _epoch_program(config, n_seeds, batch, seq_len, psd_bins, steps=1)
    return xla_flops(epoch, state, train)


def _inference_program(config: Config, seq_len: int, psd_bins: int):
    """An untrained model of `config` (graphdef, parameters) and one synthetic sequence {modality: (N, ...)}."""
    cfg = dataclasses.replace(config, seq_len=seq_len)
    inputs = select(cfg, synthetic.data_set(cfg, 1, psd_bins=psd_bins))["inputs"]
    trainer = make_trainer(cfg, feature_shapes(inputs))
    params = jax.jit(trainer.init)(seed_keys([0])[0]).params
    return trainer.graphdef, params, {k: v[0] for k, v in inputs.items()}


def inference_runner(config: Config, seq_len: int = 200, psd_bins: int = 320) -> Callable[[], float]:
    """`predict_one_timer` of an untrained model of `config` on one synthetic sequence."""
    return predict_one_timer(*_inference_program(config, seq_len, psd_bins))


def inference_flops(config: Config, seq_len: int = 200, psd_bins: int = 320) -> float:
    """FLOPs of one `predict_one` call (`xla_flops`) on the sequence `inference_runner` times."""
    graphdef, params, inputs = _inference_program(config, seq_len, psd_bins)
    return compiled_flops(compile_predict_one(graphdef, params, inputs))


def bench_inference(config: Config, seq_len: int = 200, psd_bins: int = 320, repeats: int = 200) -> dict[str, float]:
    """p50 / p99 latency in ms of `predict_one` on one sequence (dropout off, result on the host)."""
    run = inference_runner(config, seq_len=seq_len, psd_bins=psd_bins)
    return stats.percentiles_ms([run() for _ in range(repeats)])


CAMERA_TARGET = 1.5  # the target: a camera row's training step costs at most 1.5x an audio row's
# The target for the paper's rotation: the rotated camera row's training step, and so its epoch (the same
# minibatches), costs at most 1.5x the same row's without the rotation.
ROTATION_TARGET = 1.5


def compare_rows(
    rows: dict[str, Config],
    *,
    reference: str,
    n_seeds: int = 5,
    psd_bins: int = 320,
    steps: int = STEPS_PER_EPOCH,
    rounds: int = 5,
    pause_s: float = 1.0,
) -> dict[str, Any]:
    """Training steps of study rows (`rows`: name -> config, each at its own batch size, N and
    camera frame size `image_size`) timed in alternating rounds in this process (`_interleave`), so
    machine load hits all alike; each row's seconds per step (median over rounds) and its ratio
    to the `reference` row: `ratio` the median of the per-round ratios, `ratio_of_medians` the
    ratio of the median times."""
    runs, built = {}, {}
    for name, cfg in rows.items():
        make = functools.partial(
            train_step_runner,
            cfg,
            n_seeds,
            batch=cfg.batch_size,
            seq_len=cfg.seq_len,
            psd_bins=psd_bins,
            steps=steps,
            image_hw=cfg.image_size,
        )
        runs[name], built[name] = _build(make, tolerate=False)
    times = {k: np.asarray(v) for k, v in _interleave(runs, rounds, pause_s).items()}
    ref = times[reference]
    return {
        "n_seeds": n_seeds,
        "steps_per_timing": steps,
        "rounds": rounds,
        "reference": reference,
        "rows": {
            name: {
                **built[name],
                "s_per_step": float(np.median(t)),
                "min_s": float(t.min()),
                "rounds": t.tolist(),
                **(
                    {}
                    if name == reference
                    else {"ratio": float(np.median(t / ref)), "ratio_of_medians": float(np.median(t) / np.median(ref))}
                ),
            }
            for name, t in times.items()
        },
    }


# The PyTorch comparison's workload: the paper's model on two microphones (320 bins) + joints.
COMPARE_CONFIG = Config.from_preset("paper", modalities=("internal", "external", "proprio"))


def _variant(compile_mode: str | None, autocast: bool = False, ensemble: str | None = None) -> str:
    """A twin variant's name in the results: "eager" or "compiled:MODE", "+bf16 autocast" under
    `torch.autocast` to bfloat16, then how several seeds train (", in sequence" or ", vmapped":
    a key of `torch_twin.ENSEMBLES`; None for one seed, a lone model)."""
    return (
        ("eager" if compile_mode is None else f"compiled:{compile_mode}")
        + (" +bf16 autocast" if autocast else "")
        + (f", {ensemble}" if ensemble else "")
    )


def _build(
    make: Callable[[], Callable[[], float]], tolerate: bool
) -> tuple[Callable[[], float] | None, dict[str, Any]]:
    """`make()` (a runner, compiled and warmed up as it is built) and its record: the seconds to
    build it and run its first calls, which hold the whole compile time, kept apart from the step
    times. With `tolerate` a failure is recorded as {"error": ...} instead of raised: a
    `torch.compile` mode that does not work on this machine is a result, not a crash."""
    t = time.perf_counter()
    try:
        run = make()
    except Exception as e:  # noqa: BLE001 (only with tolerate; re-raised otherwise)
        if not tolerate:
            raise
        lines = str(e).strip().splitlines()  # its first line: torch's compile errors run to pages
        return None, {"error": f"{type(e).__name__}: {lines[0][:300] if lines else ''}"}
    return run, {"build_and_warmup_s": time.perf_counter() - t}


def _interleave(runs: dict[str, Callable[[], Any]], rounds: int, pause_s: float) -> dict[str, list]:
    """Each round calls every runner once, `pause_s` apart, in an order reversed every other round,
    so machine load and the position after another side's run hit all sides alike."""
    out: dict[str, list] = {k: [] for k in runs}
    order = list(runs.items())
    for r in range(rounds):
        for side, run in order if r % 2 == 0 else order[::-1]:
            time.sleep(pause_s)
            out[side].append(run())
    return out


def _ours(dtype: str) -> str:
    """Our side's name in a comparison: "ours:DTYPE" (its compute dtype)."""
    return f"ours:{dtype}"


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
    compile_modes: Sequence[str] | None = None,
    dtypes: Sequence[str] = DTYPES,
) -> dict[str, Any]:
    """Our training step and inference, in each compute dtype of `dtypes`, against the PyTorch
    twin's, interleaved in one process.

    The twin runs eager and `torch.compile`d in each of `compile_modes` (default
    `torch_twin.COMPILE_MODES`), each in float32 and under `torch.autocast` to bfloat16 (its own
    mixed precision, the fair peer of our bfloat16), every variant with the fastest AdamW
    (`torch_twin.adamw_impl`); a variant that fails to build is recorded with its error and left
    out. Every program is built and warmed up first (compile time recorded apart,
    `build_and_warmup_s`); then each round times every side back to back for every seed count
    (the order reversed every other round), so machine load hits all alike. Ours trains `n` seeds
    in one vmapped program, each seed on its own minibatches; for `n` > 1 every twin variant comes
    twice, `n` models one after another and as one `torch.vmap`ped ensemble (`torch_twin.InSequence`,
    `torch_twin.Vmapped`; each seed on its own minibatch likewise). Ratios are ours (per dtype,
    under "ours") / the fastest twin variant by median time (below 1: we are faster;
    `torch_variant` names it, `torch_variants` holds every variant and our ratio to it per dtype):
    `ratio` is the median of the per-round ratios, `ratio_of_medians` the ratio of the median
    times. Inference alternates blocks of `inference_calls` single-sequence calls, fastest variant
    by p50. The build times are an upper bound for the first compiled variant and may be near zero
    for later ones of the same shapes, which reuse its graphs (torch's in-process and on-disk
    caches, as JAX's compilation cache serves ours). `pause_s` separates the sides: a step run
    right after the other side's is slower (caches and the CPU's clock still busy with it). Needs
    torch (`pip install -e ".[compare]"`; ImportError without it): the twin
    (`fabricjax.bench.torch_twin`) imports torch when called, never at module import.
    """
    from fabricjax.bench import torch_twin as twin

    torch = twin.require()
    config = config or COMPARE_CONFIG
    cfg = dataclasses.replace(config, seq_len=seq_len, batch_size=batch)
    ours = {d: dataclasses.replace(cfg, compute_dtype=d) for d in dtypes}
    mine = {_ours(d) for d in dtypes}
    variants = [
        (mode, autocast)
        for mode in (None, *(twin.COMPILE_MODES if compile_modes is None else compile_modes))
        for autocast in (False, True)
    ]
    training: dict[str, Any] = {}
    per_round: dict[int, dict[str, np.ndarray]] = {}
    setup: dict[int, dict[str, dict]] = {}
    for n in seeds:  # one seed count at a time, so only its programs hold memory
        runs, built = {}, {}
        for d, c in ours.items():
            runs[_ours(d)], built[_ours(d)] = _build(
                lambda c=c: train_step_runner(c, n, batch=batch, seq_len=seq_len, psd_bins=psd_bins, steps=steps),
                tolerate=False,
            )
        for mode, autocast in variants:
            for ensemble in twin.ENSEMBLES if n > 1 else (None,):
                make = functools.partial(
                    twin.train_step_runner,
                    cfg,
                    n_seeds=n,
                    batch=batch,
                    n_bins=psd_bins,
                    steps=steps,
                    compile_mode=mode,
                    autocast=autocast,
                    ensemble=ensemble or twin.IN_SEQUENCE,
                )
                name = _variant(mode, autocast, ensemble)
                run, built[name] = _build(make, tolerate=mode is not None or autocast or ensemble == twin.VMAPPED)
                if run is not None:
                    runs[name] = run
        per_round[n] = {k: np.asarray(v) for k, v in _interleave(runs, rounds, pause_s).items()}
        setup[n] = built
        del runs
    for n in seeds:
        t, built = per_round[n], setup[n]
        fastest = min((v for v in t if v not in mine), key=lambda v: np.median(t[v]))
        f = t[fastest]
        training[f"{n}_seed"] = {
            "ours": {
                d: {
                    "s_per_step": float(np.median(t[_ours(d)])),
                    "min_s": float(t[_ours(d)].min()),
                    "ratio": float(np.median(t[_ours(d)] / f)),
                    "ratio_of_medians": float(np.median(t[_ours(d)]) / np.median(f)),
                    "ratio_of_mins": float(t[_ours(d)].min() / f.min()),
                    "build_and_warmup_s": built[_ours(d)]["build_and_warmup_s"],
                    "rounds": t[_ours(d)].tolist(),
                    **(
                        {"per_seed_vs_1_seed": float(np.median(t[_ours(d)] / (n * per_round[1][_ours(d)])))}
                        if n > 1 and 1 in seeds
                        else {}
                    ),
                }
                for d in dtypes
            },
            "torch_s_per_step": float(np.median(f)),
            "torch_variant": fastest,
            "torch_min_s": float(f.min()),
            "torch_rounds": f.tolist(),
            "torch_variants": {
                v: {
                    **b,
                    **(
                        {
                            "s_per_step": float(np.median(t[v])),
                            "min_s": float(t[v].min()),
                            "rounds": t[v].tolist(),
                            "ratio": {d: float(np.median(t[_ours(d)] / t[v])) for d in dtypes},
                        }
                        if v in t
                        else {}
                    ),
                }
                for v, b in built.items()
                if v not in mine
            },
        }
    runs, built = {}, {}
    for d, c in ours.items():
        runs[_ours(d)], built[_ours(d)] = _build(
            lambda c=c: inference_runner(c, seq_len=seq_len, psd_bins=psd_bins), tolerate=False
        )
    for mode, autocast in variants:
        make = functools.partial(twin.inference_runner, cfg, n_bins=psd_bins, compile_mode=mode, autocast=autocast)
        run, built[_variant(mode, autocast)] = _build(make, tolerate=mode is not None or autocast)
        if run is not None:
            runs[_variant(mode, autocast)] = run
    blocks = {side: (lambda run=run: [run() for _ in range(inference_calls)]) for side, run in runs.items()}
    lat = {
        side: [s for block in v for s in block] for side, v in _interleave(blocks, inference_rounds, pause_s).items()
    }
    p = {k: stats.percentiles_ms(v) for k, v in lat.items()}
    fastest = min((v for v in p if v not in mine), key=lambda v: p[v]["p50_ms"])
    inference = {
        "ours": {
            d: {
                **p[_ours(d)],
                "ratio_p50": p[_ours(d)]["p50_ms"] / p[fastest]["p50_ms"],
                "build_and_warmup_s": built[_ours(d)]["build_and_warmup_s"],
            }
            for d in dtypes
        },
        "torch_p50_ms": p[fastest]["p50_ms"],
        "torch_p99_ms": p[fastest]["p99_ms"],
        "torch_variant": fastest,
        "torch_variants": {
            v: {
                **b,
                **(
                    {**p[v], "ratio_p50": {d: p[_ours(d)]["p50_ms"] / p[v]["p50_ms"] for d in dtypes}} if v in p else {}
                ),
            }
            for v, b in built.items()
            if v not in mine
        },
    }
    return {
        "shapes": {"batch": batch, "seq_len": seq_len, "psd_bins": psd_bins, "modalities": list(cfg.modalities)},
        "steps_per_timing": steps,
        "rounds": rounds,
        "torch_threads": torch.get_num_threads(),
        "torch_adamw": twin.adamw_impl(),
        "training": training,
        "inference": inference,
    }
