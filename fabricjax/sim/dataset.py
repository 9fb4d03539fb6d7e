"""`ensure_dataset`: every trial of a preset as simulated archives, resumable, then indexed.

Archives are written atomically (`archive.write_archive`), so an interrupted run leaves only
finished archives (plus temporary `.partial` files, removed on the next run); rerunning skips
every archive that already exists, matches its scene and holds the wanted streams.
"""

from __future__ import annotations

import multiprocessing
from pathlib import Path
from typing import Iterable

import numpy as np
from tqdm import tqdm

from fabricjax import archive, splits, workspace
from fabricjax.sim.scene import EFFECTS, Scene
from fabricjax.sim.simulate import simulate


def scene_for(spec: splits.TrialSpec, preset: splits.Preset, streams: Iterable[str], seed: int = 0) -> Scene:
    return Scene(
        fabric_id=spec.fabric_id,
        day=spec.day,
        trial=spec.trial,
        condition=spec.condition,
        effects=EFFECTS,
        streams=tuple(streams),
        image_size=tuple(preset.image_size),
        cycles=preset.cycles_per_trial,
        seed=seed,
    )


def filename(scene: Scene) -> str:
    return archive.trial_filename({"fabric_id": scene.fabric_id, "day": scene.day, "trial": scene.trial, "condition": scene.condition})


def is_done(path: Path, scene: Scene) -> bool:
    """The archive exists, is readable, was made from this scene and has the wanted streams."""
    if not path.is_file():
        return False
    try:
        meta, _ = archive.read_meta(path)
        with np.load(path, allow_pickle=False) as npz:
            has_images = "images" in npz.files
    except archive.ArchiveError:
        return False
    made = dict(meta["source"].get("scene", {}))
    want = scene.to_json()
    made.pop("streams", None), want.pop("streams", None)
    return made == want and (has_images or "images" not in scene.streams)


def _write(job: tuple[Scene, str]) -> str:
    scene, path = job
    archive.write_archive(path, simulate(scene))
    return path


def ensure_dataset(
    preset_name: str,
    workdir=None,
    streams: Iterable[str] = ("audio", "proprio", "images"),
    progress: bool = True,
    workers: int = 2,
    seed: int = 0,
) -> Path:
    """Generate the missing archives of `preset_name` into `workspace.dataset_dir` and index them."""
    preset = splits.preset(preset_name)
    folder = workspace.dataset_dir(preset_name, workdir)
    folder.mkdir(parents=True, exist_ok=True)
    for stale in folder.glob(".*.partial"):
        stale.unlink()
    scenes = [scene_for(spec, preset, streams, seed) for spec in preset.trials()]
    jobs = [(s, str(folder / filename(s))) for s in scenes if not is_done(folder / filename(s), s)]
    bar = tqdm(total=len(scenes), initial=len(scenes) - len(jobs), desc=f"simulate {preset_name}", unit="trial", disable=not progress)
    with bar:
        if workers > 1 and len(jobs) > 1:
            with multiprocessing.get_context("spawn").Pool(min(workers, len(jobs))) as pool:
                for _ in pool.imap_unordered(_write, jobs):
                    bar.update()
        else:
            for job in jobs:
                _write(job)
                bar.update()
    archive.build_index(folder)
    return folder
