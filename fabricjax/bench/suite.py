"""Every speed benchmark in one process, side by side (`python -m experiments.bench`): `run`
writes results/bench.json and the README's table (`markdown`).

Benchmarks (names for --only):
    simulator    simulated seconds per wall second (audio + proprioception)
    welch        `welch_psd` against `scipy.signal.welch` on 4096 windows x 2048 (float32 samples)
    flow         dense Farneback flow per frame pair at 308x410 and 60x80: OpenCV on one thread and on
                 every core, the JAX reimplementation batched on JAX's devices (CPU, or an accelerator)
    input        training fed from the host (`fabricjax.training.feed`): one step's minibatches of the paper's
                 flow features (5 seeds x batch 32, N=200) gathered from memory, from disk (the
                 file's pages dropped first) and from the page cache
    extraction   cold feature extraction (audio PSDs + proprioception) of the smoke dataset and the
                 peak memory of a fresh process doing it; paper scale extrapolated linearly in steps
    training     training step of the audio + proprioception model (batch 32, N=200, 320 bins,
                 the paper's width 64 / 3 layers): ours in float32 and bfloat16 compute (`program_timing.DTYPES`)
                 for 1 and 5 vmapped seeds (--train_seeds), the PyTorch twin's for 1 seed and for 5 seeds one
                 after another ("in sequence") and torch.vmapped ("vmapped"), eager and torch.compiled, each
                 in float32 and under its bfloat16 autocast
    camera       a camera row's training step against an audio row's (target: at most 1.5x), the
                 ablation's rows on the default preset (batch 16, N=50, 30x40 frames, 5 vmapped seeds),
                 interleaved: audio (Minsound), image, and image without the rotation augmentation
    inference    one 200-step sequence, p50 / p99: ours (`predict_one` compiled ahead of time, each compute dtype) and
    the
                 twin's (eager, compiled; float32 and bfloat16 autocast)
    streaming    per-step update of `fabricjax.inference.live` (newest PSDs + model over N=200 steps)
                 on a simulated trial replayed as fast as possible
    acquisition  the 50 Hz recording loop against the simulated devices: step times, deadline misses
                 (the acquisition package's benchmark, passed in by the command: `run(acquisition=...)`)
    import       batch import (`experiments.import_manifest`) of 1000 recorded trials of 6-8 s from a rig
                 unlike the hand (one 2.2 kHz vibration channel, 7 joints, no camera); target <= 3 min on
                 2 cores (`fabricjax.importers.example_rig.bench_import`)

Ours and the twin are timed in alternating rounds in this process (`program_timing.compare_with_torch`),
so machine load hits both alike; ratios are ours / theirs for times (below 1: we are faster, the
median of the per-round ratios for training), theirs being the fastest of the twin's variants
(eager, each `torch.compile` mode; several seeds in sequence and vmapped; every variant and its
compile time in bench.json), and scipy / ours for the Welch speed-up. Training and inference
also say how close ours comes to the machine: FLOPs per step by XLA's cost analysis of the
compiled program, the GFLOP/s that makes, and its fraction of a dense matmul's GFLOP/s with
float32 and with bfloat16 operands (float32 accumulation), both measured in the same run
(`program_timing.matmul_peak`). The PyTorch twin (`fabricjax.bench.torch_twin`,
`pip install -e ".[compare]"`) is optional: without torch the comparison is skipped with a note.
Nothing here asserts a time.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import re
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Callable, Sequence

import jax
from absl import logging

from fabricjax import presets, sim, timing
from fabricjax.bench import feature_timing, input_timing, program_timing, sim_throughput, torch_twin
from fabricjax.config import Config
from fabricjax.features import welch
from fabricjax.importers import example_rig
from fabricjax.inference import live
from fabricjax.reporting import results_files
from fabricjax.sim import calibration as sim_calibration
from fabricjax.store import archive, dataset_index
from fabricjax.store.workspace import Location
from fabricjax.training import sharding, train

BENCHMARKS = (
    "simulator",
    "welch",
    "extraction",
    "flow",
    "frame_scale",
    "input",
    "training",
    "camera",
    "inference",
    "streaming",
    "acquisition",
    "import",
)
PASSED_IN = ("acquisition",)  # benchmarks of the acquisition package, which this library does not import


@dataclasses.dataclass(frozen=True)
class Workload:
    """Model and shapes of the training, inference and streaming benchmarks. The default is the
    comparison the PyTorch twin was built for: the paper's model (width 64, 3 attention layers)
    on two microphones (320 bins = 15 kHz) + joints, N=200, batch 32. Tests pass a tiny one."""

    model: Config = program_timing.COMPARE_CONFIG
    batch: int = 32
    bins: int = 320
    seeds: tuple[int, ...] = (1, 5)  # seed counts of the training benchmark; 1 must be among them

    def describe(self) -> dict:
        c = self.model
        return {
            "batch": self.batch,
            "seq_len": c.seq_len,
            "psd_bins": self.bins,
            "modalities": list(c.modalities),
            "width": c.width,
            "n_layers": c.n_layers,
            "backbone": c.backbone,
        }


# --quick's workload: a small model on short sequences, so a smoke run of the whole suite (the
# twin's torch.compile included) spends its time on compiling, not on paper-sized steps; a smoke
# check, not a measurement. The default stays the full measurement.
QUICK_WORKLOAD = Workload(
    dataclasses.replace(
        program_timing.COMPARE_CONFIG,
        width=16,
        n_heads=4,
        n_layers=1,
        ffn=32,
        audio_hidden=(32, 16),
        proprio_hidden=(16, 16),
        seq_len=24,
    ),
    batch=8,
    bins=24,
)

# A paper-preset trial: 50 rubbing cycles, ~30 s at 50 Hz (fabricjax/presets.py, preset "paper";
# acquisition/procedure.py)
PAPER_STEPS_PER_TRIAL = 1500


def _torch_twin():
    """The twin module, or the reason it cannot be used (torch not installed)."""
    try:
        torch_twin.require()
        return torch_twin, None
    except ImportError as e:
        return None, f'PyTorch comparison skipped: {e} (install with pip install -e ".[compare]")'


def bench_simulator(quick: bool) -> dict:
    return sim_throughput.bench_throughput(seconds=5.0 if quick else 30.0)


def bench_frame_scale(quick: bool) -> dict:
    """The default preset's camera data, rendered and turned into flow, at its 60x80 frames and at the
    paper's 308x410 (--quick: the smoke preset's 77x103 in its place)."""
    spec = presets.get("default").dataset
    big = presets.get("smoke").dataset.image_size if quick else archive.MINSIGHT_SIZE
    return sim_throughput.bench_frame_scale("default", sizes=(spec.image_size, big), cycles=1 if quick else 5)


def bench_welch(quick: bool) -> dict:
    return feature_timing.bench_welch(n_windows=512 if quick else 4096, repeats=3 if quick else 5)


def bench_extraction(quick: bool, workdir) -> dict:
    """In a spawned process, so its peak memory is the extraction's alone."""
    folder = sim.ensure_dataset("smoke", workdir, streams=("audio", "proprio"), progress=False)
    config = Config.from_preset("smoke", modalities=("internal", "external", "proprio"))
    # concurrent.futures: its worker is not daemonic, so the extraction's own process pool may start
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        out = pool.submit(feature_timing.bench_extraction, config, folder).result()
    steps = sum(e.n_steps for e in dataset_index.load_index(folder, workdir).entries)
    paper_steps = len(presets.get("paper").dataset.trials()) * PAPER_STEPS_PER_TRIAL
    return {
        **out,
        "dataset": "smoke",
        "steps": steps,
        "ms_per_step": 1e3 * out["cold_s"] / steps,
        "paper_scale_extrapolated_s": out["cold_s"] / steps * paper_steps,
        "paper_scale_note": f"extrapolated linearly in steps to {paper_steps} steps "
        f"({len(presets.get('paper').dataset.trials())} trials x ~{PAPER_STEPS_PER_TRIAL}), audio + "
        f"proprioception only; not measured",
    }


