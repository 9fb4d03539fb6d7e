"""PSD bandwidth (the paper's Table bandwidth_classification): 2.5 / 10 / 15 / 24 kHz.

    python -m experiments.bandwidth --seeds=5
    python -m experiments.bandwidth --seeds=5 --rows=2.5,15

Input: the internal microphone (Minsound) alone, the setting of the paper's 15 kHz row, which
equals its internal-audio ablation row (95.06 ± 1.85). The PSDs are loaded once at 24 kHz and
truncated per row to the bins at or below the bandwidth (`welch.n_bins`). Reports validation
accuracy (the best-validation epoch's) and test accuracy, beside the paper's, the paper's two
claims about the table as a findings checklist (`checklist`) and accuracy against bandwidth with
every seed's point (results/bandwidth.png).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Sequence

import numpy as np

from fabricjax import data, findings, paper_tables, plots, report, stats
from fabricjax.config import AUDIO_MODALITIES
from fabricjax.features import welch
from fabricjax.errors import UserError
from fabricjax.studies import common

MODALITIES = ("internal",)


def row_name(khz: float) -> str:
    return f"{khz:g}"


def truncate(sets: dict[str, data.SequenceSet], khz: float) -> dict[str, data.SequenceSet]:
    """The same sequences with every PSD cut to the bins at or below `khz`."""
    n = welch.n_bins(khz)
    return {
        k: dataclasses.replace(s, inputs={m: a[..., :n] if m in AUDIO_MODALITIES else a for m, a in s.inputs.items()})
        for k, s in sets.items()
    }


def run(
    *,
    n_seeds: int = 5,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    workdir=None,
    data_dir=None,
    results="results",
    command: str | None = None,
) -> dict[str, Any]:
    """Train one row per bandwidth and write results/bandwidth.{md,json}; returns the JSON."""
    overrides = dict(overrides or {})
    if "bandwidth_khz" in overrides:
        raise UserError("the bandwidth study sweeps the bandwidth itself; choose bandwidths with rows (e.g. 2.5,15)")
    chosen = common.select_rows(sorted(paper_tables.BANDWIDTH), rows, name=row_name)
    seeds = common.seed_list(n_seeds)
    base = common.study_config(preset, **{**overrides, "modalities": MODALITIES})
    ds = common.load_dataset(dataclasses.replace(base, bandwidth_khz=max(paper_tables.BANDWIDTH)), data_dir=data_dir, workdir=workdir, split_names=common.TRAIN_VAL_TEST)
    progress = common.Progress("bandwidth", len(chosen))
    out_rows = []
    for khz in chosen:
        name = row_name(khz)
        progress.start(f"{name} kHz")
        row = common.train_row(
            name, dataclasses.replace(base, bandwidth_khz=khz), truncate(ds.sets, khz), seeds, ["test"],
            log_dir=common.logs_dir("bandwidth", name, workdir),
        )
        progress.finish(f"{name} kHz", row.seconds, f"test {stats.format_mean_sd(row.accuracy('test'))} %")
        vm, vs, tm, ts = paper_tables.BANDWIDTH[khz]
        out_rows.append({
            "name": name, "bandwidth_khz": khz, "psd_bins": welch.n_bins(khz),
            "paper": {"val_mean": vm, "val_sd": vs, "test_mean": tm, "test_sd": ts},
            **common.row_doc(row, ["test"]),
        })
    doc = {
        "study": "bandwidth",
        "command": command or common.command_line(),
        "preset": preset,
        "modalities": list(base.modalities),
        "seeds": list(seeds),
        "machine": report.machine(),
        "dataset": common.dataset_doc(ds),
        "train_s": sum(r["wall_s"] for r in out_rows),
        "rows": out_rows,
        "test_samples": common.samples_doc(ds.sets["test"]),
    }
    doc["findings"] = [f.to_json() for f in checklist({r["name"]: {s: np.asarray(r["accuracy"][s]["fabric"]) for s in ("val", "test")} for r in out_rows})]
    doc["png"] = str(plot(common.results_path(results) / "bandwidth.png", out_rows))
    common.write_outputs(results, "bandwidth", markdown(doc), doc)
    return doc


def checklist(acc: dict[str, dict[str, np.ndarray]]) -> list[findings.Finding]:
    """The paper's claims about the bandwidth table, as predicates over per-seed accuracies
    (`acc`: row name, e.g. "15", -> {"val": per-seed, "test": per-seed} in [0, 1]; rows not run
    are skipped)."""
    low, mid, full = row_name(2.5), row_name(15.0), row_name(24.0)
    claim = "test accuracy at 15 kHz is at least that at 2.5 kHz (the band above 2.5 kHz carries fabric cues)"
    out = [findings.missing(claim, [mid, low], acc) or findings.at_least(claim, ("15 kHz test", acc[mid]["test"]), ("2.5 kHz test", acc[low]["test"]))]
    claim = "24 kHz overfits: its validation accuracy is at least 15 kHz's while its test accuracy is not higher"
    if not (f := findings.missing(claim, [full, mid], acc)):
        val = findings.at_least(claim, ("24 kHz val", acc[full]["val"]), ("15 kHz val", acc[mid]["val"]))
        test = findings.at_least(claim, ("15 kHz test", acc[mid]["test"]), ("24 kHz test", acc[full]["test"]))
        f = findings.Finding(claim, val.holds and test.holds, f"{val.evidence}. {test.evidence}")
    out.append(f)
    return out


def plot(path, rows: Sequence[dict[str, Any]]):
    """Validation and test accuracy against bandwidth: every seed, our means, the paper's means."""
    khz = [r["bandwidth_khz"] for r in rows]
    series = {
        split: (
            [100 * np.asarray(r["accuracy"][split]["fabric"]) for r in rows],
            [r["paper"][f"{split}_mean"] for r in rows],
        )
        for split in ("val", "test")
    }
    return plots.plot_against_bandwidth(path, khz, series)


