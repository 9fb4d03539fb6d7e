"""Declared calibrations: an estimate fitted to the one measurement of the paper that pins it.

    python -m experiments.calibrate --results=results

An estimate of the simulator (`sim.estimates`) that one measurement of the paper pins says so in
the registry (`Estimate.calibrated`): the measurement, where the paper gives it, and which of our
numbers is matched to it. This study searches the estimate's declared range for the value whose
number matches the measurement: every point it tries simulates the default preset's dataset with
the estimate set there (its own workspace under <workspace>/calibration/, audio and joints only,
removed once measured), trains the matched row as its study would, and measures. The search
brackets the target between the range's ends, then narrows the bracket by interpolating (regula
falsi, Illinois variant) until the measured number is within `TOLERANCE_PP` of the target or the
bracket is narrower than `RESOLUTION`'s share of the range. The fitted value is the point tried
whose number came closest: a measured point, never an interpolated one. Resumable: each point's
measurement is kept in <workspace>/calibration/<estimate>/points.json.

The registry's value is then set to the fitted value by hand (a test checks that they agree);
the number matched is a calibration from then on, no longer a finding, and every other number of
the same table is a prediction. One estimate per measurement: the registry refuses a second.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from fabricjax.errors import UserError
from fabricjax.reporting import results_files
from fabricjax.sim import estimates, scene
from fabricjax.store import workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import cafe, documents, row_training, runner

STUDY = "calibration"
TOLERANCE_PP = 1.0  # close enough: well within the paper's seed SD of the cafe accuracy (5.05 pp)
RESOLUTION = 0.02  # stop when the bracket is narrower than this share of the declared range
MAX_POINTS = 8
PRESET = "default"
SEEDS = cafe.N_SEEDS  # the noise study's


def minsound_cafe_drop(point: Path) -> dict[str, Any]:
    """The noise study's Minsound row on the dataset of the estimates in force, trained with its
    seeds in the workspace `point` as the noise study trains it (its checkpoints kept under its
    name): lab test and cafe accuracy per seed, and the drop in pp."""
    row = cafe.ROWS[0]
    trained = row_training.train_rows(
        "noise",
        [(row.name, row.config(PRESET, {}))],
        runner.seed_list(SEEDS),
        eval_splits=cafe.SPLITS,
        split_names=cafe.SPLIT_NAMES,
        workdir=point,
        checkpoints=True,
        label=lambda name: row.label,
        summary=cafe.summary,
        check=cafe.has_cafe_trials,
        data_names=True,
    )
    test, cafe_acc = (100 * trained.rows[row.name].accuracy(s) for s in ("test", cafe.SPLIT))
    return {
        "test": test.tolist(),
        "cafe": cafe_acc.tolist(),
        "number": float(test.mean() - cafe_acc.mean()),
        "train_s": trained.train_s,
    }


# What each calibration's `fitted_on` measures: estimate name -> measuring function.
MEASURE: dict[str, Callable[[Path], dict[str, Any]]] = {"SHELL_TL_MAX_DB": minsound_cafe_drop}


def calibrated() -> list[estimates.Estimate]:
    """The registry's calibrated estimates, each measurement used once."""
    out = [e for e in estimates.ESTIMATES.values() if e.calibrated is not None]
    seen: dict[str, str] = {}
    for e in out:
        if e.calibrated.measurement in seen:
            raise UserError(
                f"estimates {seen[e.calibrated.measurement]} and {e.name} are both fitted to "
                f"{e.calibrated.measurement!r}: one estimate per measurement"
            )
        seen[e.calibrated.measurement] = e.name
    for e in out:
        if e.name not in MEASURE:
            raise UserError(
                f"estimate {e.name} is declared calibrated, but nothing measures {e.calibrated.fitted_on!r}"
            )
    return out


class _Points:
    """The points measured so far for one estimate, kept on disk after each."""

    def __init__(self, folder: Path, e: estimates.Estimate):
        self.path = folder / "points.json"
        # every other magnitude of the simulator: a point measured under others measures something else
        self.others = scene.magnitudes(besides=e.name)
        kept = json.loads(self.path.read_text()) if self.path.is_file() else {}
        self.points: dict[str, dict[str, Any]] = kept.get("points", {}) if kept.get("others") == self.others else {}

    def measure(self, e: estimates.Estimate, value: float, folder: Path, log: Callable[[str], None]) -> float:
        key = f"{value:.6g}"
        if key not in self.points:
            point = folder / f"{e.name}={key}"
            log(
                f"{e.name} = {key}: simulating the {PRESET} preset and training ({len(self.points) + 1} of "
                f"at most {MAX_POINTS})"
            )
            t0 = time.perf_counter()
            estimates.override({e.name: value})
            try:
                result = MEASURE[e.name](point)
            finally:
                estimates.override({})
            self.points[key] = {
                "value": value,
                **result,
                "wall_s": time.perf_counter() - t0,
                "code": results_files.git_commit(),
            }
            results_files.write_json(self.path, {"others": self.others, "points": self.points})
            shutil.rmtree(
                point, ignore_errors=True
            )  # the point's dataset, features and checkpoints: its numbers are kept
        number = self.points[key]["number"]
        log(f"{e.name} = {key}: {number:.2f} (target {e.calibrated.paper_value:.2f})")
        return number


