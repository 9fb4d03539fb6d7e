"""Robustness to cafe noise (the paper's Table new_noise_results): trained in the lab, tested in a cafe.

    python -m experiments.noise --seeds=10

Rows: Minsound; + proprioception; + palm microphone. Every row is trained on the lab training
days and evaluated on the cafe split (and, for reference, the lab test day). Each row is compared
with the preceding one by Wilcoxon signed-rank tests on the cafe split, paired per seed (exact
over 10 seeds: p >= 2 / 2^10 = 0.002) and per cafe sequence pooled over seeds (`wilcoxon.paired_tests`).
The paper's claims about the table are checked by `checklist`; results/noise.png shows every
seed's lab and cafe accuracy per row. On recorded data (`--data_dir`, its cafe split) the rows are
compared with each other instead (`documents.recorded`), and the table, the tests and the figure
name each row by the data's names for its streams (`data.inputs_name`: the rig file's microphones
and joints); --rows still names rows by role (internal, internal+proprio, ...).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from fabricjax.reporting import plots, results_files, stats
from fabricjax.sim import estimates
from fabricjax.studies.machinery import cafe, documents, findings, runner, wilcoxon
from fabricjax.studies.machinery.cafe import ROWS, SPLIT, SPLITS, display_name
from fabricjax.studies.machinery.rows import RowSpec
from fabricjax.studies.machinery.trained import TrainingRun

TITLE, PAPER = (
    "Cafe noise",
    "Table new_noise_results",
)  # how results name the study, and what of the paper it reproduces

SIGNIFICANCE = 0.05  # the level at which the checklist calls a per-seed Wilcoxon test significant


def document(trained: TrainingRun, chosen: Sequence[RowSpec]) -> dict[str, Any]:
    """Every row with its tests against the preceding row on the cafe split and the class each
    seed collapsed to on the cafe and lab test splits (`findings.collapsed`); both splits'
    majority class (`findings.majority`)."""
    sets = trained.dataset.sets
    labels = sets[SPLIT].labels["fabric"]
    recorded = trained.dataset.recorded
    out_rows, previous = [], None
    for r in chosen:
        row = trained.rows[r.name]
        tests = wilcoxon.paired_tests(previous, row, SPLIT, labels) if previous is not None else {}
        out_rows.append(
            {
                "name": r.name,
                "modalities": list(r.modalities),
                **({} if recorded else {"paper": dict(r.paper)}),
                "against": previous.name if previous is not None else None,
                "wilcoxon": {k: documents.wilcoxon_doc(v) for k, v in tests.items()} or None,
                "collapsed": {s: findings.collapsed(row.predictions(s), sets[s].labels["fabric"]) for s in SPLITS},
                **row.doc([SPLIT, "test"]),
            }
        )
        previous = row
    calibrated = [] if recorded else estimates.calibrated_in("noise")
    majority = {s: findings.majority(sets[s].labels["fabric"]) for s in SPLITS}
    return {
        "rows": out_rows,
        "majority": majority,
        "calibrated": calibrated,
    }


def figures(doc: dict[str, Any], results: Path) -> list[Path]:
    """results/noise.png (`plot`), drawn from the results JSON."""
    return [plot(results / "noise.png", doc["rows"], documents.stream_names(doc) if documents.recorded(doc) else None)]


def checklist(acc: dict[str, dict[str, np.ndarray]]) -> list[findings.Finding]:
    """The paper's claims about the cafe-noise table as predicates over per-seed accuracies
    (`acc`: row name -> {"cafe": per-seed, "test": per-seed (the lab test day)} in [0, 1], the same
    seeds in every row; rows not run are skipped). Each gain is tested for significance by the
    exact per-seed Wilcoxon test (two-sided, floor 2 / 2^n over n seeds), as the paper tests it."""
    minsound, proprio, palm = (r.name for r in ROWS)
    claim = "cafe noise lowers Minsound's accuracy against the lab test day"
    out = [
        findings.missing(claim, [minsound], acc)
        or findings.below(claim, ("cafe", acc[minsound][SPLIT]), ("lab test", acc[minsound]["test"]))
    ]
    for base, added, what in ((minsound, proprio, "proprioception"), (proprio, palm, "the palm mic")):
        claim = f"adding {what} raises cafe accuracy ({display_name(added)} > {display_name(base)})"
        out.append(
            findings.missing(claim, [added, base], acc)
            or findings.at_least(
                claim, (display_name(added), acc[added][SPLIT]), (display_name(base), acc[base][SPLIT]), strict=True
            )
        )
        claim = f"the gain from {what} on the cafe split is significant (per-seed Wilcoxon, p < {SIGNIFICANCE})"
        if not (f := findings.missing(claim, [added, base], acc)):
            w = stats.wilcoxon(
                acc[added][SPLIT],
                acc[base][SPLIT],
                pairing=f"per seed: cafe accuracy of the same seed, {len(acc[base][SPLIT])} seeds",
            )
            gain = findings.mean_pct(acc[added][SPLIT]) - findings.mean_pct(acc[base][SPLIT])
            f = findings.Finding(
                claim, bool(gain > 0 and w.p_value < SIGNIFICANCE), f"mean gain {gain:+.1f} pp; {w.describe()}"
            )
        out.append(f)
    return out


def plot(path, rows: Sequence[dict[str, Any]], names: Mapping[str, str] | None = None):
    """Lab-test and cafe accuracy per row, every seed a dot, the paper's cafe mean a tick (none on
    recorded data); rows named by `names` (recorded data: the data's names for its streams)."""
    series = {
        "test": ([100 * np.asarray(r["accuracy"]["test"]["fabric"]) for r in rows], [None] * len(rows)),
        SPLIT: (
            [100 * np.asarray(r["accuracy"][SPLIT]["fabric"]) for r in rows],
            [r["paper"]["mean"] if "paper" in r else None for r in rows],
        ),
    }
    groups = [display_name(r["name"], names).replace(" + ", "\n+ ") for r in rows]
    return plots.plot_seed_bars(
        path, groups, series, f"Trained in the lab, tested in a cafe ({len(rows[0]['seeds'])} seeds)"
    )


def _p(w: dict[str, Any] | None) -> str:
    return "–" if w is None else f"{w['p_value']:.4g} (floor {w['min_attainable_p']:.2g}, {w['method']})"


def table(
    rows: Sequence[dict[str, Any]],
    majority: Mapping[str, Mapping[str, Any] | None],
    recorded: bool = False,
    names: Mapping[str, str] | None = None,
) -> str:
    """Cafe accuracy per row, flagged where seeds collapsed (each row's "collapsed"), beside the
    cafe split's `majority` class and the paper's (on recorded data: beside the best row's), the
    tests against the preceding row, and the lab test day's accuracy beside its majority class;
    rows named by `names` (recorded data: the data's names for its streams) else the paper's sensors."""
    cafe = [stats.mean_sd(100 * np.asarray(r["accuracy"][SPLIT]["fabric"])) for r in rows]
    gaps = documents.best_gaps([m for m, _ in cafe])
    body = []
    for r, (mean, sd), gap in zip(rows, cafe, gaps):
        lab = stats.mean_sd(100 * np.asarray(r["accuracy"]["test"]["fabric"]))
        w = r["wilcoxon"] or {}
        tests = [_p(w.get("per_seed")), _p(w.get("per_sample"))]
        if recorded:
            compared = [gap, *tests]
        else:
            p = r["paper"]
            compared = [f"{p['mean']:.2f} ± {p['sd']:.2f}", f"{mean - p['mean']:+.2f}", *tests, p["p"] or "–"]
        body.append(
            [
                display_name(r["name"], names),
                f"{mean:.2f} ± {sd:.2f}{findings.collapse_text(r['collapsed'][SPLIT])}",
                findings.majority_cell(majority[SPLIT]),
                *compared,
                f"{lab[0]:.2f} ± {lab[1]:.2f}{findings.collapse_text(r['collapsed']['test'])}",
                findings.majority_cell(majority["test"]),
                f"{r['wall_s']:.1f}",
            ]
        )
    tests = ["p per seed", "p per sequence"]
    compared = [documents.BEST_GAP, *tests] if recorded else ["Paper [%]", "Ours − paper [pp]", *tests, "Paper p"]
    ours = "recorded data" if recorded else "ours"
    return results_files.markdown_table(
        [
            "Modalities",
            f"Cafe test [%] ({ours})",
            "Majority class, cafe [%]",
            *compared,
            f"Lab test [%] ({ours})",
            "Majority class, lab test [%]",
            "Train wall time [s]",
        ],
        body,
    )


def markdown(doc: dict[str, Any]) -> str:
    recorded, names = documents.recorded(doc), documents.stream_names(doc)
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc),
        table(doc["rows"], doc["majority"], recorded, names),
        findings.baseline_note(),
        "",
        "Tests, each row against the preceding one on the cafe split:",
        "",
    ]
    for r in doc["rows"]:
        for w in (r["wilcoxon"] or {}).values():
            lines.append(f"- {display_name(r['name'], names)} vs {display_name(r['against'], names)}: {w['describe']}")
    caveat = (
        "per-sequence test treats sequences of one trial and of different seeds as independent, which they are "
        "not: read it as descriptive."
    )
    lines += [
        "",
        f"The {caveat}" if recorded else f"The per-seed test is the one comparable to the paper's; the {caveat}",
        "",
    ]
    for c in doc.get("calibrated", []):
        lines += [
            f"**Calibrated, not a finding**: the simulator's estimate `{c['estimate']}` = {c['value']:g} is "
            f"fitted to {c['measurement']} "
            f"on {c['fitted_on']} ([calibration.md](calibration.md)), so that number is a calibration. Every "
            f"other number of this "
            "table is a prediction.",
            "",
        ]
    lines += findings.claims_markdown(doc)
    lines += ["Lab and cafe accuracy per row, every seed: `noise.png`.", ""]
    return "\n".join(lines)


STUDY = runner.Study(
    "noise",
    ROWS,
    n_seeds=cafe.N_SEEDS,
    eval_splits=SPLITS,
    split_names=cafe.SPLIT_NAMES,
    document=document,
    checklist=lambda doc: checklist(
        {r["name"]: {s: np.asarray(r["accuracy"][s]["fabric"]) for s in SPLITS} for r in doc["rows"]}
    ),
    markdown=markdown,
    module=__name__,
    figures=figures,
    summary=cafe.summary,
    check=cafe.has_cafe_trials,
)
run = STUDY.run  # every study module has `run`: the training studies through `runner.run_study`
