"""What training a study's rows gives: each row's seeds' metrics, wall time and checkpoint, and
the rows of one training call with the dataset they were trained on.

A trained row is what the recipe compares (`recipe.choose`), what the Wilcoxon tests pair and
what a study's document records (`TrainedRow.doc`); it lies beneath all of them, so that none of them
reads another through it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from fabricjax.config import Config
from fabricjax.store import workspace
from fabricjax.studies.machinery import loading
from fabricjax.training import curves, train


@dataclasses.dataclass
class TrainedRow:
    """A row after training: every seed's metrics, its wall time and its checkpoint.

    The metrics have a leading seed axis; `checkpoint` is None where the study keeps no models."""

    name: str
    config: Config
    results: train.TrainedSeeds
    seconds: float
    checkpoint: Path | None = None
    recipe: dict[str, Any] | None = None  # how its recipe was chosen on validation (`recipe.document`), where it was

    def accuracy(self, split: str, head: str = "fabric") -> np.ndarray:
        return np.asarray(self.results.metrics["eval"][split]["accuracy"][head], np.float64)

    def predictions(self, split: str, head: str = "fabric") -> np.ndarray:
        return np.asarray(self.results.metrics["eval"][split]["predictions"][head])

    def time_to_accuracy(self, head: str = "fabric") -> tuple[np.ndarray, np.ndarray]:
        """The row's time-to-accuracy curve: each trained epoch's end in seconds since its training
        began (the first epoch's with the compilation) and the validation accuracy of `head` per
        seed and epoch (seeds, epochs), over the epochs the run went through."""
        epochs = self.results.metrics["epochs"]
        wall = np.asarray(epochs[curves.WALL_TAG], np.float64)[0]
        trained = ~np.isnan(wall)
        return np.cumsum(wall[trained]), np.asarray(epochs[f"val/accuracy/{head}"], np.float64)[:, trained]

    def doc(self, splits: Sequence[str]) -> dict[str, Any]:
        """The row's config, checkpoint (None where the study keeps no models), wall time and its
        account (`train.TimeAccount`), per-epoch curves and, per seed, the accuracies of every
        head on "val" and `splits`; its per-sample predictions are `samples`."""
        ev = self.results.metrics["eval"]
        return {
            "config": self.config.to_json(),
            "checkpoint": None if self.checkpoint is None else workspace.shown(self.checkpoint),
            "seeds": list(self.results.seeds),
            "wall_s": self.seconds,
            "time": self.results.metrics["time"],
            "best_epoch": np.asarray(self.results.metrics["best_epoch"]).tolist(),
            "stopped_at": np.asarray(self.results.metrics["stopped_at"]).tolist(),
            "recipe": self.recipe,
            "epochs": {
                t: [[None if np.isnan(x) else float(x) for x in s] for s in v]
                for t, v in self.results.metrics["epochs"].items()
            },
            "accuracy": {
                s: {h: np.asarray(a, np.float64).tolist() for h, a in ev[s]["accuracy"].items()}
                for s in ("val", *splits)
            },
        }

    def samples(self, splits: Sequence[str]) -> dict[str, Any]:
        """Per split of `splits` and head, every seed's prediction of every sequence (seeds x
        sequences): the results' per-sample records, apart from the compact document (`doc`)."""
        ev = self.results.metrics["eval"]
        return {s: {h: np.asarray(p).tolist() for h, p in ev[s]["predictions"].items()} for s in splits}


@dataclasses.dataclass
class TrainingRun:
    """The rows one training call trained, and the dataset it loaded once for them.

    `row_training.train_rows` gives one, its rows in the order they were asked for."""

    dataset: loading.Dataset
    rows: dict[str, TrainedRow]

    @property
    def train_s(self) -> float:
        return sum(r.seconds for r in self.rows.values())
