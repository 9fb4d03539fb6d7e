"""The paper's modality ablation (Table ablation_table): 12 transformer rows and the TCN row.

    python -m experiments.ablation --seeds=5                          # default preset, whole table
    python -m experiments.ablation --seeds=5 --rows=internal,internal+external
    python -m experiments.ablation --preset=paper --backbone=tcn      # any sweep dimension by flag

Each row trains all seeds in one vmapped program and reports mean ± SD test accuracy beside the
paper's number and the difference. Internal audio is compared with internal + palm audio by
Wilcoxon signed-rank tests (per seed and per test sequence, see `common.paired_tests`), and the
proprioception-only and flow-only models' confusion matrices are drawn (results/ablation_confusion.png).
The simulator is the same for every row: differences from the paper are findings, not tuning targets.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from fabricjax import paper_tables, plots, report, stats
from fabricjax.studies import common

WILCOXON_PAIR = ("internal", "internal+external")  # (baseline, compared), as in the paper
CONFUSION_ROWS = ("proprio", "flow")
NAMES = {"image": "Minsight image", "flow": "optical flow", "internal": "Minsound", "external": "palm mic", "proprio": "proprioception"}


def display_name(row_name: str) -> str:
    """How the table names a row: 'Minsound + palm mic', 'TCN: Minsound + palm mic + proprioception'."""
    r = next(r for r in paper_tables.ABLATION if r.name == row_name)
    text = " + ".join(NAMES[m] for m in r.modalities)
    return f"TCN: {text}" if r.backbone == "tcn" else text


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
    """Train the chosen rows (all by default) and write results/ablation.{md,json}; returns the JSON."""
    overrides = dict(overrides or {})
    chosen = common.select_rows(paper_tables.ABLATION, rows)
    seeds = common.seed_list(n_seeds)
    configs = [common.study_config(preset, **{"backbone": r.backbone, **overrides, "modalities": r.modalities}) for r in chosen]
    ds = common.load_for_rows(configs, data_dir=data_dir, workdir=workdir, split_names=common.TRAIN_VAL_TEST)
    progress = common.Progress("ablation", len(chosen), [common.relative_cost(c) for c in configs])
    trained = {}
    for r, config in zip(chosen, configs):
        progress.start(display_name(r.name))
        trained[r.name] = row = common.train_row(r.name, config, ds.sets, seeds, ["test"])
        progress.finish(display_name(r.name), row.seconds, f"test {stats.format_mean_sd(row.accuracy('test'))} %")

    test = ds.sets["test"]
    labels = test.labels["fabric"]
    base, compared = WILCOXON_PAIR
    tests = common.paired_tests(trained[base], trained[compared], "test", labels) if base in trained and compared in trained else {}
    out = common.results_path(results)
    panels = [
        (f"{NAMES[n]} only, {len(seeds)} seeds pooled", np.tile(labels, len(seeds)), trained[n].predictions("test").ravel())
        for n in CONFUSION_ROWS
        if n in trained
    ]
    figure = plots.plot_confusions(out / "ablation_confusion.png", panels) if panels else None

    doc = {
        "study": "ablation",
        "command": command or common.command_line(),
        "preset": preset,
        "seeds": list(seeds),
        "machine": report.machine(),
        "dataset": common.dataset_doc(ds),
        "train_s": sum(t.seconds for t in trained.values()),
        "rows": [
            {
                "name": r.name,
                "backbone": trained[r.name].config.backbone,
                "modalities": list(r.modalities),
                "paper_mean": r.paper_mean,
                "paper_sd": r.paper_sd,
                **common.row_doc(trained[r.name], ["test"]),
            }
            for r in chosen
        ],
        "test_samples": common.samples_doc(test),
        "wilcoxon": {
            "baseline": base,
            "compared": compared,
            "paper_p": paper_tables.ABLATION_WILCOXON_P,
            **{k: common.wilcoxon_doc(v) for k, v in tests.items()},
        }
        if tests
        else None,
        "confusion_png": str(figure) if figure else None,
    }
    common.write_outputs(results, "ablation", markdown(doc), doc)
    return doc


def table(rows: Sequence[dict[str, Any]]) -> str:
    """Our accuracy beside the paper's, with the difference, one line per row."""
    body = []
    for r in rows:
        mean, sd = stats.mean_sd(100 * np.asarray(r["accuracy"]["test"]["fabric"]))
        body.append([
            "TCN" if r["backbone"] == "tcn" else "Transformer",
            " + ".join(NAMES[m] for m in r["modalities"]),
            f"{mean:.2f} ± {sd:.2f}",
            f"{r['paper_mean']:.2f} ± {r['paper_sd']:.2f}",
            f"{mean - r['paper_mean']:+.2f}",
            f"{r['wall_s']:.1f}",
        ])
    header = ["Backbone", "Modalities", f"Test accuracy [%] (ours, {len(rows[0]['seeds'])} seeds)", "Paper [%]", "Ours − paper [pp]", "Train wall time [s]"]
    return report.markdown_table(header, body)


def markdown(doc: dict[str, Any]) -> str:
    lines = [
        "# Modality ablation (the paper's Table ablation_table)",
        "",
        common.header_markdown(doc),
        table(doc["rows"]),
    ]
    w = doc["wilcoxon"]
    if w:
        lines += [
            f"## Wilcoxon signed-rank: {w['compared']} against {w['baseline']} (paper: p = {w['paper_p']})",
            "",
            f"- {w['per_seed']['describe']}",
            f"- {w['per_sample']['describe']}",
            "",
            "The per-seed test is the one comparable to the paper's; its smallest attainable p is the floor above. "
            "The per-sequence test treats sequences of one trial and of different seeds as independent, "
            "which they are not: read it as descriptive.",
            "",
        ]
    if doc["confusion_png"]:
        lines += ["Confusion matrices (proprioception only, optical flow only): `ablation_confusion.png`.", ""]
    lines += [
        "The simulator is the same for every row (never tuned per row): differences from the paper are findings.",
        "",
    ]
    return "\n".join(lines)
