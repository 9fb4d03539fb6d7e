"""What a new recording day changes in each input: the per-trial variation the fabric, the day and
the trial explain, beside the linear probe's accuracy on the training days and on the new day.

    python -m experiments.day_shift                       # default preset, every input
    python -m experiments.day_shift --rows=image,proprio --data_dir=DIR

The paper splits by recording day so that a model cannot lean on what a day shares; this study
says, before any model, what the test day differs in. For every model input (`ROWS`: Minsound,
the palm microphone, proprioception, optical flow, the Minsight image as it is and minus its
session's no-contact reference, `Config.image_reference`), as the probe reads it
(`linear_probe.summarise`: each dimension's mean and SD over a sequence's steps), each lab trial's
summary is the mean of its sequences' summaries. Each dimension is standardised over the trials
and its sum of squares split, for fabric f and day d:

    fabric        between the fabrics' means
    day           between the days' means of what the fabric leaves (fabric first, then day:
                  exact for any trial counts, the textbook two-way split when they are balanced)
    fabric x day  the rest between the (fabric, day) cells' means: the day's effect that differs by fabric
    trial         within a cell: the trial-to-trial variation of one fabric on one day

The shares are averaged over the input's dimensions (every standardised dimension weighs the
same). For the Minsight image the page also weighs each dimension by its variance in DN (the sums
of squares pooled over the dimensions before they are divided, `variance_shares(weighted=True)`)
and counts the dimensions in which the day explains more than the fabric (`day_led_dims`): the
numbers behind the sentence this page shares with the camera-frames page
(`camera_variation.RECONCILE`), which measures the image's difference in DN. Trials are every
lab trial of the training and test days (`loading.TRAIN_VAL_TEST`), in the classes of the data.
The probe's validation (whole trials of the training days) and test (the new day) accuracy per
input come from the probe's own results file in the same results folder (`python -m
experiments.probe`, which `reproduce` runs first); where it is missing or ran on
other data, the table says so instead of numbers.
"""

from __future__ import annotations

import json
import time
from typing import Any, Mapping, Sequence

import numpy as np

from fabricjax.reporting import results_files
from fabricjax.sequences import data
from fabricjax.store import archive
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import camera_variation, documents, linear_probe, loading
from fabricjax.studies.machinery.progress import Progress
from fabricjax.studies.machinery.rows import RowSpec
from fabricjax.studies.diagnostics import probe

