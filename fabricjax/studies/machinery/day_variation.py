"""What a new recording day changes in each input, as the day shift measures it: the per-trial
variation the fabric, the day and the trial explain (`variance_shares`), each input read as the
probe reads it (`linear_probe.summarise`).

The day-shift study publishes it (`diagnostics.day_shift`) beside the probe's accuracies; the
sensitivity screening measures the shares again at every point of the simulator's estimates.
"""

from __future__ import annotations

import dataclasses
import json
import time
from typing import Any, Sequence

import numpy as np

from fabricjax.reporting import results_files
from fabricjax.sequences import data
from fabricjax.store import archive
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import linear_probe, loading, probing
from fabricjax.studies.machinery.progress import Progress
from fabricjax.studies.machinery.rows import RowSpec

ROWS = (
    *(RowSpec(m, {"modalities": (m,)}, data.inputs_name((m,))) for m in ("internal", "external", "proprio", "flow")),
    # the frames as they are: the "none" and "training_mean" readings differ from them by a per-pixel
    # constant, which standardising each dimension over the trials removes
    RowSpec("image", {"modalities": ("image",), "image_reference": "training_mean"}, data.inputs_name(("image",))),
    RowSpec(
        probing.SESSION + "image",
        {"modalities": ("image",), "image_reference": "session"},
        data.inputs_name(("image",)) + " − session reference",
    ),
)
SHARES = ("fabric", "day", "fabric x day", "trial")


