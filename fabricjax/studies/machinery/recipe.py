"""A row's recipe fitted on the validation split of the data it trains on.

A config with a grid (`Config.lr_grid`, `Config.width_grid`) stands for one run per grid point
(`points`: each point's config sets `learning_rate` and `width` and has no grid); each point
trains every seed with early stopping (`Config.patience`, capped at `Config.epochs`) and keeps
each seed's best-validation parameters. `choose` keeps the point whose seeds' best validation
accuracy is highest on average; ties go to the earlier point of the grid (the declared order).
Only the validation split decides: the epoch (early stopping), the learning rate and the width.
The test split and every other evaluation set are read from the chosen point's models alone.
"""

from __future__ import annotations

import dataclasses
import itertools
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from fabricjax.config import Config

if TYPE_CHECKING:
    from fabricjax.studies.machinery.trained import TrainedRow

CHOSEN_BY = "validation accuracy at each seed's best epoch, mean over seeds (ties: the earlier grid point)"


def has_grid(config: Config) -> bool:
    return bool(config.lr_grid or config.width_grid)


def points(config: Config) -> list[Config]:
    """The configs `config`'s grid stands for, in the grid's order (learning rate outer, width
    inner); `config` itself where it has no grid."""
    if not has_grid(config):
        return [config]
    return [
        dataclasses.replace(config, learning_rate=lr, width=width, lr_grid=(), width_grid=())
        for lr, width in itertools.product(
            config.lr_grid or (config.learning_rate,), config.width_grid or (config.width,)
        )
    ]


def point_name(config: Config) -> str:
    """How logs and the results JSON name a grid point."""
    return f"lr={config.learning_rate:g},width={config.width}"


def validation_score(row: TrainedRow) -> float:
    """The mean over seeds of each seed's validation accuracy at its best epoch [%]."""
    return float(100 * np.mean(row.results.metrics["best_val_acc"]))


def choose(grid: Sequence[TrainedRow]) -> TrainedRow:
    """The point of `grid` (trained rows, in the grid's order) whose `validation_score` is highest;
    the earliest on a tie."""
    scores = [validation_score(r) for r in grid]
    return grid[int(np.argmax(scores))]


def document(config: Config, grid: Sequence[TrainedRow], chosen: TrainedRow) -> dict[str, Any]:
    """What the results JSON says of a row's recipe: the grid, each point's validation score,
    epochs trained and time, the point chosen and why, the cap and patience of early stopping."""
    return {
        "chosen_by": CHOSEN_BY,
        "max_epochs": config.epochs,
        "patience": config.patience,
        "chosen": {"learning_rate": chosen.config.learning_rate, "width": chosen.config.width},
        "grid": [
            {
                "learning_rate": r.config.learning_rate,
                "width": r.config.width,
                "val": validation_score(r),
                "epochs_trained": epochs_trained(r),
                "wall_s": r.seconds,
            }
            for r in grid
        ],
        "grid_s": sum(r.seconds for r in grid),
    }


def epochs_trained(row: TrainedRow) -> list[int]:
    """Per seed, the epochs whose training changed its parameters: to the epoch it stopped at
    (inclusive), else all of the run's (`Config.epochs`: a seed that never stopped kept the run
    going to its cap)."""
    return [int(s) + 1 if s >= 0 else row.config.epochs for s in np.asarray(row.results.metrics["stopped_at"])]


def line(doc: dict[str, Any]) -> str:
    """One line for a table: the point chosen, out of how many, and the epochs it trained."""
    chosen = doc["chosen"]
    point = next(
        p for p in doc["grid"] if p["learning_rate"] == chosen["learning_rate"] and p["width"] == chosen["width"]
    )
    epochs = point["epochs_trained"]
    text = f"lr {chosen['learning_rate']:g}, width {chosen['width']}"
    if len(doc["grid"]) > 1:
        text += f" (best of {len(doc['grid'])} by validation)"
    if doc["patience"]:
        span = f"{min(epochs)}-{max(epochs)}" if min(epochs) != max(epochs) else f"{epochs[0]}"
        text += (
            f"; {span} epochs of at most {doc['max_epochs']} (early stopping after {doc['patience']} without a "
            f"better validation)"
        )
    else:
        text += f"; {doc['max_epochs']} epochs (no early stopping)"
    return text


def markdown(rows: Sequence[dict[str, Any]]) -> list[str]:
    """A results page's recipe section: one line per row of the results JSON that carries one."""
    lines = [f"- {r.get('display_name', r['name'])}: {line(r['recipe'])}" for r in rows if r.get("recipe")]
    if not lines:
        return []
    return ["## Recipe per row (chosen on the validation split; the test split decides nothing)", "", *lines, ""]