def _interleaved(quick: bool, w: Workload) -> dict:
    """Ours and the twin's training steps and inference timed in alternating rounds, so machine
    load hits both alike (`program_timing.compare_with_torch`)."""
    return program_timing.compare_with_torch(
        w.model,
        seeds=w.seeds,
        batch=w.batch,
        seq_len=w.model.seq_len,
        psd_bins=w.bins,
        steps=2 if quick else program_timing.STEPS_PER_EPOCH,
        rounds=2 if quick else 5,
        pause_s=0.05 if quick else 1.0,
        inference_rounds=2 if quick else 10,
        inference_calls=5 if quick else 20,
    )


def bench_training(quick: bool, w: Workload, compared: dict | None, peaks: dict) -> dict:
    """Seconds per step, 1 and 5 seeds, per compute dtype; beside the twin's fastest variant (median
    of per-round ratios) when compared; ours' FLOPs per step and their share of each matmul peak."""
    out: dict[str, Any] = {"workload": w.describe()}
    gflops = {d: p["gflop_per_s"] for d, p in peaks.items()}
    for n in w.seeds:
        ours = out[f"ours_{n}_seed"] = {}
        for d in program_timing.DTYPES:
            model = dataclasses.replace(w.model, compute_dtype=d)
            if compared is None:
                ours[d] = program_timing.bench_train_step(
                    model,
                    n,
                    batch=w.batch,
                    seq_len=model.seq_len,
                    psd_bins=w.bins,
                    steps=2 if quick else program_timing.STEPS_PER_EPOCH,
                    repeats=2 if quick else 3,
                )
            else:
                c = compared["training"][f"{n}_seed"]["ours"][d]
                ours[d] = {
                    "n_seeds": n,
                    "seconds_per_step": c["s_per_step"],
                    "sequences_per_s_per_seed": w.batch / c["s_per_step"],
                    "ratio": c["ratio"],
                }
            flops = program_timing.train_step_flops(model, n, batch=w.batch, seq_len=model.seq_len, psd_bins=w.bins)
            ours[d]["xla"] = program_timing.utilisation(flops, ours[d]["seconds_per_step"], gflops)
        if compared is not None:
            c = compared["training"][f"{n}_seed"]
            out[f"torch_{n}_seed"] = {
                "n_seeds": n,
                "variant": c["torch_variant"],
                "seconds_per_step": c["torch_s_per_step"],
                "sequences_per_s_per_seed": w.batch * n / c["torch_s_per_step"],
            }
    for n in w.seeds:
        if n > 1:  # our n vmapped seeds against n times one seed of ours (1.0: vmapping is free)
            out[f"ours_{n}_over_1_per_seed"] = {
                d: out[f"ours_{n}_seed"][d]["seconds_per_step"] / (n * out["ours_1_seed"][d]["seconds_per_step"])
                for d in program_timing.DTYPES
            }
    # How training splits each minibatch's samples over the devices: {"batch": devices}.
    out["mesh"] = dict(sharding.training_mesh(w.batch).shape)
    if compared is not None:
        out["interleaved"] = {
            k: compared[k] for k in ("rounds", "steps_per_timing", "torch_threads", "torch_adamw", "training")
        }
    return out


