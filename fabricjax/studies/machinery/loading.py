"""A study's data: every split it evaluates, as sequences of every input any of its rows uses.

Where the data comes from: `data_dir` (a folder of real recordings, see docs/data.md) if given,
else the simulated dataset of the preset, written on first use by `sim.ensure_dataset` (camera
frames are rendered only when some row needs images or optical flow).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Mapping, Sequence

from absl import logging

from fabricjax import config as config_fields
from fabricjax import sim
from fabricjax.config import CAMERA_MODALITIES, Config
from fabricjax.sequences import data
from fabricjax.store import archive, lock, workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery.rows import RowSpec, check_overrides, feedable_rows, select_rows
from fabricjax.training.trainer import steps_per_epoch

# The splits a study that evaluates on the lab test day needs (no cafe or holdout features computed).
TRAIN_VAL_TEST = ("train", "val", "test")
# The `Config` fields besides modalities and bandwidth that decide the sequences `data.load_sequences`
# returns (which trials, how they are cut, which camera features), as each field's metadata says
# (`config.SEQUENCE_FIELDS`): one load serves several rows only where these agree (`data.narrow`
# then gives each row its modalities and band).
SEQUENCE_FIELDS = config_fields.SEQUENCE_FIELDS


@dataclasses.dataclass
class Dataset:
    """A study's data: the sequences of every split, and what it took to get them (reported apart
    from training)."""

    sets: dict[str, data.SequenceSet]
    folder: Path
    source: str  # "recorded" | "simulated"
    generate_s: float  # simulating missing archives (0 for recorded data or a finished dataset)
    load_s: float  # features (cached after the first run) and sequences
    workdir: str | Path | None = None  # the workspace it was loaded under (a recorded folder's index lives there)
    # the camera inputs laid out and placed for training, once for the rows that share them (`row_training.train_rows`)
    layout_s: float = 0.0

    @property
    def classes(self) -> tuple[str, ...]:
        """The class names of the data's label space (every split has the same)."""
        return next(iter(self.sets.values())).classes

    @property
    def n_classes(self) -> int:
        return len(self.classes)

    @property
    def window_s(self) -> float:
        """The microphones' step window [s] the sequences were cut with (`data.step_window_s`)."""
        return next(iter(self.sets.values())).window_s

    def config_for(self, config: Config) -> Config:
        """`config` as trained on this data: its classes (the fabric head's size), its
        microphones' step window, so a checkpoint's config says what its features were, and,
        where it gives its budget or patience in optimiser steps (`Config.train_steps`,
        `patience_steps`), the epochs that cover them on this data's training split."""
        fitted = dataclasses.replace(config, n_classes=self.n_classes, mic_window_s=self.window_s)
        n_train = len(self.sets["train"])
        if config.train_steps:
            fitted = dataclasses.replace(fitted, epochs=epochs_for(config, config.train_steps, n_train))
        if config.patience_steps:
            fitted = dataclasses.replace(fitted, patience=epochs_for(config, config.patience_steps, n_train))
        return fitted

    @property
    def recorded(self) -> bool:
        return self.source == "recorded"

    def split_counts(self) -> dict[str, dict[str, int]]:
        """Trials and sequences per split."""
        return {
            k: {"trials": len(set(v.info["trial_key"].tolist())), "sequences": len(v)} for k, v in self.sets.items()
        }


