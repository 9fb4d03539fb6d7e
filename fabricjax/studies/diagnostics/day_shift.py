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
and counts the dimensions in which the day explains more than the fabric (`day_variation.day_led_dims`): the
numbers behind the sentence this page shares with the camera-frames page
(`camera_variation.RECONCILE`), which measures the image's difference in DN. Trials are every
lab trial of the training and test days (`loading.TRAIN_VAL_TEST`), in the classes of the data.
The probe's validation (whole trials of the training days) and test (the new day) accuracy per
input come from the probe's own results file in the same results folder (`python -m
experiments.probe`, which `reproduce` runs first); where it is missing or ran on
other data, the table says so instead of numbers.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from fabricjax.reporting import results_files
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import camera_variation, day_variation, documents, probing
from fabricjax.studies.machinery.day_variation import SHARES

TITLE, PAPER = "Day shift: what the fabric, the day and the trial explain in each input", "not in the paper"
ROWS = day_variation.ROWS  # what --rows and the plan choose from


def run(
    *,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    where: Location = Location(),
) -> dict[str, Any]:
    """The shares and the probe's gap for the chosen inputs (all by default); writes
    results/day_shift.{md,json} and returns the JSON."""
    shift = day_variation.measure(preset=preset, rows=rows, overrides=overrides, where=where)
    doc = {
        **documents.header(
            "day_shift",
            module=__name__,
            command=where.command,
            preset=preset,
            dataset=shift.dataset,
            study_s=shift.seconds,
        ),
        **shift.body,
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
    rows = [r for r in doc["rows"] if r["name"].removeprefix(probing.SESSION) == "image" and "shares_weighted" in r]
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
    session = next((r for r in rows if r["name"].startswith(probing.SESSION)), rows[-1])
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
