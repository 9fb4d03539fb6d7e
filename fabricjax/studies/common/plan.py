"""What a study on simulated data will cost, printed before it starts: disk and time per stage.

    simulation   the preset's missing trials: a two-cycle trial simulated on this host just now
                 (`probe`), per step, over the simulation's processes
    flow         the missing trials' frames: OpenCV's Farneback timed on the probe's frames, per
                 frame, over the feature processes
    features     the cache's bytes per step of each camera input (the audio and joint features are small)
    sequences    what the rows' loaded sequences take, and whether they go to memory-mapped files
                 (`data.MEMORY_FRACTION`)
    training     per row, seconds per training sequence, epoch and seed measured by the published
                 run of `SAMPLE_RESULTS` (the paper preset on a sample of its data), times this
                 run's sequences, epochs and seeds, plus that row's compilation; the host it was
                 measured on is named, and rows it did not run are "unknown" until the run's own
                 progress log gives their ETA

A paper-scale run takes hours on a laptop CPU: it says so before it starts, and how much disk
it will use. The simulation and flow lines are measured on this host at the start; only training
is measured elsewhere.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from pathlib import Path
from typing import Any, Sequence

import cv2

from fabricjax import archive, data, memo, presets, workspace
from fabricjax.config import Config
from fabricjax.features import flow, welch
from fabricjax.sim import dataset as sim_dataset
from fabricjax.sim.trial import simulate
from fabricjax.splits import DatasetSpec

# The published run the training line is extrapolated from (`python -m experiments.ablation
# --preset=paper_sample --seeds=5 --results=results/paper_sample`).
SAMPLE_RESULTS = Path(__file__).resolve().parents[3] / "results" / "paper_sample" / "ablation.json"
PROBE_FLOW_PAIRS = 8  # frame pairs timed per probe
PROBE_CYCLES = 2  # rubbing cycles of the probe's trial: its closing's share of the time stays small
# Config fields a row of the published sample may differ in and still give this run's rate: the
# data's own (preset, classes, step window) and where inputs are read from (the same bits)
RATE_NEUTRAL = ("preset", "n_classes", "mic_window_s", "input_source")


@dataclasses.dataclass(frozen=True)
class Stage:
    name: str
    disk_bytes: float
    seconds: float | None  # None: unknown before the run
    basis: str


def probe(dataset: DatasetSpec, images: bool) -> dict[str, float]:
    """Seconds per simulated step and per frame of OpenCV flow (one thread), on this host now."""
    one_cycle = dataclasses.replace(dataset, cycles_per_trial=PROBE_CYCLES)
    scene = sim_dataset.scene_for(one_cycle.trials()[0], one_cycle, ("audio", "proprio") + (("images",) if images else ()))
    t0 = time.perf_counter()
    trial = simulate(scene)
    out = {"simulate_s_per_step": (time.perf_counter() - t0) / len(trial.timestamps)}
    if images:
        threads = cv2.getNumThreads()
        cv2.setNumThreads(1)
        frames = trial.images[: PROBE_FLOW_PAIRS + 1]
        t0 = time.perf_counter()
        flow.farneback(frames)
        out["flow_s_per_frame"] = (time.perf_counter() - t0) / max(len(frames) - 1, 1)
        cv2.setNumThreads(threads)
    return out


def _bytes_per_step(config: Config, image_size: tuple[int, int]) -> float:
    """Bytes one step of `config`'s inputs takes, loaded (camera inputs as cached)."""
    out = 0.0
    for m in config.modalities:
        if m == "flow":
            out += 2 * math.prod(flow.pooled_shape(*image_size)) * 2  # float16
        elif m == "image":
            size = image_size if config.image_resolution == "full" else config.image_size
            out += math.prod(size) * 3 * (2 if config.image_reference == "session" else 1)  # uint8, int16 against a reference
        elif m == "proprio":
            out += 4 * archive.N_PROPRIO
        else:
            out += 4 * welch.n_bins(config.bandwidth_khz, archive.AUDIO_RATE, archive.WINDOW)
    return out


