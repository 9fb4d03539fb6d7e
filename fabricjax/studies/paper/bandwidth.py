"""PSD bandwidth (the paper's Table bandwidth_classification): 2.5 / 10 / 15 / 24 kHz.

    python -m experiments.bandwidth --seeds=5
    python -m experiments.bandwidth --seeds=5 --rows=2.5,15

Input: the internal microphone (Minsound) alone, the setting of the paper's 15 kHz row, which
equals its internal-audio ablation row (95.06 ± 1.85). The PSDs are loaded once at the widest
bandwidth chosen and cut per row to the bins at or below its bandwidth (`data.narrow`, `welch.n_bins`). Reports
validation
accuracy (the best-validation epoch's) and test accuracy, beside the paper's, the paper's two
claims about the table as a findings checklist (`checklist`) and accuracy against bandwidth with
every seed's point (results/bandwidth.png). On recorded data (`--data_dir`) the rows are compared
with each other instead (`documents.recorded`), and the PSD bins are those at its microphone's rate.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from fabricjax.config import MODALITY_NAMES
from fabricjax.features import welch
from fabricjax.reporting import plots, results_files, stats
from fabricjax.store import archive, dataset_index
from fabricjax.studies.machinery import documents, findings, loading, runner
from fabricjax.studies.machinery.rows import RowSpec
from fabricjax.studies.machinery.trained import TrainingRun

TITLE, PAPER = (
    "PSD bandwidth",
    "Table bandwidth_classification",
)  # how results name the study, and what of the paper it reproduces

MODALITIES = ("internal",)
SPLITS = ("val", "test")  # the splits the table reports


def row_name(khz: float) -> str:
    return f"{khz:g}"


def _row(khz: float, val_mean: float, val_sd: float, test_mean: float, test_sd: float) -> RowSpec:
    """The row of bandwidth `khz` and the paper's validation and test accuracy [%] (5 seeds)."""
    paper = {"val_mean": val_mean, "val_sd": val_sd, "test_mean": test_mean, "test_sd": test_sd}
    return RowSpec(row_name(khz), {"modalities": MODALITIES, "bandwidth_khz": khz}, f"{khz:g} kHz", paper)


# The paper's Table bandwidth_classification.
ROWS = (
    _row(2.5, 92.43, 1.13, 89.87, 3.31),
    _row(10.0, 97.45, 1.17, 93.07, 3.33),
    _row(15.0, 97.75, 1.62, 95.06, 1.85),
    _row(24.0, 98.20, 1.39, 91.94, 2.68),
)


def document(trained: TrainingRun, chosen: Sequence[RowSpec]) -> dict[str, Any]:
    """Every row's PSD bins beside the paper's, with the class each seed collapsed to on the
    validation and test splits (`findings.collapsed`); both splits' majority class
    (`findings.majority`) and the microphone read."""
    sets = trained.dataset.sets
    test = sets["test"]
    recorded = trained.dataset.recorded
    out_rows = []
    for r in chosen:
        khz = r.settings["bandwidth_khz"]
        row = trained.rows[r.name]
        out_rows.append(
            {
                "name": r.name,
                "bandwidth_khz": khz,
                "psd_bins": welch.n_bins(khz, test.rates.get("internal", archive.AUDIO_RATE)),
                **({} if recorded else {"paper": dict(r.paper)}),
                "collapsed": {s: findings.collapsed(row.predictions(s), sets[s].labels["fabric"]) for s in SPLITS},
                **row.doc(["test"]),
            }
        )
    mic = microphone(trained.dataset)
    majority = {s: findings.majority(sets[s].labels["fabric"]) for s in SPLITS}
    return {
        "modalities": list(MODALITIES),
        "microphone": mic,
        "rows": out_rows,
        "majority": majority,
    }


def figures(doc: dict[str, Any], results: Path) -> list[Path]:
    """results/bandwidth.png (`plot`), drawn from the results JSON."""
    return [plot(results / "bandwidth.png", doc["rows"], doc["microphone"])]


def checklist(acc: dict[str, dict[str, np.ndarray]]) -> list[findings.Finding]:
    """The paper's claims about the bandwidth table, as predicates over per-seed accuracies
    (`acc`: row name, e.g. "15", -> {"val": per-seed, "test": per-seed} in [0, 1]; rows not run
    are skipped)."""
    low, mid, full = row_name(2.5), row_name(15.0), row_name(24.0)
    claim = "test accuracy at 15 kHz is at least that at 2.5 kHz (the band above 2.5 kHz carries fabric cues)"
    out = [
        findings.missing(claim, [mid, low], acc)
        or findings.at_least(claim, ("15 kHz test", acc[mid]["test"]), ("2.5 kHz test", acc[low]["test"]))
    ]
    claim = "24 kHz overfits: its validation accuracy is at least 15 kHz's while its test accuracy is not higher"
    if not (f := findings.missing(claim, [full, mid], acc)):
        val = findings.at_least(claim, ("24 kHz val", acc[full]["val"]), ("15 kHz val", acc[mid]["val"]))
        test = findings.at_least(claim, ("15 kHz test", acc[mid]["test"]), ("24 kHz test", acc[full]["test"]))
        f = findings.Finding(claim, val.holds and test.holds, f"{val.evidence}. {test.evidence}")
    out.append(f)
    return out