TITLE, PAPER = "Day shift: what the fabric, the day and the trial explain in each input", "not in the paper"
ROWS = (
    *(RowSpec(m, {"modalities": (m,)}, data.inputs_name((m,))) for m in ("internal", "external", "proprio", "flow")),
    # the frames as they are: the "none" and "training_mean" readings differ from them by a per-pixel
    # constant, which standardising each dimension over the trials removes
    RowSpec("image", {"modalities": ("image",), "image_reference": "training_mean"}, data.inputs_name(("image",))),
    RowSpec(
        probe.SESSION + "image",
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
        row = probe.row_for(r.modalities, doc["rows"], r.settings.get("image_reference"))
        if row is not None:
            out[r.name] = {s: row["accuracy"].get(s) for s in ("val", "test")}
    return out, None


def run(
    *,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    where: Location = Location(),
) -> dict[str, Any]:
    """The shares and the probe's gap for the chosen inputs (all by default); writes
    results/day_shift.{md,json} and returns the JSON."""
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

    doc = {
        **documents.header(
            "day_shift",
            module=__name__,
            command=where.command,
            preset=preset,
            dataset=ds,
            study_s=time.perf_counter() - t0,
        ),
        "splits": present,
        "trials": int(len(np.unique(info["trial_key"]))),
        "days": sorted(int(d) for d in np.unique(info["day"])),
        "fabrics": len(np.unique(info["fabric_id"])),
        "probe_missing": no_probe,
        "rows": out_rows,
    }
    return results_files.write(where.results_dir(), doc, markdown)


def _pct(x: float | None) -> str:
    return "–" if x is None or np.isnan(x) else f"{100 * x:.1f}"


def table(doc: Mapping[str, Any]) -> str:
    """One line per input: the four shares, then the probe's validation and test accuracy and their gap."""
    body = []
    for r in doc["rows"]:
        p = r["probe"] or {}
        val, test = p.get("val"), p.get("test")
        gap = "–" if val is None or test is None else f"{100 * (test - val):+.1f}"
        body.append(
            [r["display_name"], r["summary_dims"], *[_pct(r["shares"][k]) for k in SHARES], _pct(val), _pct(test), gap]
        )
    header = [
        "Input",
        "Summary dims",
        "Fabric [%]",
        "Day [%]",
        "Fabric x day [%]",
        "Trial [%]",
        "Probe, validation (training days) [%]",
        "Probe, test (new day) [%]",
        "Test − validation [pp]",
    ]
    return results_files.markdown_table(header, body)


def image_weighting(doc: Mapping[str, Any]) -> list[str]:
    """The Minsight image's rows weighed two ways, after the sentence the camera-frames page carries
    too (`camera_variation.RECONCILE`); nothing where the doc has no image row (or was written
    before the weighted shares were)."""
    rows = [r for r in doc["rows"] if r["name"].removeprefix(probe.SESSION) == "image" and "shares_weighted" in r]
    if not rows:
        return []
    body = [
        [
            r["display_name"],
            *[_pct(r["shares"][k]) for k in ("fabric", "day")],
            *[_pct(r["shares_weighted"][k]) for k in ("fabric", "day")],
            _pct(r["day_led_dims"]),
        ]
        for r in rows
    ]
    session = next((r for r in rows if r["name"].startswith(probe.SESSION)), rows[-1])
    header = [
        "Input",
        "Fabric, each dimension alike [%]",
        "Day, each dimension alike [%]",
        "Fabric, weighted by variance [%]",
        "Day, weighted by variance [%]",
        "Dimensions where the day explains more than the fabric [%]",
    ]
    return [
        "## The image, weighted by variance",
        "",
        camera_variation.RECONCILE
        + f" Weighted by each dimension's variance in DN instead (the sums of squares pooled over the "
        f"dimensions, as an RMS in DN pools pixels), {session['display_name']} gives the fabric "
        f"{_pct(session['shares_weighted']['fabric'])} % of its variation and the day "
        f"{_pct(session['shares_weighted']['day'])} %; the day explains more than the fabric in "
        f"{_pct(session['day_led_dims'])} % of its {session['summary_dims']} dimensions.",
        "",
        results_files.markdown_table(header, body),
    ]


def markdown(doc: Mapping[str, Any]) -> str:
    lines = [
        documents.title(doc, "Day shift: what the fabric, the day and the trial explain in each input"),
        "",
        documents.header_markdown(
            doc, f"{doc['study_s']:.0f} s in all; {documents.data_time_markdown(doc['dataset'])}"
        ),
        f"Every lab trial of days {', '.join(map(str, doc['days']))} ({doc['trials']} trials, "
        f"{doc['fabrics']} fabrics): each "
        "input's per-sequence summaries as the linear probe reads them (each dimension's mean and SD over the steps), "
        "averaged per trial, each dimension standardised over the trials; the shares split its sum of squares into "
        "fabric, day (after the fabric), fabric x day and trial (within one fabric and day), averaged over the "
        "dimensions. A large day share is what a model can learn about a day and lose on a new one; the probe's "
        "validation and test accuracy show whether it does. The Minsight image appears as it is (the `none` and "
        "`training_mean` readings of `Config.image_reference` differ from it by a per-pixel constant, which "
        "standardising "
        "each dimension removes) and minus its session's no-contact reference (`session`); optical flow is "
        "computed from "
        "the frames under every reading.",
        "",
        table(doc),
    ]
    if doc["probe_missing"]:
        lines += [f"Probe columns: {doc['probe_missing']}.", ""]
    lines += image_weighting(doc)
    return "\n".join(lines)
