"""`ensure_dataset`: every trial of a preset as simulated archives, resumable, then indexed.

Archives are written atomically (`archive.write_archive`), so an interrupted run leaves only
finished archives (plus temporary `.partial` files, removed on the next run); rerunning skips
every archive that already exists, matches its scene and holds the wanted streams. Writing holds
the dataset's lock (`fabricjax.store.lock`): a run that reads the dataset, or simulates it, at the same
time makes this one end in a line naming it, before anything is written.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

import numpy as np
from tqdm import tqdm

from fabricjax import parallel, presets
from fabricjax.sim import calibration as cal
from fabricjax.sim import estimates
from fabricjax.sim.scene import EFFECTS, Scene
from fabricjax.sim.trial import simulate
from fabricjax.store import archive, dataset_index, disk, lock, splits, workspace


def history(spec: splits.TrialSpec, dataset: splits.DatasetSpec) -> int:
    """How many of the dataset's trials rubbed `spec`'s cloth before it: the fabric's trials of
    earlier days (in day order, whatever the condition) and the earlier trials of its own day."""
    return sum(
        1 for t in dataset.trials() if t.fabric_id == spec.fabric_id and (t.day, t.trial) < (spec.day, spec.trial)
    )


def scene_for(spec: splits.TrialSpec, dataset: splits.DatasetSpec, streams: Iterable[str], seed: int = 0) -> Scene:
    return Scene(
        fabric_id=spec.fabric_id,
        day=spec.day,
        trial=spec.trial,
        condition=spec.condition,
        effects=EFFECTS,
        streams=tuple(streams),
        image_size=tuple(dataset.image_size),
        cycles=dataset.cycles_per_trial,
        seed=seed,
        history=history(spec, dataset),
        estimates=estimates.in_force(),
    )


def filename(scene: Scene) -> str:
    return archive.trial_filename(
        {"fabric_id": scene.fabric_id, "day": scene.day, "trial": scene.trial, "condition": scene.condition}
    )


def is_done(path: Path, scene: Scene) -> bool:
    """The archive exists, is readable, was made from this scene by today's simulator code
    (`source.simulator`, part of the scene's JSON) and has the wanted streams (frames with their
    session's no-contact reference, which archives before format 3 lack)."""
    if not path.is_file():
        return False
    try:
        meta, _ = archive.read_meta(path)
        with np.load(path, allow_pickle=False) as npz:
            has_images = "images" in npz.files and "reference" in npz.files
    except archive.ArchiveError:
        return False
    made = dict(meta["source"].get("scene", {}))
    want = scene.to_json()
    made.pop("streams", None), want.pop("streams", None)
    return made == want and (has_images or "images" not in scene.streams)


def trial_seconds(dataset: splits.DatasetSpec) -> float:
    """About how long one simulated trial of `dataset` lasts, at most: its cycles at the commanded
    rate, ~12 % slower on average under load (the servo droop of calibration.SPEED_DROOP_PER_N),
    plus ~1 s of closing and pauses."""
    return dataset.cycles_per_trial / cal.CYCLE_HZ * 1.12 + 1.0  # [numerics] a bound for disk checks and plans


def trial_steps(dataset: splits.DatasetSpec) -> int:
    """About how many steps one simulated trial of `dataset` records (`trial_seconds`)."""
    return int(trial_seconds(dataset) * archive.STEP_RATE)


def trial_bytes(dataset: splits.DatasetSpec, images: bool) -> int:
    """About how many bytes one simulated trial archive of `dataset` takes before its members are
    deflated (`archive.write_npz`): an upper bound, for the free-disk check."""
    seconds = trial_seconds(dataset)
    steps = seconds * archive.STEP_RATE
    frame = 3 * dataset.image_size[0] * dataset.image_size[1] if images else 0  # [numerics] bytes
    per_step = 8 + 2 * 8 + archive.N_PROPRIO * 4 + 4 + frame  # [numerics] bytes
    return int(steps * per_step + 2 * 4 * (seconds * archive.AUDIO_RATE + cal.LEAD_IN))


def _write(job: tuple[Scene, str]) -> str:
    scene, path = job
    archive.write_archive(path, simulate(scene))
    return path


def ensure_dataset(
    preset_name: str,
    workdir=None,
    streams: Iterable[str] = ("audio", "proprio", "images"),
    progress: bool = True,
    workers: int | None = None,
    seed: int = 0,
) -> Path:
    """Generate the missing archives of `preset_name` into `workspace.dataset_dir` and index them;
    archives there that no trial of the preset produces (a preset that changed) are removed.

    Trials are simulated in a process pool of `workers` (default: one per core). Each archive is
    a function of its scene alone (every draw is seeded by the scene), so the pool's order
    changes nothing: the archives equal those of `workers=1` byte for byte (tested). Before
    writing, the disk space the missing trials need is estimated (`trial_bytes`) and checked."""
    dataset = presets.get(preset_name).dataset
    folder = workspace.dataset_dir(preset_name, workdir)
    scenes = [scene_for(spec, dataset, streams, seed) for spec in dataset.trials()]
    wanted = {filename(s) for s in scenes}
    missing = [s for s in scenes if not is_done(folder / filename(s), s)]
    # complete: only read, as readers may at the same time
    if folder.is_dir() and not missing and not _stray(folder, wanted):
        dataset_index.load_index(folder, workdir)
        return folder
    doing = f"simulating preset {preset_name!r}"
    with lock.hold(lock.lock_file(folder, workdir), f"the dataset {workspace.shown(folder)}", doing):
        folder.mkdir(parents=True, exist_ok=True)
        for stale in folder.glob(".*.partial"):
            stale.unlink()
        for foreign in sorted(p for p in folder.glob("*.npz") if p.name not in wanted):
            # the simulator's own folder: a trial the preset no longer has (e.g. an older smoke preset's fabrics)
            foreign.unlink()
            if progress:
                print(f"removed {foreign}: the preset {preset_name!r} has no such trial", flush=True)
        # again under the lock, the missing ones only (a finished archive is never unfinished): another
        # run may have written some of them since `missing` was taken
        jobs = [(s, str(folder / filename(s))) for s in missing if not is_done(folder / filename(s), s)]
        workers = workers or os.cpu_count() or 1
        if jobs:
            need = len(jobs) * trial_bytes(dataset, "images" in streams)
            disk.require(
                folder,
                need,
                f"{len(jobs)} simulated trials of preset {preset_name!r}",
                margin=1 / 0.95,  # [numerics] a margin for other files
            )
            if progress:
                print(
                    f"Simulating {len(jobs)} of {len(scenes)} trials of preset {preset_name!r} "
                    f"({', '.join(streams)}) into {folder}: "
                    f"at most {disk.size(need)} on disk (less: members are deflated), on {workers} processes. "
                    "This happens once; later runs reuse the archives.",
                    flush=True,
                )
        bar = tqdm(
            total=len(scenes),
            initial=len(scenes) - len(jobs),
            desc=f"simulate {preset_name}",
            unit="trial",
            disable=not progress or not jobs,
        )
        with bar:
            parallel.run_jobs(_write, jobs, workers, bar.update)
        dataset_index.build_index(folder)
    return folder


def _stray(folder: Path, wanted: set[str]) -> bool:
    """Whether the dataset in `folder` holds an archive that no trial makes (`wanted`: their file
    names), or a temporary file of an interrupted write."""
    return any(folder.glob(".*.partial")) or any(p.name not in wanted for p in folder.glob("*.npz"))