def table(rows: Sequence[dict[str, Any]]) -> str:
    body = []
    for r in rows:
        val = stats.mean_sd(100 * np.asarray(r["accuracy"]["val"]["fabric"]))
        test = stats.mean_sd(100 * np.asarray(r["accuracy"]["test"]["fabric"]))
        p = r["paper"]
        body.append([
            f"{r['bandwidth_khz']:g}", r["psd_bins"],
            f"{val[0]:.2f} ± {val[1]:.2f}", f"{p['val_mean']:.2f} ± {p['val_sd']:.2f}", f"{val[0] - p['val_mean']:+.2f}",
            f"{test[0]:.2f} ± {test[1]:.2f}", f"{p['test_mean']:.2f} ± {p['test_sd']:.2f}", f"{test[0] - p['test_mean']:+.2f}",
            f"{r['wall_s']:.1f}",
        ])
    header = [
        "Bandwidth [kHz]", "PSD bins", "Val [%] (ours)", "Val [%] (paper)", "Val diff [pp]",
        "Test [%] (ours)", "Test [%] (paper)", "Test diff [pp]", "Train wall time [s]",
    ]
    return report.markdown_table(header, body)


def markdown(doc: dict[str, Any]) -> str:
    return "\n".join([
        "# PSD bandwidth (the paper's Table bandwidth_classification)",
        "",
        common.header_markdown(doc),
        f"Inputs: {' + '.join(doc['modalities'])} (Minsound only; the paper's 15 kHz row equals its internal-audio "
        "ablation row). Validation accuracy is that of the best-validation epoch, the model every test number uses.",
        "",
        table(doc["rows"]),
        "## Findings checklist (the paper's claims about this table)",
        "",
        findings.markdown(doc["findings"]),
        "Accuracy against bandwidth, every seed: `bandwidth.png`.",
        "",
    ])
