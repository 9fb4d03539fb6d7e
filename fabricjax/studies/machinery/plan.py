"""What a study on simulated data will cost, printed before it starts: disk and time per stage.

    simulation   the preset's missing trials: a short trial simulated on this host just now
                 (`probe`), per step, over the simulation's processes
    camera       the missing trials' frames: each camera feature (optical flow, downsampled frames)
      features   timed on the probe's frames, per frame, over the feature processes; the cache's
                 bytes per step (the audio and joint features are small)
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
import os
import shutil
import tempfile
import time
import types
from pathlib import Path
from typing import Any, Sequence

import cv2

from fabricjax import memo, presets
from fabricjax.config import CAMERA_MODALITIES, RATE_NEUTRAL_FIELDS, Config
from fabricjax.reporting import results_files
from fabricjax.sequences import data
from fabricjax.sim import dataset as sim_dataset
from fabricjax.sim.trial import simulate
from fabricjax.store import archive, provenance, splits, workspace
from fabricjax.store.disk import size
from fabricjax.store.splits import DatasetSpec
from fabricjax.studies.machinery import documents, loading, recipe
from fabricjax.training import feed

# The published run the training line is extrapolated from (`python -m experiments.ablation
# --preset=paper_sample --seeds=5 --results=results/paper_sample`).
SAMPLE_RESULTS = provenance.repository_root() / "results" / "paper_sample" / "ablation.json"
# The manifest of the published `python -m experiments.reproduce --results=results`: each training
# study's rate per row (`rates`), measured on the default preset.
REPRODUCE_MANIFEST = provenance.repository_root() / "results" / "reproduce.json"
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


def _published_rates() -> list[tuple[str, dict[str, dict[str, float]]]]:
    """(where from, {rate key: rate}) of every published training run: each study of the
    repository's `REPRODUCE_MANIFEST`, then the paper_sample run (`SAMPLE_RESULTS`)."""
    out = []
    try:
        manifest = json.loads(REPRODUCE_MANIFEST.read_text())
        for study, entry in manifest.items():
            # keys re-read under today's `RATE_NEUTRAL` (a key is the JSON of the fields it kept)
            if entry.get("rates"):
                keyed = {rate_key(json.loads(k)): v for k, v in entry["rates"].items()}
                out.append(
                    (
                        f"{study} in {workspace.shown(REPRODUCE_MANIFEST)} "
                        f"({entry.get('machine', 'host not recorded')}, {entry['finished']})",
                        keyed,
                    )
                )
    except (OSError, ValueError):
        pass
    try:
        sample = json.loads(SAMPLE_RESULTS.read_text())
        out.append(
            (
                f"{workspace.shown(SAMPLE_RESULTS)} ({sample['machine'].get('cpu')}, "
                f"{sample['machine'].get('cores')} cores, {sample['date']})",
                rates(sample),
            )
        )
    except (OSError, ValueError, KeyError):
        pass
    return out


def training(configs: Sequence[tuple[str, Config]], n_seeds: int, train_sequences: int) -> list[Stage]:
    """One stage per row: its grid points (`recipe.points`) times its compilation and its epochs on
    `train_sequences` times the published rate of a row with the same inputs and model (`rates`):
    the cap of its epochs (`loading.epochs_for`), or with a patience the epochs the published run
    of the row went through under the same cap (early stopping ends each run on its own data). A row no
    published run matches is unknown until the run's own progress log gives its ETA."""
    published = _published_rates()
    out = []
    for name, config in configs:
        key = rate_key(config.to_json())
        source, rate = next(((src, r[key]) for src, r in published if key in r), (None, None))
        points = recipe.points(config)
        epochs = (
            loading.epochs_for(config, config.train_steps, train_sequences) if config.train_steps else config.epochs
        )
        grid = f"{len(points)} grid points x " if len(points) > 1 else ""
        early = bool(config.patience or config.patience_steps)  # early stopping on: it may end sooner
        if rate is None:
            out.append(
                Stage(
                    f"training {name}",
                    0,
                    None,
                    f"unknown before the run: no published run of these inputs and this model; {grid}at most "
                    f"{epochs} epochs",
                )
            )
            continue
        # with early stopping, the epochs the published run of this row went through, where it ran to the same cap
        same_cap = early and rate.get("epochs_run") and rate.get("epochs_cap") == epochs
        expected = min(epochs, rate["epochs_run"]) if same_cap else epochs
        seconds = len(points) * (rate["compile_s"] + rate["per_unit_s"] * train_sequences * expected * n_seeds)
        ran = f"{expected:.3g} epochs as it ran when published (at most {epochs}) " if expected != epochs else ""
        out.append(
            Stage(
                f"training {name}",
                0,
                seconds,
                f"{grid}{ran or f'at most {epochs} epochs '}"
                f"{'(early stopping ends sooner) ' if early and not ran else ''}"
                f"of {train_sequences} sequences x "
                f"{n_seeds} seeds at {1e6 * rate['per_unit_s']:.0f} us per sequence, epoch and seed",
                source,
            )
        )
    return out


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
    train_sequences = sum(  # the trials the data will place in the training split (`splits`, `data.split_of`)
        per_trial
        for meta, role in splits.dataset_roles(spec)
        if role == "train" and data.split_of(meta, role, exclude) == "train"
    )
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
    return out + training(configs, n_seeds, train_sequences)


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
