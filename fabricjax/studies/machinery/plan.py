"""What a study on simulated data will cost, printed before it starts: disk and time per stage.

    simulation   the preset's missing trials: a short trial simulated on this host just now
                 (`probe`), per step, over the simulation's processes
    camera       the missing trials' frames: each camera feature (optical flow, downsampled frames)
      features   timed on the probe's frames, per frame, over the feature processes; the cache's
                 bytes per step (the audio and joint features are small)
    sequences    what the rows' loaded sequences take, and whether they go to memory-mapped files
                 (`data.MEMORY_FRACTION`)
    training     per row, its training step and validation minibatch compiled and timed on this
                 host just now, on noise of the data's per-step shapes and dtypes, times its
                 epochs, splits and grid points, plus its compilation; with its FLOPs per epoch
                 and the share of this host's matmul peak its step reaches

A paper-scale run takes hours on a laptop CPU: it says so before it starts, and how much disk
it will use. Every line is measured on this host at the start.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import shutil
import tempfile
import time
import types
from pathlib import Path
from typing import Any, Mapping, Sequence

import cv2
from tqdm import tqdm

from fabricjax import catalog, host_arrays, memo, presets
from fabricjax.bench import program_timing
from fabricjax.config import CAMERA_MODALITIES, RATE_NEUTRAL_FIELDS, Config
from fabricjax.reporting import results_files
from fabricjax.sequences import data
from fabricjax.sim import dataset as sim_dataset
from fabricjax.sim.trial import simulate
from fabricjax.store import archive, splits, workspace
from fabricjax.store.disk import size
from fabricjax.store.splits import DatasetSpec
from fabricjax.studies.machinery import documents, loading, recipe
from fabricjax.training import feed
from fabricjax.training.trainer import steps_per_epoch

PROBE_FRAMES = 16  # frames each camera feature is timed on (two of flow's chunks)
PROBE_CYCLES = 2  # rubbing cycles of the probe's trial: its closing's share of the time stays small
# Config fields a published row may differ in and still give this run's seconds per sequence, epoch
# and seed, as each field's metadata says (`config.RATE_NEUTRAL_FIELDS`): the data's own (preset,
# classes, step window, band, holdouts), where inputs are read from (the same bits), the recipe (the
# width's share of the time is small beside the inputs' encoders) and the fusion's normalisation (a
# rescale or a LayerNorm of each step's features: little of a step's work)
RATE_NEUTRAL = RATE_NEUTRAL_FIELDS


@dataclasses.dataclass(frozen=True)
class Stage:
    """One line of the plan: what a stage of the run takes on disk and in time, and from what."""

    name: str
    disk_bytes: float
    seconds: float | None  # None: unknown before the run
    basis: str
    source: str | None = None  # the published run a training stage's rate comes from, said once under the table


def probe(dataset: DatasetSpec, config: Config) -> dict[str, float]:
    """Seconds per simulated step ("simulate") and per frame of each camera feature of `config`
    (its name: flow with OpenCV on one thread, sparsified and pooled; frames downsampled), on this
    host now: a `PROBE_CYCLES` trial simulated and written as a worker does after its first trial
    (whose caches serve every later one), its features computed once to compile, then timed."""
    camera = [m for m in config.modalities if m in CAMERA_MODALITIES]
    cycles = dataclasses.replace(dataset, cycles_per_trial=PROBE_CYCLES)
    scene = sim_dataset.scene_for(cycles.trials()[0], cycles, loading.simulated_streams(config.modalities))
    # a worker's first trial fills its caches (rooms, textures, the camera's views) for every later one
    simulate(scene)
    with tempfile.TemporaryDirectory() as scratch:
        t0 = time.perf_counter()
        trial = simulate(scene)
        archive.write_archive(Path(scratch) / sim_dataset.filename(scene), trial)  # deflating is part of the cost
        out = {"simulate": (time.perf_counter() - t0) / len(trial.timestamps)}
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # a feature process's one thread (`cache`)
    try:
        features = data.features_for(config)  # camera features: the microphones' step window is no part of them
        for m in camera:
            feature = features[m]
            frames = lambda n: types.SimpleNamespace(images=trial.images[:n], reference=trial.reference)  # noqa: E731
            feature.compute(frames(PROBE_FRAMES))  # compiles
            t0 = time.perf_counter()
            feature.compute(frames(PROBE_FRAMES))
            out[feature.name] = (time.perf_counter() - t0) / PROBE_FRAMES
    finally:
        cv2.setNumThreads(threads)
    return out


def _bytes_per_step(config: Config, image_size: tuple[int, int]) -> float:
    """Bytes one step of `config`'s inputs takes, loaded (camera inputs as cached), as each input's
    feature says (`Feature.step_bytes`) for frames of `image_size` and the config's band."""
    return float(sum(f.step_bytes(image_size, config.bandwidth_khz) for f in data.features_for(config).values()))


