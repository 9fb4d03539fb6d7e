"""The cafe-noise protocol: trained in the lab, tested in a cafe, the rows of the paper's Table
new_noise_results and the splits and seeds it reads them on.

The noise study publishes the table (`paper.noise`); the calibration of the shell's transmission
loss trains its Minsound row again at every point it tries (`diagnostics.calibrate`).
"""

from __future__ import annotations

from typing import Mapping

from fabricjax.errors import UserError
from fabricjax.reporting import stats
from fabricjax.sequences import data
from fabricjax.studies.machinery import loading
from fabricjax.studies.machinery.rows import RowSpec
from fabricjax.studies.machinery.trained import TrainedRow

SPLIT = "cafe"
SPLITS = (SPLIT, "test")  # the splits every row is evaluated on: the cafe and, for reference, the lab test day
SPLIT_NAMES = (*loading.TRAIN_VAL_TEST, SPLIT)  # the splits loaded: training, validation and both test sets
N_SEEDS = 10  # the paper's


def display_name(row_name: str, names: Mapping[str, str] | None = None) -> str:
    """A row's inputs by name: the data's (`names`, recorded data) else the paper's sensors."""
    return data.inputs_name(row_name.split("+"), names)


def _row(modalities: tuple[str, ...], mean: float, sd: float, p: str | None) -> RowSpec:
    """A row and the paper's cafe accuracy [%] (10 seeds) with its p against the preceding row."""
    name = "+".join(modalities)
    return RowSpec(name, {"modalities": modalities}, display_name(name), {"mean": mean, "sd": sd, "p": p})


# The paper's Table new_noise_results.
ROWS = (
    _row(("internal",), 67.51, 5.05, None),
    _row(("internal", "proprio"), 87.51, 2.66, "< 0.0001"),
    _row(("internal", "proprio", "external"), 90.30, 2.18, "0.0098"),
)


def has_cafe_trials(ds: loading.Dataset) -> None:
    """Refuse data without trials of the cafe condition: nothing to test on."""
    if len(ds.sets[SPLIT]) == 0:
        raise UserError(f"the dataset in {ds.folder} has no cafe-condition trials to test on")


def summary(row: TrainedRow) -> str:
    """How the progress log says a row did: its cafe accuracy."""
    return f"{SPLIT} {stats.format_mean_sd(row.accuracy(SPLIT))} %"