def camera_rows(quick: bool) -> dict[str, Config]:
    """The ablation's audio and camera rows on the default preset (--quick: a small model on short
    sequences of small frames), and the camera row without its rotation (the rotation's share)."""
    shrink = (
        dict(
            seq_len=12,
            width=16,
            n_heads=4,
            n_layers=1,
            ffn=32,
            audio_hidden=(32, 16),
            batch_size=8,
            image_size=(12, 16),
        )
        if quick
        else {}
    )
    audio = Config.from_preset("default", modalities=("internal",), **shrink)
    camera = Config.from_preset("default", modalities=("image",), **shrink)
    return {"audio": audio, "camera": camera, "camera_unrotated": dataclasses.replace(camera, augment_rotation=False)}


def bench_camera(quick: bool) -> dict:
    """A camera row's 5-seed training step against an audio row's, interleaved (`program_timing.compare_rows`),
    with the target for the ratio (camera / audio <= `program_timing.CAMERA_TARGET`)."""
    rows = camera_rows(quick)
    bins = 24 if quick else welch.n_bins(rows["audio"].bandwidth_khz)
    out = program_timing.compare_rows(
        rows,
        reference="audio",
        psd_bins=bins,
        steps=2 if quick else program_timing.STEPS_PER_EPOCH,
        rounds=2 if quick else 5,
        pause_s=0.05 if quick else 1.0,
    )
    c = rows["camera"]
    ratio = out["rows"]["camera"]["ratio"]
    rotation = out["rows"]["camera"]["s_per_step"] / out["rows"]["camera_unrotated"]["s_per_step"]
    return {
        **out,
        "workload": {
            "preset": c.preset,
            "batch": c.batch_size,
            "seq_len": c.seq_len,
            "image_size": list(c.image_size),
            "psd_bins": bins,
            "cnn_features": list(c.cnn_features),
            "width": c.width,
            "n_layers": c.n_layers,
        },
        "target_ratio": program_timing.CAMERA_TARGET,
        "meets_target": ratio <= program_timing.CAMERA_TARGET,
        # the rotation's cost: rotated / unrotated step, the ratio of their epochs (the same minibatches)
        "rotation_ratio": rotation,
        "rotation_target_ratio": program_timing.ROTATION_TARGET,
        "rotation_meets_target": rotation <= program_timing.ROTATION_TARGET,
    }