def training(
    configs: Sequence[tuple[str, Config]],
    n_seeds: int,
    sizes: Mapping[str, int],
    arrays: Mapping[str, tuple[tuple[int, ...], Any]],
) -> list[Stage]:
    """One stage per row, timed on this host now: the row's training step and validation
    minibatch, compiled and run a few times on inputs of the data's per-step `arrays` ({modality:
    (shape, dtype)}, `program_timing.row_cost`), times its epochs on `sizes` ({split: sequences}): its grid points
    (`recipe.points`) x (its compilation + the cap of its epochs (`loading.epochs_for`) x (its
    optimiser steps + a validation pass) + the last evaluation of every split but training's). With
    early stopping a seed may end sooner: the cap is what the plan counts, and says. Each stage
    also says its FLOPs per epoch (XLA's count) and the share of this host's matmul peak its step
    reaches (`program_timing.matmul_peak`). Rows of the same config are timed once."""
    n_train = sizes.get("train", 0)
    costs: dict[str, program_timing.RowCost] = {}
    keys = [json.dumps(c.to_json(), sort_keys=True) for _, c in configs]
    distinct = {k: c for k, (_, c) in zip(keys, configs)}
    with tqdm(total=len(distinct), desc="timing each row's training step on this host", unit="row", leave=False) as bar:
        for key, config in distinct.items():
            costs[key] = program_timing.row_cost(config, n_seeds, {m: arrays[m] for m in config.modalities})
            bar.update(1)
    peak = host_peak_flops() if configs else 0.0
    out = []
    for key, (name, config) in zip(keys, configs):
        cost = costs[key]
        points = recipe.points(config)
        epochs = loading.epochs_for(config, config.train_steps, n_train) if config.train_steps else config.epochs
        steps = steps_per_epoch(config.batch_size, max(n_train, 1))
        batches = lambda n: host_arrays.whole_minibatches(n, config.batch_size) // config.batch_size  # noqa: E731
        val = batches(sizes.get("val", 0))
        at_end = sum(batches(n) for split, n in sizes.items() if split != "train")
        per_epoch = steps * cost.s_per_step + val * cost.s_per_eval_batch
        seconds = len(points) * (cost.compile_s + epochs * per_epoch + at_end * cost.s_per_eval_batch)
        flops = steps * cost.flops_per_step + val * cost.flops_per_eval_batch
        grid = f"{len(points)} grid points x " if len(points) > 1 else ""
        early = " (early stopping may end sooner)" if config.patience or config.patience_steps else ""
        out.append(
            Stage(
                f"training {name}",
                0,
                seconds,
                f"{grid}at most {epochs} epochs{early} of {n_train} sequences x {n_seeds} seeds: a step "
                f"{1e3 * cost.s_per_step:.0f} ms, compiling {cost.compile_s:.0f} s; {flops / 1e9:.0f} GFLOP "
                f"per epoch, the step at {100 * cost.flops_per_step / cost.s_per_step / peak:.0f} % of the "
                "float32 matmul peak",
                "each row's step, timed on this host just now",
            )
        )
    return out