def fit(e: estimates.Estimate, folder: Path, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Search `e`'s range for the value whose measured number is the paper's (module docstring)."""
    points = _Points(folder, e)
    target = e.calibrated.paper_value
    a, b = e.low, e.high
    fa, fb = points.measure(e, a, folder, log) - target, points.measure(e, b, folder, log) - target
    bracketed = fa * fb <= 0
    side = 0
    while (
        bracketed
        and len(points.points) < MAX_POINTS
        and min(abs(fa), abs(fb)) > TOLERANCE_PP
        and abs(b - a) > RESOLUTION * (e.high - e.low)
    ):
        c = (a * fb - b * fa) / (fb - fa)
        fc = points.measure(e, c, folder, log) - target
        if fc * fb < 0:
            a, fa = b, fb
            if side == -1:
                fa /= 2  # Illinois: halve the stale end's weight so the bracket shrinks from both sides
            side = -1
        else:
            if side == 1:
                fa /= 2
            side = 1
        b, fb = c, fc
    tried = sorted(points.points.values(), key=lambda p: p["value"])
    best = min(tried, key=lambda p: abs(p["number"] - target))
    return {
        "estimate": e.name,
        "registry_value": e.value,
        "range": [e.low, e.high],
        "measurement": e.calibrated.measurement,
        "paper_value": target,
        "where": e.calibrated.where,
        "fitted_on": e.calibrated.fitted_on,
        "bracketed": bracketed,
        "fitted_value": best["value"],
        "fitted_number": best["number"],
        "points": tried,
    }


def run(*, where: Location = Location()) -> dict[str, Any]:
    """Fit every calibrated estimate; writes results/calibration.{md,json} and returns the JSON."""
    folder = workspace.root(where.workdir) / "calibration"
    t0 = time.perf_counter()
    fits = [fit(e, folder / e.name) for e in calibrated()]
    doc = {
        **documents.header(
            STUDY,
            module=__name__,
            command=where.command,
            preset=PRESET,
            seeds=list(range(SEEDS)),
            wall_s=time.perf_counter() - t0,
        ),
        "fits": fits,
    }
    return results_files.write(where.results_dir(), doc, markdown)


def markdown(doc: dict[str, Any]) -> str:
    lines = [
        "# Declared calibrations: estimates fitted to one measurement of the paper each",
        "",
        documents.header_markdown(doc),
        "",
    ]
    for f in doc["fits"]:
        lines += [
            f"## {f['estimate']}",
            "",
            f"- measurement: {f['measurement']}, {f['paper_value']:.2f} pp ({f['where']})",
            f"- our number matched to it: {f['fitted_on']}",
            f"- declared range: {f['range'][0]:g} to {f['range'][1]:g}; the registry holds {f['registry_value']:g}",
            f"- fitted: **{f['fitted_value']:.4g}**, where our number is {f['fitted_number']:.2f} pp"
            if f["bracketed"]
            else f"- no value in the declared range reaches {f['paper_value']:.2f} pp: the closest is "
            f"**{f['fitted_value']:.4g}**, the range's end "
            f"({f['fitted_number']:.2f} pp), which is the calibrated value. The other "
            f"{f['paper_value'] - f['fitted_number']:.2f} pp are not this "
            "estimate's to explain: [sensitivity.md](sensitivity.md) shows what else moves the number",
            "",
            "Every point tried (measured by the code named beside it; a point is kept while every other "
            "magnitude of the simulator is unchanged):",
            "",
            results_files.markdown_table(
                ["Value", "Lab test [%]", "Cafe [%]", "Drop [pp]", "Measured by"],
                [
                    [
                        f"{p['value']:.4g}",
                        f"{np.mean(p['test']):.2f}",
                        f"{np.mean(p['cafe']):.2f}",
                        f"{p['number']:.2f}",
                        p["code"],
                    ]
                    for p in f["points"]
                ],
            ),
            "",
        ]
    lines.append(
        "The fitted number is a calibration, not a finding; every other number of its table is a prediction "
        "(results/noise.md)."
    )
    return "\n".join(lines) + "\n"