def bench_inference(quick: bool, w: Workload, compared: dict | None, peaks: dict) -> dict:
    """p50 / p99 of one sequence per compute dtype, beside the twin's fastest variant when compared."""
    out: dict[str, Any] = {"workload": w.describe(), "ours": {}}
    gflops = {d: p["gflop_per_s"] for d, p in peaks.items()}
    for d in program_timing.DTYPES:
        model = dataclasses.replace(w.model, compute_dtype=d)
        if compared is None:
            out["ours"][d] = program_timing.bench_inference(
                model, seq_len=model.seq_len, psd_bins=w.bins, repeats=30 if quick else 200
            )
        else:
            c = compared["inference"]["ours"][d]
            out["ours"][d] = {"p50_ms": c["p50_ms"], "p99_ms": c["p99_ms"], "ratio_p50": c["ratio_p50"]}
        # At p50: the typical call's rate (p99 is the machine's hiccups, not the program's work). One
        # sequence runs on one device, so its share is of a peak that every device makes together.
        flops = program_timing.inference_flops(model, seq_len=model.seq_len, psd_bins=w.bins)
        out["ours"][d]["xla"] = program_timing.utilisation(flops, out["ours"][d]["p50_ms"] / 1e3, gflops)
    if compared is not None:
        c = compared["inference"]
        out["torch"] = {"variant": c["torch_variant"], "p50_ms": c["torch_p50_ms"], "p99_ms": c["torch_p99_ms"]}
        out["interleaved"] = {
            "torch_variants": c["torch_variants"],
            "build_and_warmup_s": {d: v["build_and_warmup_s"] for d, v in c["ours"].items()},
        }
    return out