@functools.cache
def host_peak_flops() -> float:
    """This host's practical float32 matmul peak [FLOP/s] over its devices (`program_timing.matmul_peak`),
    measured once per process."""
    return program_timing.matmul_peak(repeats=2)["gflop_per_s"] * 1e9


def rate_key(config: dict[str, Any]) -> str:
    """What decides a row's seconds per sequence, epoch and seed besides the host: its inputs and
    model; not its data's size and classes, nor its recipe (`RATE_NEUTRAL`)."""
    return json.dumps({k: v for k, v in sorted(config.items()) if k not in RATE_NEUTRAL})


def rates(doc: dict[str, Any]) -> dict[str, dict[str, float]]:
    """Per row of a training study's results document (keyed by `rate_key`): its seconds per
    training sequence, epoch run and seed, and its compilation per grid point; what `training`
    scales a later run's rows by. An epoch run is one the vmapped program went through (until
    every seed had stopped), summed over the row's grid points."""
    n_train = doc["dataset"]["sequences"]["train"]
    out = {}
    for row in doc["rows"]:
        grid = (row.get("recipe") or {}).get("grid") or [{"epochs_trained": [row["config"]["epochs"]]}]
        epochs_run = sum(max(p["epochs_trained"]) for p in grid)
        compile_s = row["time"].get("compile_s", 0.0)
        units = n_train * epochs_run * len(row["seeds"])
        out[rate_key(row["config"])] = {
            "per_unit_s": max(row["wall_s"] - compile_s, 0.0) / max(units, 1),
            "compile_s": compile_s / len(grid),
            "epochs_run": epochs_run / len(grid),
            "epochs_cap": row["config"]["epochs"],
        }
    return out


def stages(preset: str, configs: Sequence[tuple[str, Config]], n_seeds: int, workdir=None) -> list[Stage]:
    """The stages of a study of `configs` rows on the simulated data of `preset` (see the module docstring)."""
    spec = presets.get(preset).dataset
    modalities = loading.union_modalities([c for _, c in configs])
    camera = set(modalities) & set(CAMERA_MODALITIES)
    folder = workspace.dataset_dir(preset, workdir)
    streams = loading.simulated_streams(modalities)
    scenes = [sim_dataset.scene_for(t, spec, streams) for t in spec.trials()]
    missing = [s for s in scenes if not sim_dataset.is_done(folder / sim_dataset.filename(s), s)]
    steps = sim_dataset.trial_steps(spec)
    workers = os.cpu_count() or 1
    union = dataclasses.replace(configs[0][1], modalities=modalities)
    costs = probe(spec, union) if missing else {}
    per_frame = sum(v for k, v in costs.items() if k != "simulate")
    out = [
        Stage(
            f"simulation ({len(missing)} of {len(scenes)} trials missing)",
            len(missing) * sim_dataset.trial_bytes(spec, bool(camera)),
            len(missing) * steps * costs.get("simulate", 0.0) / workers,
            f"a {PROBE_CYCLES}-cycle trial simulated and written just now: {1e3 * costs['simulate']:.1f} ms per step, "
            f"{workers} processes"
            if missing
            else "done",
        )
    ]
    if camera:
        cameras = dataclasses.replace(union, modalities=tuple(sorted(camera)))
        timed = ", ".join(f"{k} {1e3 * v:.1f} ms" for k, v in costs.items() if k != "simulate")
        out.append(
            Stage(
                f"camera features ({len(missing)} trials' frames)",
                len(missing) * steps * _bytes_per_step(cameras, spec.image_size),
                len(missing) * steps * per_frame / workers,
                f"per frame on one thread just now ({timed}; flow by {union.flow_method}), {workers} processes"
                if missing
                else "trials already simulated may have theirs cached",
            )
        )
    n = configs[0][1].seq_len
    per_trial = steps // n
    exclude = configs[0][1].exclude_fabrics
    sizes: dict[str, int] = {}  # the sequences each split will hold (`splits`, `data.split_of`)
    classes = 1 + max(f for f in spec.fabrics if f not in catalog.NEW_FABRICS)  # `data.classes_of`'s on these trials
    for meta, role in splits.dataset_roles(spec):
        split = data.split_of({**meta, "label": archive.fabric_or_class(meta)}, role, exclude, classes)
        if split is not None:
            sizes[split] = sizes.get(split, 0) + per_trial
    per_sequence = n * _bytes_per_step(union, spec.image_size)
    loaded = len(scenes) * per_trial * per_sequence
    to_disk = loaded > memo.memory_budget(data.MEMORY_FRACTION)
    # held in memory, Minsight frames are held twice: as loaded, and as training's rows (`inputs.training_layout`)
    frames = dataclasses.replace(union, modalities=("image",)) if "image" in union.modalities else None
    rows = len(scenes) * per_trial * n * _bytes_per_step(frames, spec.image_size) if frames else 0.0
    peak = feed.host_bytes(int(per_sequence), union.batch_size, n_seeds) if to_disk else loaded + rows
    out.append(
        Stage(
            "sequences",
            loaded if to_disk else 0,
            0.0,
            f"{size(loaded)} loaded: "
            + (
                "more than half of memory, so memory-mapped files in the workspace, read a block at a time"
                if to_disk
                else "held in memory"
            )
            + f"; peak host memory for training inputs {size(peak)}"
            + (" (Minsight frames a second time, as training's rows)" if rows and not to_disk else ""),
        )
    )
    features = data.features_for(union)
    arrays = {m: features[m].step_array(spec.image_size, union.bandwidth_khz) for m in union.modalities}
    return out + training(configs, n_seeds, sizes, arrays)


