"""Training a study's rows: the data loaded once for all of them, each row's seeds in one vmapped
program, every point of its recipe grid, and the rows in the order that places a camera's inputs
once for the rows that read them.

    run = row_training.train_rows("ablation", [(name, config), ...], seeds, eval_splits=("test",))
    run.rows[name].accuracy("test")          # a `trained.TrainedRow`, one value per seed
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Callable, Mapping, Sequence, TypeVar

from fabricjax.config import CAMERA_MODALITIES, Config
from fabricjax.reporting import stats
from fabricjax.sequences import data
from fabricjax.sequences.inputs import input_statistics
from fabricjax.store import lock, workspace
from fabricjax.studies.machinery import loading, plan, recipe
from fabricjax.studies.machinery.checkpoints import checkpoint_dir
from fabricjax.studies.machinery.progress import Progress
from fabricjax.studies.machinery.trained import TrainedRow, TrainingRun
from fabricjax.training import placement, train

T = TypeVar("T")


ROW_KINDS = (*CAMERA_MODALITIES, "other")  # what `row_kind` says, in the order rows train


def row_kind(config: Config) -> str:
    """What a row's training time mostly depends on: its costliest input (a camera row trains
    several times longer than an audio row), else "other"."""
    return next((m for m in CAMERA_MODALITIES if m in config.modalities), "other")


def in_training_order(items: Sequence[T], config: Callable[[T], Config]) -> list[T]:
    """`items` (rows, each with its `config(item)`) in the order they train: grouped by their
    camera input (`row_kind`), in the given order within a group. A study's rows share the inputs
    placed on the devices (`placement.place_sets`) within a memory budget, so a camera's frames are placed
    once for its group, instead of again each time a row of the other camera has pushed them out."""
    return sorted(items, key=lambda item: ROW_KINDS.index(row_kind(config(item))))


def place_row(config: Config, sets: Mapping[str, data.SequenceSet], eval_splits: Sequence[str]) -> placement.Placed:
    """A row's part of `sets` ("train", "val" and `eval_splits`; its inputs, `data.narrow`) placed
    as its runs read it (`placement.place_sets`): once, for every point of its recipe grid."""
    return placement.place_sets(config, data.narrow({s: sets[s] for s in ("train", "val", *eval_splits)}, config))


def train_row(
    name: str,
    config: Config,
    placed: placement.Placed,
    seeds: Sequence[int],
    checkpoint_dir=None,
    log_dir=None,
) -> TrainedRow:
    """Train all seeds of one row on its placed sets (`place_row`) and evaluate the
    best-validation models on each; with `checkpoint_dir` the models are saved there, with
    `log_dir` (`workspace.logs_dir`) the training curves are written there as it trains."""
    t0 = time.perf_counter()
    results = train.train_and_evaluate(config, placed, seeds, workdir=checkpoint_dir, log_dir=log_dir)
    return TrainedRow(name, config, results, time.perf_counter() - t0, Path(checkpoint_dir) if checkpoint_dir else None)


def train_fitted(
    study: str,
    name: str,
    config: Config,
    placed: placement.Placed,
    seeds: Sequence[int],
    workdir=None,
    checkpoints: bool = False,
) -> TrainedRow:
    """`train_row` of every point of `config`'s recipe grid (`recipe.points`) on the row's placed
    sets (`place_row`: the points differ in learning rate and width only), the point the
    validation split prefers kept (`recipe.choose`); its time is the whole grid's. A config
    without a grid is one point, reported as is."""
    configs = recipe.points(config)
    grid = []
    for point in configs:
        sub = name if len(configs) == 1 else f"{name}/{recipe.point_name(point)}"
        grid.append(
            train_row(
                name,
                point,
                placed,
                seeds,
                checkpoint_dir=checkpoint_dir(study, name, point, seeds, placed.training_set.dataset, workdir)
                if checkpoints
                else None,
                log_dir=workspace.logs_dir(study, sub, workdir),
            )
        )
    chosen = recipe.choose(grid)
    return dataclasses.replace(
        chosen, seconds=sum(r.seconds for r in grid), recipe=recipe.document(config, grid, chosen)
    )


def summary_by_test(row: TrainedRow) -> str:
    """How the progress log says a row did: its test accuracy, mean ± SD over seeds."""
    return f"test {stats.format_mean_sd(row.accuracy('test'))} %"


def train_rows(
    study: str,
    rows: Sequence[tuple[str, Config]],
    seeds: Sequence[int],
    *,
    eval_splits: Sequence[str],
    split_names: Sequence[str] = data.SPLITS,
    data_dir=None,
    workdir=None,
    checkpoints: bool = False,
    label: Callable[[str], str] = str,
    summary: Callable[[TrainedRow], str] = summary_by_test,
    check: Callable[[loading.Dataset], None] | None = None,
    progress: Progress | None = None,
    data_names: bool = False,
) -> TrainingRun:
    """Load the data every row needs once, then train each (name, config) row's seeds, in
    `in_training_order` (the rows come back in the order given).

    `eval_splits`: the splits every row is evaluated on (beside val); `split_names`: the splits
    loaded. `checkpoints`: keep each row's models (`checkpoint_dir`). `label` names a row in the
    progress log, `summary` says how it did there. `check` looks at the loaded data before any
    training (raise `UserError` for data the study cannot use). `progress`: a log shared with
    other calls (a study that loads its rows in several parts), else one for these rows.
    `data_names`: on recorded data, name each row in the log by its name and the data's own names
    for its inputs (the rig's microphones and joints), not by `label`."""
    configs = [c for _, c in rows]
    checkpoints_folder = workspace.checkpoints_dir(study, workdir)
    with (
        lock.hold(
            lock.lock_file(checkpoints_folder, workdir),
            f"the {study} study's checkpoints ({workspace.shown(checkpoints_folder)})",
            f"training {len(rows)} rows",
        ),
        loading.dataset_read_lock(configs[0].preset, data_dir, workdir),
    ):
        ds = loading.load_for_rows(configs, data_dir=data_dir, workdir=workdir, split_names=split_names)
        if check is not None:
            check(ds)
        rows = [(name, ds.config_for(config)) for name, config in rows]  # the data's classes, step window and epochs
        if ds.recorded:  # what training will take, now that the data's size is known
            train = ds.sets["train"].inputs
            arrays = {m: (a.shape[2:], a.dtype) for m, a in train.items()}
            stages = plan.training(rows, len(seeds), {k: len(v) for k, v in ds.sets.items()}, arrays)
            print(
                plan.markdown(
                    f"{rows[0][1].preset} on recorded data", stages, len(rows), len(seeds), plan.free_disk(workdir)
                ),
                flush=True,
            )
        if data_names and ds.recorded:
            names, inputs = next(iter(ds.sets.values())).names, {n: c.modalities for n, c in rows}
            label = lambda name: f"{name} ({data.inputs_name(inputs[name], names)})"  # noqa: E731
        order = in_training_order(rows, lambda row: row[1])
        if progress is None:
            progress = Progress(study, len(rows), [row_kind(c) for _, c in order])
        else:  # started before this load
            progress.exclude(ds.generate_s + ds.load_s)
        trained, laid_out = {}, set()
        for name, config in order:
            t0 = time.perf_counter()
            placed = place_row(config, ds.sets, eval_splits)
            camera = row_kind(config)
            # the group's camera input is laid out with its first row (`in_training_order`) and its
            # statistics computed, timed as the data's cost, not as that row's: the group's other
            # rows find both kept (`placement.KEPT`)
            if camera in CAMERA_MODALITIES and camera not in laid_out:
                input_statistics(config, placed.training_set)
                ds.layout_s += time.perf_counter() - t0
                laid_out.add(camera)
            progress.start(label(name))
            trained[name] = row = train_fitted(study, name, config, placed, seeds, workdir, checkpoints)
            del placed  # before the next row's: inputs `placement.KEPT` lets go leave the devices
            progress.finish(label(name), row.seconds, summary(row))
        return TrainingRun(ds, {name: trained[name] for name, _ in rows})