def _training(configs: Sequence[tuple[str, Config]], n_seeds: int, train_sequences: int) -> Stage:
    try:
        sample = json.loads(SAMPLE_RESULTS.read_text())
    except (OSError, ValueError):
        return Stage("training", 0, None, f"unknown before the run: no published run of the paper_sample preset ({workspace.shown(SAMPLE_RESULTS)})")
    measured = {r["name"]: r for r in sample.get("rows", [])}
    n_sample = sample["dataset"]["sequences"]["train"]
    total, missing = 0.0, []
    for name, config in configs:
        row = measured.get(name)
        if row is None or _recipe(row["config"]) != _recipe(config.to_json()):
            missing.append(name)
            continue
        compile_s = row["time"]["compile_s"]
        per_unit = (row["wall_s"] - compile_s) / (n_sample * row["config"]["epochs"] * len(row["seeds"]))
        total += compile_s + per_unit * train_sequences * config.epochs * n_seeds
    machine = sample["machine"]
    basis = (f"seconds per training sequence, epoch and seed of each row in {workspace.shown(SAMPLE_RESULTS)} "
             f"({machine.get('cpu')}, {machine.get('cores')} cores, {sample['date']}), times {train_sequences} sequences")
    if missing:
        basis += f"; rows it did not run with this recipe ({', '.join(missing)}) not counted"
    if len(missing) == len(configs):
        return Stage("training", 0, None, "unknown before the run: the published run of the paper_sample preset trained other recipes")
    return Stage("training", 0, total, basis)


def _recipe(config: dict[str, Any]) -> dict[str, Any]:
    return {k: json.dumps(v) for k, v in config.items() if k not in RATE_NEUTRAL}


def stages(preset: str, configs: Sequence[tuple[str, Config]], n_seeds: int, workdir=None) -> list[Stage]:
    """The stages of a study of `configs` rows on the simulated data of `preset` (see the module docstring)."""
    spec = presets.get(preset).dataset
    camera = {m for _, c in configs for m in c.modalities} & {"image", "flow"}
    folder = workspace.dataset_dir(preset, workdir)
    streams = ("audio", "proprio") + (("images",) if camera else ())
    scenes = [sim_dataset.scene_for(t, spec, streams) for t in spec.trials()]
    missing = [s for s in scenes if not sim_dataset.is_done(folder / sim_dataset.filename(s), s)]
    steps = sim_dataset.trial_steps(spec)
    workers = os.cpu_count() or 1
    costs = probe(spec, bool(camera)) if missing else {}
    union = dataclasses.replace(configs[0][1], modalities=tuple(sorted({m for _, c in configs for m in c.modalities})))
    out = [Stage(
        f"simulation ({len(missing)} of {len(scenes)} trials missing)", len(missing) * sim_dataset.trial_bytes(spec, bool(camera)),
        len(missing) * steps * costs.get("simulate_s_per_step", 0.0) / workers,
        f"a two-cycle trial simulated just now: {1e3 * costs['simulate_s_per_step']:.1f} ms per step, {workers} processes" if missing else "done",
    )]
    if camera:
        cameras = dataclasses.replace(union, modalities=tuple(sorted(camera)))
        out.append(Stage(
            f"optical flow and features ({len(missing)} trials' frames)", len(missing) * steps * _bytes_per_step(cameras, spec.image_size),
            len(missing) * steps * costs.get("flow_s_per_frame", 0.0) / workers if "flow" in camera else 0.0,
            f"OpenCV's Farneback on the probe's frames just now: {1e3 * costs.get('flow_s_per_frame', 0):.1f} ms per frame on one thread, "
            f"{workers} processes" if missing and "flow" in camera else "trials already simulated may have theirs cached",
        ))
    n = configs[0][1].seq_len
    per_trial = steps // n
    train_sequences = sum(per_trial for t in spec.trials() if t.day in spec.splits.train_days and t.trial < spec.train_trials_per_day - spec.splits.val_trials_per_day)
    loaded = len(scenes) * per_trial * n * _bytes_per_step(union, spec.image_size)
    to_disk = loaded > memo.memory_budget(data.MEMORY_FRACTION)
    out.append(Stage(
        "sequences", loaded if to_disk else 0, 0.0,
        f"{loaded / 1e9:.1f} GB loaded: " + ("more than half of memory, so memory-mapped files in the workspace, read a block at a time" if to_disk else "held in memory"),
    ))
    out.append(_training(configs, n_seeds, train_sequences))
    return out


def markdown(preset: str, stages_: Sequence[Stage], n_rows: int, n_seeds: int) -> str:
    known = [s.seconds for s in stages_ if s.seconds is not None]
    total = sum(known)
    lines = [
        f"Plan: {n_rows} rows x {n_seeds} seeds on preset {preset!r}: about {_duration(total)}"
        + (" and more (a stage is unknown)" if len(known) < len(stages_) else "")
        + f", {sum(s.disk_bytes for s in stages_) / 1e9:.1f} GB of disk at most",
        "",
        "| stage | disk | time | from |",
        "|---|---|---|---|",
    ]
    lines += [f"| {s.name} | {s.disk_bytes / 1e9:.1f} GB | {'unknown' if s.seconds is None else _duration(s.seconds)} | {s.basis} |" for s in stages_]
    return "\n".join(lines)


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def document(preset: str, stages_: Sequence[Stage]) -> dict[str, Any]:
    return {"preset": preset, "stages": [dataclasses.asdict(s) for s in stages_]}