def bench_streaming(quick: bool, w: Workload) -> dict:
    """Untrained weights (latency does not depend on them) on a simulated trial longer than N.

    The window's PSD bins follow the model's bandwidth (320 bins at the default 15 kHz)."""
    n = w.model.seq_len
    cycles = max(2, round((n + (50 if quick else 250)) / (50 / sim_calibration.CYCLE_HZ)))  # ~N + 1 or 5 s of rubbing
    trial = sim.simulate(sim.Scene(12, cycles=cycles, streams=("audio", "proprio")))
    shapes = {
        m: (archive.N_PROPRIO,) if m == "proprio" else (welch.n_bins(w.model.bandwidth_khz),)
        for m in w.model.modalities
    }
    trainer = train.make_trainer(w.model, shapes)
    params = jax.jit(trainer.init)(jax.random.PRNGKey(0)).params
    out = live.replay(live.Streamer(trainer.graphdef, params, w.model), trial, realtime=False)
    keep = ("steps", "window_steps", "decided_steps", "latency_p50_ms", "latency_p99_ms", "latency_max_ms")
    return {k: out[k] for k in keep} | {
        "workload": w.describe(),
        "target_p99_ms": 20.0,
        "meets_target": out["latency_p99_ms"] <= 20.0,
    }


def run(
    *,
    only: Sequence[str] | None = None,
    quick: bool = False,
    workload: Workload = Workload(),
    out: Callable[[str], None] = print,
    acquisition: Callable[..., dict] | None = None,
    where: Location = Location(),
) -> dict[str, Any]:
    """Run the chosen benchmarks (all by default) in order; write results/bench.json and bench.md.

    `acquisition` is the acquisition package's benchmark of its recording loop
    (`bench_acquisition(seconds=...)`), which this library does not import: without it its entry is
    left out of the default set, and asking for it is an error."""
    given = {"acquisition": acquisition}
    chosen = list(only) if only else [b for b in BENCHMARKS if b not in PASSED_IN or given[b] is not None]
    unknown = [b for b in chosen if b not in BENCHMARKS]
    if unknown:
        raise ValueError(f"unknown benchmarks {unknown}; choose from {BENCHMARKS}")
    for b in PASSED_IN:
        if b in chosen and given[b] is None:
            raise ValueError(f"the {b} benchmark needs its function: run(..., acquisition=bench_acquisition)")
    twin, note = (None, None)
    if {"training", "inference"} & set(chosen):
        twin, note = _torch_twin()
        if note:
            out(note)
    compared: dict[str, Any] = {}
    peak: dict[str, Any] = {}

    def matmul_peak():  # measured once per operand dtype, in this process, for the training and the inference entry
        if not peak:
            peak.update(
                {d: program_timing.matmul_peak(repeats=2 if quick else 5, dtype=d) for d in program_timing.DTYPES}
            )
        return peak

    def comparison():  # one interleaved run serves both the training and the inference entry
        if twin is None:
            return None
        if not compared:
            compared.update(_interleaved(quick, workload))
        return compared

    jobs = {
        "simulator": lambda: bench_simulator(quick),
        "welch": lambda: bench_welch(quick),
        "extraction": lambda: bench_extraction(quick, where.workdir),
        "flow": lambda: timing.bench_flow(batch=4 if quick else 8, repeats=1 if quick else 3),
        "frame_scale": lambda: bench_frame_scale(quick),
        "input": lambda: input_timing.bench_input(n_sequences=24 if quick else 96, steps=1 if quick else 3),
        "training": lambda: bench_training(quick, workload, comparison(), matmul_peak()),
        "camera": lambda: bench_camera(quick),
        "inference": lambda: bench_inference(quick, workload, comparison(), matmul_peak()),
        "streaming": lambda: bench_streaming(quick, workload),
        "acquisition": lambda: acquisition(seconds=3.0 if quick else 10.0),
        "import": lambda: example_rig.bench_import(trials=100 if quick else 1000),
    }
    doc = results_files.header(
        "bench", module=__name__, command=where.command, quick=quick, torch=_torch_version(twin), benchmarks={}
    )
    if note:
        doc["torch_note"] = note
    for name in (b for b in BENCHMARKS if b in chosen):
        logging.info("bench: %s ...", name)
        t = time.perf_counter()
        doc["benchmarks"][name] = jobs[name]()
        logging.info("bench: %s done in %.1f s", name, time.perf_counter() - t)
    if peak:
        doc["matmul_peak"] = peak
    out(markdown(doc))
    return results_files.write(where.results_dir(), doc, markdown)