def trial_summaries(x: np.ndarray, trial_key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(trials, 2 D) float64: the mean over each trial's sequences of `linear_probe.summarise`, and the
    index of each trial's first sequence (to read its fabric and day)."""
    keys, first, inverse = np.unique(trial_key, return_index=True, return_inverse=True)
    summaries = linear_probe.summarise(x).astype(np.float64)
    out = np.zeros((len(keys), summaries.shape[1]))
    np.add.at(out, inverse, summaries)
    return out / np.bincount(inverse, minlength=len(keys))[:, None], first


def _between(x: np.ndarray, groups: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(per-row group means, sum of squares of the group means about 0, per dimension)."""
    _, inverse = np.unique(groups, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    counts = np.bincount(inverse)
    means = np.zeros((len(counts), x.shape[1]))
    np.add.at(means, inverse, x)
    means /= counts[:, None]
    return means[inverse], (counts[:, None] * means**2).sum(axis=0)


def variance_shares(x: np.ndarray, fabric: np.ndarray, day: np.ndarray, weighted: bool = False) -> dict[str, float]:
    """Shares of the per-trial variation of `x` (trials, dims) by fabric, day, fabric x day and
    trial (see the module docstring), averaged over the dimensions that vary; they sum to 1. With
    `weighted`, each dimension weighs as its variance in the input's own units (the sums of squares
    are pooled over the dimensions before they are divided), instead of every standardised
    dimension the same."""
    x = x[:, x.std(axis=0) > 0]
    if x.shape[1] == 0:
        return {k: float("nan") for k in SHARES}
    x = x - x.mean(axis=0)
    if not weighted:
        x = x / x.std(axis=0)
    fabric_means, ss_fabric = _between(x, fabric)
    left = x - fabric_means
    _, ss_day = _between(left, day)
    cell_means, ss_cells = _between(left, np.stack([fabric, day], axis=1))
    ss_trial = ((left - cell_means) ** 2).sum(axis=0)
    total = (x**2).sum(axis=0)
    parts = {"fabric": ss_fabric, "day": ss_day, "fabric x day": ss_cells - ss_day, "trial": ss_trial}
    if weighted:
        return {k: float(v.sum() / total.sum()) for k, v in parts.items()}
    return {k: float(np.mean(v / total)) for k, v in parts.items()}


def day_led_dims(x: np.ndarray, fabric: np.ndarray, day: np.ndarray) -> float:
    """The share of the dimensions that vary in which the day explains more than the fabric does."""
    x = x[:, x.std(axis=0) > 0]
    if x.shape[1] == 0:
        return float("nan")
    x = x - x.mean(axis=0)
    fabric_means, ss_fabric = _between(x, fabric)
    _, ss_day = _between(x - fabric_means, day)
    return float(np.mean(ss_day > ss_fabric))


def probe_accuracy(results, folder: str) -> tuple[dict[str, dict[str, float | None]], str | None]:
    """Each input's single-input probe accuracy on val and test from results/probe.json, and why
    there is none (None when the probe ran on the same data folder)."""
    path = results_files.results_path(results) / "probe.json"
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}, f"no probe results in {path.parent} (run `python -m experiments.probe` on the same data)"
    if doc.get("dataset", {}).get("folder") != folder:
        return {}, f"the probe in {path} ran on other data (`{doc.get('dataset', {}).get('folder')}`)"
    out = {}
    for r in ROWS:
        row = probing.row_for(r.modalities, doc["rows"], r.settings.get("image_reference"))
        if row is not None:
            out[r.name] = {s: row["accuracy"].get(s) for s in ("val", "test")}
    return out, None


@dataclasses.dataclass(frozen=True)
class DayShift:
    """What the day shift measured: the data read, the seconds it took, and the results JSON's own
    part (`body`: the splits, the trial, day and fabric counts, why the probe's accuracies are
    missing (None: they are not) and the rows)."""

    dataset: loading.Dataset
    seconds: float
    body: dict[str, Any]


def measure(
    *,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    where: Location = Location(),
) -> DayShift:
    """The shares and the probe's gap (from `where`'s results folder) for the chosen inputs (all by
    default); writes nothing."""
    chosen, _, datasets, present = loading.load_chosen_rows(
        "day_shift", ROWS, rows, preset, overrides, where, loading.TRAIN_VAL_TEST
    )
    ds = datasets[0]
    info = {k: np.concatenate([ds.sets[s].info[k] for s in present]) for k in ("fabric_id", "day", "trial_key")}
    if len(np.unique(info["day"])) < 2:
        raise archive.ArchiveError(
            ds.folder, "day", "the lab trials come from fewer than two days: there is no day to tell apart"
        )
    accuracy, no_probe = probe_accuracy(where.results_dir(), str(ds.folder))

    t0 = time.perf_counter()
    progress = Progress("day_shift", len(chosen))
    out_rows = []
    names = ds.sets[present[0]].names if ds.recorded else {}  # recorded data: its own names for its streams
    for r, d in zip(chosen, datasets):
        display = data.inputs_name(r.modalities, names) + r.label.removeprefix(data.inputs_name(r.modalities))
        progress.start(display)
        t1 = time.perf_counter()
        m = r.modalities[0]
        per_split = [
            trial_summaries(d.sets[s].inputs[m], d.sets[s].info["trial_key"]) for s in present
        ]  # a trial lies in one split
        x = np.concatenate([x for x, _ in per_split])
        labels = {
            k: np.concatenate([d.sets[s].info[k][first] for s, (_, first) in zip(present, per_split)])
            for k in ("fabric_id", "day")
        }
        shares = variance_shares(x, labels["fabric_id"], labels["day"])
        out_rows.append(
            {
                "name": r.name,
                "display_name": display,
                "summary_dims": int(x.shape[1]),
                "shares": shares,
                "shares_weighted": variance_shares(x, labels["fabric_id"], labels["day"], weighted=True),
                "day_led_dims": day_led_dims(x, labels["fabric_id"], labels["day"]),
                "probe": accuracy.get(r.name),
                "wall_s": time.perf_counter() - t1,
            }
        )
        progress.finish(
            display, time.perf_counter() - t1, f"fabric {100 * shares['fabric']:.0f} %, day {100 * shares['day']:.0f} %"
        )

    return DayShift(
        ds,
        time.perf_counter() - t0,
        {
            "splits": present,
            "trials": int(len(np.unique(info["trial_key"]))),
            "days": sorted(int(d) for d in np.unique(info["day"])),
            "fabrics": len(np.unique(info["fabric_id"])),
            "probe_missing": no_probe,
            "rows": out_rows,
        },
    )