def microphone(ds: loading.Dataset) -> str:
    """The microphone the rows read, as the data names it: Minsound on the hand's simulated data,
    on recorded data the name its meta gives the microphone feeding the internal input (a rig's
    own, not the paper's)."""
    if not ds.recorded:
        return MODALITY_NAMES["internal"]
    lay = archive.layout(dataset_index.load_index(ds.folder, ds.workdir).entries[0].meta)
    return lay.mics[lay.mic("internal")].name


def plot(path, rows: Sequence[dict[str, Any]], microphone: str):
    """Validation and test accuracy of `microphone` against bandwidth: every seed, our means, the
    paper's means (none on recorded data)."""
    khz = [r["bandwidth_khz"] for r in rows]
    series = {
        split: (
            [100 * np.asarray(r["accuracy"][split]["fabric"]) for r in rows],
            [r["paper"][f"{split}_mean"] for r in rows] if "paper" in rows[0] else None,
        )
        for split in ("val", "test")
    }
    return plots.plot_against_bandwidth(path, khz, series, microphone)


def table(
    rows: Sequence[dict[str, Any]], majority: Mapping[str, Mapping[str, Any] | None], recorded: bool = False
) -> str:
    """Validation and test accuracy per bandwidth, flagged where seeds collapsed (each row's
    "collapsed"), each beside its split's `majority` class and the paper's; on recorded data test
    accuracy beside the best row's instead."""
    val = [stats.mean_sd(100 * np.asarray(r["accuracy"]["val"]["fabric"])) for r in rows]
    test = [stats.mean_sd(100 * np.asarray(r["accuracy"]["test"]["fabric"])) for r in rows]
    gaps = documents.best_gaps([m for m, _ in test])
    body = []
    for r, v, t, gap in zip(rows, val, test, gaps):
        ours = {
            s: f"{m:.2f} ± {sd:.2f}{findings.collapse_text(r['collapsed'][s])}" for s, (m, sd) in zip(SPLITS, (v, t))
        }
        base = {s: findings.majority_cell(majority[s]) for s in SPLITS}
        if recorded:
            compared = [ours["val"], base["val"], ours["test"], base["test"], gap]
        else:
            p = r["paper"]
            compared = [
                ours["val"],
                base["val"],
                f"{p['val_mean']:.2f} ± {p['val_sd']:.2f}",
                f"{v[0] - p['val_mean']:+.2f}",
                ours["test"],
                base["test"],
                f"{p['test_mean']:.2f} ± {p['test_sd']:.2f}",
                f"{t[0] - p['test_mean']:+.2f}",
            ]
        body.append([f"{r['bandwidth_khz']:g}", r["psd_bins"], *compared, f"{r['wall_s']:.1f}"])
    compared = (
        ["Val [%]", "Majority class, val [%]", "Test [%]", "Majority class, test [%]", documents.BEST_GAP]
        if recorded
        else [
            "Val [%] (ours)",
            "Majority class, val [%]",
            "Val [%] (paper)",
            "Val diff [pp]",
            "Test [%] (ours)",
            "Majority class, test [%]",
            "Test [%] (paper)",
            "Test diff [pp]",
        ]
    )
    return results_files.markdown_table(["Bandwidth [kHz]", "PSD bins", *compared, "Train wall time [s]"], body)


def markdown(doc: dict[str, Any]) -> str:
    recorded = documents.recorded(doc)
    inputs = (
        f"its microphone `{doc['microphone']}` only"
        if recorded
        else "Minsound only; the paper's 15 kHz row equals its internal-audio ablation row"
    )
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc),
        f"Inputs: {' + '.join(doc['modalities'])} ({inputs}). Validation accuracy is that of the "
        f"best-validation epoch, "
        "the model every test number uses.",
        "",
        table(doc["rows"], doc["majority"], recorded),
        findings.baseline_note(),
        "",
    ]
    lines += findings.claims_markdown(doc)
    lines += ["Accuracy against bandwidth, every seed: `bandwidth.png`.", ""]
    return "\n".join(lines)


STUDY = runner.Study(
    "bandwidth",
    ROWS,
    n_seeds=5,
    eval_splits=("test",),
    split_names=loading.TRAIN_VAL_TEST,
    document=document,
    checklist=lambda doc: checklist(
        {r["name"]: {s: np.asarray(r["accuracy"][s]["fabric"]) for s in ("val", "test")} for r in doc["rows"]}
    ),
    markdown=markdown,
    module=__name__,
    figures=figures,
    choose_rows="choose bandwidths with --rows (e.g. 2.5,15)",
)
run = STUDY.run  # every study module has `run`: the training studies through `runner.run_study`