def _torch_version(twin) -> str | None:
    return None if twin is None else twin.require().__version__


def markdown(doc: dict[str, Any]) -> str:
    """The README table: one row per measurement, ours beside the reference where there is one."""
    b, m = doc["benchmarks"], doc["machine"]
    rows = []
    variants = []  # every twin variant: its time, our ratio to it, its build + compile time
    if "training" in b:
        t = b["training"]
        for n in sorted(int(hit.group(1)) for k in t if (hit := re.fullmatch(r"ours_(\d+)_seed", k))):
            theirs = t.get(f"torch_{n}_seed", {})
            mesh = t.get("mesh", {}).get(str(n), {})
            split = ", ".join(f"{k} over {v} devices" for k, v in mesh.items() if v > 1)
            secs = theirs.get("seconds_per_step")
            for dtype, ours in t[f"ours_{n}_seed"].items():
                what = (
                    f"training step, {n} seed"
                    + (("s vmapped" if n > 1 else "") + (f", {split}" if split else ""))
                    + (f", {dtype} (batch {t['workload']['batch']}, N={t['workload']['seq_len']})")
                )
                rows.append(
                    [
                        what,
                        f"{ours['seconds_per_step'] * 1e3:.0f} ms",
                        f"{theirs['variant']} {secs * 1e3:.0f} ms" if secs else "n/a",
                        _ratio(ours.get("ratio")),
                        *_machine(ours.get("xla")),
                    ]
                )
            for name, v in (
                t.get("interleaved", {}).get("training", {}).get(f"{n}_seed", {}).get("torch_variants", {}).items()
            ):
                variants.append(
                    [
                        f"training, {n} seed" + ("s" if n > 1 else ""),
                        name,
                        _ms(v.get("s_per_step") and v["s_per_step"] * 1e3, 0),
                        _ratios(v.get("ratio")),
                        _built(v),
                    ]
                )
    if "camera" in b:
        c = b["camera"]
        r, w = c["rows"], c["workload"]
        rows.append(
            [
                f"camera row's training step, {c['n_seeds']} seeds vmapped ({w['preset']} preset: batch "
                f"{w['batch']}, N={w['seq_len']}, "
                f"{w['image_size'][0]}x{w['image_size'][1]} frames; without rotation "
                f"{r['camera_unrotated']['s_per_step'] * 1e3:.0f} ms)",
                f"{r['camera']['s_per_step'] * 1e3:.0f} ms",
                f"audio row {r['audio']['s_per_step'] * 1e3:.0f} ms; target ratio <= {c['target_ratio']:g}",
                _ratio(r["camera"]["ratio"]),
            ]
        )
        rows.append(
            [
                "the same camera row's epoch with the paper's rotation, against without it (the same minibatches)",
                f"{r['camera']['s_per_step'] * 1e3:.0f} ms per step",
                f"unrotated {r['camera_unrotated']['s_per_step'] * 1e3:.0f} ms; target ratio <= "
                f"{c['rotation_target_ratio']:g}",
                _ratio(c["rotation_ratio"]),
            ]
        )
    if "inference" in b:
        i = b["inference"]
        theirs = i.get("torch")
        for dtype, ours in i["ours"].items():
            rows.append(
                [
                    f"inference, one {i['workload']['seq_len']}-step sequence, {dtype}, p50 / p99",
                    f"{ours['p50_ms']:.2f} / {ours['p99_ms']:.2f} ms",
                    f"{theirs['variant']} {theirs['p50_ms']:.2f} / {theirs['p99_ms']:.2f} ms" if theirs else "n/a",
                    _ratio(ours.get("ratio_p50")),
                    *_machine(ours.get("xla")),
                ]
            )
        for name, v in i.get("interleaved", {}).get("torch_variants", {}).items():
            times = f"{v['p50_ms']:.2f} / {v['p99_ms']:.2f} ms" if "p50_ms" in v else "n/a"
            variants.append(["inference, p50 / p99", name, times, _ratios(v.get("ratio_p50")), _built(v)])
    if "streaming" in b:
        s = b["streaming"]
        rows.append(
            [
                f"streaming update per step (N={s['workload']['seq_len']}), p50 / p99",
                f"{s['latency_p50_ms']:.2f} / {s['latency_p99_ms']:.2f} ms",
                "target p99 <= 20 ms",
                "",
            ]
        )
    if "welch" in b:
        w = b["welch"]
        rows.append(
            [
                f"Welch PSD, {w['n_windows']} windows x 2048",
                f"{w['welch_psd_s'] * 1e3:.1f} ms",
                f"scipy {w['scipy_welch_s'] * 1e3:.1f} ms",
                f"{w['speedup_vs_scipy']:.1f}x faster",
            ]
        )
    if "simulator" in b:
        s = b["simulator"]
        rows.append(["scene simulator (audio + joints)", f"{s['realtime_factor']:.1f}x real time", "", ""])
    if "extraction" in b:
        e = b["extraction"]
        rows.append(
            [
                f"feature extraction, {e['dataset']} dataset ({e['steps']} steps)",
                f"{e['cold_s']:.1f} s, peak {e['peak_rss_mb']:.0f} MB",
                f"paper scale ~{e['paper_scale_extrapolated_s'] / 60:.0f} min (extrapolated)",
                "",
            ]
        )
    if "flow" in b:
        f = b["flow"]
        for size, v in f["sizes"].items():
            rows.append(
                [
                    f"optical flow (Farneback) per frame pair, {size}: JAX on {f['jax_devices']} "
                    f"{f['device']} device(s), batch {f['batch']}",
                    f"{v['jax_s'] * 1e3:.1f} ms",
                    f"OpenCV 1 thread {v['opencv_1_thread_s'] * 1e3:.1f} ms, {f['opencv_threads']} threads "
                    f"{v['opencv_all_cores_s'] * 1e3:.1f} ms",
                    _ratio(v["jax_s"] / min(v["opencv_1_thread_s"], v["opencv_all_cores_s"])),
                ]
            )
    if "frame_scale" in b:
        f = b["frame_scale"]
        (small, s), (big, g) = f["sizes"].items()
        rows.append(
            [
                f"the {f['preset']} preset's camera data at {big} against {small}: {f['trials']} trials of "
                f"{f['frames_per_trial']} frames rendered and turned into optical flow, one trial per core on "
                f"{f['cores']} cores",
                _camera_data(g),
                f"{small} {_camera_data(s)}",
                _ratio(g["preset_s"] / s["preset_s"]),
            ]
        )
    if "input" in b:
        i = b["input"]
        src = i["sources"]
        rows.append(
            [
                f"training fed from the host: one step's minibatches of paper flow features ({i['n_seeds']} "
                f"seeds x {i['batch']}, {i['step_mb']:.0f} MB)",
                f"disk {src['disk_cold']['s_per_step'] * 1e3:.0f} ms ({src['disk_cold']['mb_per_s']:.0f} "
                f"MB/s), page cache {src['disk_warm']['s_per_step'] * 1e3:.0f} ms",
                f"memory {src['memory']['s_per_step'] * 1e3:.0f} ms ({src['memory']['mb_per_s']:.0f} MB/s)",
                _ratio(src["disk_cold"]["s_per_step"] / src["memory"]["s_per_step"]),
            ]
        )
    if "acquisition" in b:
        a = b["acquisition"]
        rows.append(
            [
                "acquisition loop, 50 Hz step p50 / p99",
                f"{a['p50_ms']:.1f} / {a['p99_ms']:.1f} ms",
                f"{a['missed_deadlines']} of {a['steps']} deadlines missed",
                "",
            ]
        )
    if "import" in b:
        i = b["import"]
        rows.append(
            [
                f"batch import, {i['trials']} trials of "
                f"{i['seconds_per_trial'][0]:g}-{i['seconds_per_trial'][1]:g} s ({i['rig']})",
                f"{i['wall_s']:.0f} s ({i['ms_per_trial']:.0f} ms per trial)",
                f"target <= {i['target_s']:.0f} s",
                "",
            ]
        )
    env = "".join(f"{k}={v} " for k, v in m.get("env", {}).items())
    written = f" ({doc['code']}, {doc['date']})" if "code" in doc else ""
    head = (
        f"Measured by `{env}{doc['command']}`{written} on {m['cpu']} ({m['cores']} cores), JAX {m['jax']}"
        + (f", PyTorch {doc['torch']}" if doc["torch"] else "")
        + (" (--quick sizes)" if doc["quick"] else "")
        + (
            ". Ratio: ours / the fastest PyTorch variant's time (named in the reference column)."
            if doc["torch"]
            else "."
        )
    )
    if "matmul_peak" in doc:
        peaks = doc["matmul_peak"]
        p = next(iter(peaks.values()))
        head += (
            f" Rows name our compute dtype (`compute_dtype`: matrix products' inputs, float32 accumulation). "
            f"GFLOP: XLA's cost analysis of "
            f"our compiled step or call; % peak: its GFLOP/s over a {p['n']}x{p['n']} matmul's with "
            + " and ".join(f"{d} operands ({v['gflop_per_s']:.1f} GFLOP/s)" for d, v in peaks.items())
            + f", float32 accumulation, on the same {p['devices']} device{'s' if p['devices'] > 1 else ''}, "
            f"measured in this run."
        )
    cols = [
        "benchmark",
        "fabricjax",
        "reference",
        "ratio",
        "GFLOP",
        "GFLOP/s (% peak: " + " / ".join(doc.get("matmul_peak", {})) + ")",
    ]
    text = head + "\n\n" + results_files.markdown_table(cols, [r + [""] * (len(cols) - len(r)) for r in rows])
    if variants:
        adamw = b.get("training", {}).get("interleaved", {}).get("torch_adamw")
        text += (
            "\nEvery PyTorch variant"
            + (f" (AdamW {adamw})" if adamw else "")
            + "; ratio: ours / its time, per our compute dtype; build + "
            "compile: seconds to build it and run its first, compiling calls, not in its times.\n\n"
            + results_files.markdown_table(
                ["workload", "PyTorch variant", "time", "ratio", "build + compile"], variants
            )
        )
    return text