def epochs_for(config: Config, steps: int, n_train: int) -> int:
    """The fewest epochs whose optimiser steps on `n_train` training sequences cover `steps`
    (an epoch's steps as training takes them, `trainer.steps_per_epoch`; one for no sequences)."""
    per_epoch = steps_per_epoch(config.batch_size, max(n_train, 1))
    return max(1, -(-steps // per_epoch))


def simulated_streams(modalities: Sequence[str]) -> tuple[str, ...]:
    """The streams a simulated trial records for rows that read `modalities`: those every archive
    has, and the camera's frames where an input is computed from them (rendering them is most of
    a trial's cost)."""
    return sim.REQUIRED_STREAMS + (("images",) if set(CAMERA_MODALITIES) & set(modalities) else ())


def load_dataset(config: Config, *, data_dir=None, workdir=None, split_names: Sequence[str] = data.SPLITS) -> Dataset:
    """The splits a study evaluates as sequences of `config.modalities`, loaded once."""
    t0 = time.perf_counter()
    with dataset_read_lock(config.preset, data_dir, workdir):
        if data_dir:
            folder, source = workspace.dataset_dir(config.preset, workdir, data_dir), "recorded"
        else:
            streams = simulated_streams(config.modalities)
            folder, source = sim.ensure_dataset(config.preset, workdir, streams=streams), "simulated"
        t1 = time.perf_counter()
        sets = data.load_sequences(config, folder, workdir=workdir, split_names=split_names)
    t2 = time.perf_counter()
    logging.info("dataset %s (%s): %s", folder, source, {k: len(v) for k, v in sets.items()})
    ds = Dataset(sets, Path(folder), source, t1 - t0, t2 - t1, workdir)
    if ds.recorded:  # the user's own splits: say what each got
        counts = ", ".join(
            f"{k} {c['trials']} trials / {c['sequences']} sequences" for k, c in ds.split_counts().items()
        )
        print(f"recorded data {folder} ({ds.n_classes} classes): {counts}")
    return ds


def dataset_read_lock(preset: str, data_dir=None, workdir=None):
    """The dataset's lock held shared (`fabricjax.store.lock`) while the block reads it: runs that read
    one dataset go together; one that would simulate it anew at the same time is refused."""
    folder = workspace.dataset_dir(preset, workdir, data_dir)
    return lock.hold(
        lock.lock_file(folder, workdir), f"the dataset {workspace.shown(folder)}", "reading it", shared=True
    )


def sequence_key(config: Config) -> tuple:
    """What of `config` decides its loaded sequences (`SEQUENCE_FIELDS`): rows with equal keys share a load."""
    return tuple(getattr(config, f) for f in SEQUENCE_FIELDS)


def union_modalities(configs: Sequence[Config]) -> tuple[str, ...]:
    return tuple(sorted({m for c in configs for m in c.modalities}))


def load_for_rows(
    configs: Sequence[Config], *, data_dir=None, workdir=None, split_names: Sequence[str] = data.SPLITS
) -> Dataset:
    """The sequences of every modality any row uses, at the widest bandwidth any row uses, loaded
    once for all rows (each row takes its own with `data.narrow`). The rows must agree on
    `SEQUENCE_FIELDS`, which `data.narrow` cannot change."""
    keys = {sequence_key(c) for c in configs}
    if len(keys) > 1:
        raise ValueError(f"rows differ in {SEQUENCE_FIELDS} ({sorted(map(str, keys))}): they need separate loads")
    merged = dataclasses.replace(
        configs[0], modalities=union_modalities(configs), bandwidth_khz=max(c.bandwidth_khz for c in configs)
    )
    return load_dataset(merged, data_dir=data_dir, workdir=workdir, split_names=split_names)


def load_chosen_rows(
    study: str,
    all_rows: Sequence[RowSpec],
    names: Sequence[str] | None,
    preset: str,
    overrides: Mapping | None,
    where: Location,
    split_names: Sequence[str],
) -> tuple[list[RowSpec], list[Config], list[Dataset], list[str]]:
    """What a study without training (the probe, the day shift) reads: the chosen rows of
    `all_rows` (all for None), their configs, each row's sequences on `split_names` (rows that
    agree on `SEQUENCE_FIELDS` share one load: the same object), and the splits that hold
    any. Rows that read frames against their session's reference are left out, with a warning,
    when the data has none and the rows were not asked for by name."""
    chosen = select_rows(all_rows, names)
    overrides = check_overrides(study, overrides, chosen, "choose them with --rows")
    if where.data_dir and not names:  # recorded data: the rows it can feed, the others left out in one line
        chosen = feedable_rows(study, chosen, where)
    configs = [r.config(preset, overrides) for r in chosen]
    loads: dict[tuple, Dataset] = {}
    for key in dict.fromkeys(sequence_key(c) for c in configs):
        group = [c for c in configs if sequence_key(c) == key]
        # another reading of the frames decides only the image's sequences: an earlier load that
        # differs in nothing else gives the rest, and only what it lacks is loaded
        base = next((d for k, d in loads.items() if _apart_from_image_reference(k, key)), None)
        if base is not None:
            have = set(next(iter(base.sets.values())).inputs)
            lacking = [(c, tuple(m for m in c.modalities if m == "image" or m not in have)) for c in group]
            group = [dataclasses.replace(c, modalities=ms) for c, ms in lacking if ms]
        try:
            ds = (
                load_for_rows(group, data_dir=where.data_dir, workdir=where.workdir, split_names=split_names)
                if group
                else base
            )
        except archive.ArchiveError as e:
            if e.field != "reference" or names:
                raise
            logging.warning("%s: rows that read frames against their session's reference left out: %s", study, e)
            continue
        if base is not None and ds is not base:
            ds = dataclasses.replace(
                base,
                sets={
                    s: dataclasses.replace(x, inputs={**x.inputs, **ds.sets[s].inputs}) for s, x in base.sets.items()
                },
            )
        loads[key] = ds
    kept = [(r, c) for r, c in zip(chosen, configs) if sequence_key(c) in loads]
    datasets = [loads[sequence_key(c)] for _, c in kept]
    return [r for r, _ in kept], [c for _, c in kept], datasets, [s for s in split_names if len(datasets[0].sets[s])]


def _apart_from_image_reference(a: tuple, b: tuple) -> bool:
    """Two `sequence_key`s that differ in `image_reference` alone."""
    i = SEQUENCE_FIELDS.index("image_reference")
    return a != b and a[:i] + a[i + 1 :] == b[:i] + b[i + 1 :]