def markdown(preset: str, stages_: Sequence[Stage], n_rows: int, n_seeds: int, free_bytes: float) -> str:
    known = [s.seconds for s in stages_ if s.seconds is not None]
    need = sum(s.disk_bytes for s in stages_)
    lines = [
        f"Plan: {n_rows} rows x {n_seeds} seeds on preset {preset!r}: "
        + (
            f"about {_duration(sum(known))}"
            if len(known) == len(stages_)
            else f"{len(stages_) - len(known)} of {len(stages_)} stages unknown before the run (below), the "
            f"others about {_duration(sum(known))}"
        )
        + f", {size(need)} of disk at most ({size(free_bytes)} free"
        + ("; it does not fit: free disk space or give --workdir on a larger disk" if need > free_bytes else "")
        + ")",
        "",
        "| stage | disk | time | from |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {s.name} | {size(s.disk_bytes)} | {'unknown' if s.seconds is None else _duration(s.seconds)} | {s.basis} |"
        for s in stages_
    ]
    sources = list(dict.fromkeys(s.source for s in stages_ if s.source))
    if sources:
        lines += ["", "Training rates as measured by " + "; ".join(sources) + "."]
    return "\n".join(lines)


def free_disk(workdir=None) -> int:
    """Free bytes on the disk the workspace is on (its nearest existing folder)."""
    folder = workspace.root(workdir).absolute()
    while not folder.exists():
        folder = folder.parent
    return shutil.disk_usage(folder).free


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def write(
    where: workspace.Location, study: str, preset: str, stages_: Sequence[Stage], n_rows: int, n_seeds: int
) -> dict[str, Any]:
    """results/plan.md and plan.json: the plan, with the command, code, date and host it was made on."""
    doc = {
        **documents.header("plan", module=__name__, command=where.command, preset=preset),
        "of_study": study,
        "rows": n_rows,
        "n_seeds": n_seeds,
        "stages": [dataclasses.asdict(s) for s in stages_],
        "total_s": sum(s.seconds or 0.0 for s in stages_),
        "free_bytes": free_disk(where.workdir),
    }
    spent = "seconds: the plan simulates one trial and computes its features to measure sizes"
    return results_files.write(
        where.results_dir(),
        doc,
        lambda d: (
            f"# What {d['of_study']} needs on preset {d['preset']}\n\n"
            + documents.header_markdown(d, time=spent)
            + "\n"
            + markdown(preset, stages_, n_rows, n_seeds, d["free_bytes"])
            + "\n"
        ),
    )