def _machine(xla: dict | None) -> list[str]:
    """The GFLOP and GFLOP/s (% of each matmul peak) cells of a row."""
    if xla is None:
        return ["", ""]
    shares = " / ".join(f"{100 * f:.0f} %" for f in xla["fraction_of_peak"].values())
    return [f"{xla['flops_per_step'] / 1e9:.3g}", f"{xla['gflop_per_s']:.3g} ({shares})"]


def _camera_data(size: dict) -> str:
    """A preset's camera data at one frame size: hours on its cores, and seconds per trial."""
    per_trial = size["render_s_per_trial"] + size["flow_s_per_trial"]
    return f"{size['preset_s'] / 3600:.2f} h ({per_trial:.0f} s per trial)"


def _built(variant: dict) -> str:
    """A twin variant's build + compile seconds, or why it failed."""
    return f"failed: {variant['error']}" if "error" in variant else f"{variant['build_and_warmup_s']:.1f} s"


def _ms(x, digits: int) -> str:
    return "n/a" if x is None else f"{x:.{digits}f} ms"


def _ratio(r) -> str:
    return "" if r is None else f"{r:.2f}"


def _ratios(by_dtype: dict | None) -> str:
    """Our ratios to one twin variant, one per compute dtype."""
    return "" if by_dtype is None else ", ".join(f"{d} {r:.2f}" for d, r in by_dtype.items())
