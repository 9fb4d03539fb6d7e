"""Robustness to cafe noise (the paper's Table new_noise_results): trained in the lab, tested in a cafe.

    python -m experiments.noise --seeds=10

Rows: Minsound; + proprioception; + palm microphone. Every row is trained on the lab training
days and evaluated on the cafe split (and, for reference, the lab test day). Each row is compared
with the preceding one by Wilcoxon signed-rank tests on the cafe split, paired per seed (exact
over 10 seeds: p >= 2 / 2^10 = 0.002) and per cafe sequence pooled over seeds (`common.paired_tests`).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from fabricjax import paper_tables, report, stats
from fabricjax.studies import common

SPLIT = "cafe"
ROWS = tuple(("+".join(mods), mods, mean, sd, p) for mods, mean, sd, p in paper_tables.NOISE)


def run(
    *,
    n_seeds: int = 10,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    workdir=None,
    data_dir=None,
    results="results",
    command: str | None = None,
) -> dict[str, Any]:
    """Train the rows, test on the cafe split and write results/noise.{md,json}; returns the JSON."""
    overrides = dict(overrides or {})
    chosen = common.select_rows(ROWS, rows, name=lambda r: r[0])
    seeds = common.seed_list(n_seeds)
    configs = [common.study_config(preset, **{**overrides, "modalities": mods}) for _, mods, *_ in chosen]
    ds = common.load_for_rows(configs, data_dir=data_dir, workdir=workdir, split_names=(*common.TRAIN_VAL_TEST, SPLIT))
    if len(ds.sets[SPLIT]) == 0:
        raise ValueError(f"the dataset in {ds.folder} has no cafe-condition trials to test on")
    labels = ds.sets[SPLIT].labels["fabric"]
    progress = common.Progress("noise", len(chosen))
    out_rows, previous = [], None
    for (name, mods, mean, sd, p), config in zip(chosen, configs):
        progress.start(name)
        row = common.train_row(name, config, ds.sets, seeds, [SPLIT, "test"], log_dir=common.logs_dir("noise", name, workdir))
        progress.finish(name, row.seconds, f"{SPLIT} {stats.format_mean_sd(row.accuracy(SPLIT))} %")
        tests = common.paired_tests(previous, row, SPLIT, labels) if previous is not None else {}
        out_rows.append({
            "name": name, "modalities": list(mods),
            "paper": {"mean": mean, "sd": sd, "p": p},
            "against": previous.name if previous is not None else None,
            "wilcoxon": {k: common.wilcoxon_doc(v) for k, v in tests.items()} or None,
            **common.row_doc(row, [SPLIT, "test"]),
        })
        previous = row
    doc = {
        "study": "noise",
        "command": command or common.command_line(),
        "preset": preset,
        "seeds": list(seeds),
        "machine": report.machine(),
        "dataset": common.dataset_doc(ds),
        "train_s": sum(r["wall_s"] for r in out_rows),
        "rows": out_rows,
        "cafe_samples": common.samples_doc(ds.sets[SPLIT]),
    }
    common.write_outputs(results, "noise", markdown(doc), doc)
    return doc


def _p(w: dict[str, Any] | None) -> str:
    return "–" if w is None else f"{w['p_value']:.4g} (floor {w['min_attainable_p']:.2g}, {w['method']})"


def table(rows: Sequence[dict[str, Any]]) -> str:
    body = []
    for r in rows:
        cafe = stats.mean_sd(100 * np.asarray(r["accuracy"][SPLIT]["fabric"]))
        lab = stats.mean_sd(100 * np.asarray(r["accuracy"]["test"]["fabric"]))
        w = r["wilcoxon"] or {}
        body.append([
            " + ".join(r["modalities"]),
            f"{cafe[0]:.2f} ± {cafe[1]:.2f}",
            f"{r['paper']['mean']:.2f} ± {r['paper']['sd']:.2f}",
            f"{cafe[0] - r['paper']['mean']:+.2f}",
            _p(w.get("per_seed")),
            _p(w.get("per_sample")),
            r["paper"]["p"] or "–",
            f"{lab[0]:.2f} ± {lab[1]:.2f}",
            f"{r['wall_s']:.1f}",
        ])
    header = [
        "Modalities", "Cafe test [%] (ours)", "Paper [%]", "Ours − paper [pp]", "p per seed", "p per sequence",
        "Paper p", "Lab test [%] (ours)", "Train wall time [s]",
    ]
    return report.markdown_table(header, body)


def markdown(doc: dict[str, Any]) -> str:
    lines = ["# Cafe noise (the paper's Table new_noise_results)", "", common.header_markdown(doc), table(doc["rows"]), "Tests, each row against the preceding one on the cafe split:", ""]
    for r in doc["rows"]:
        for w in (r["wilcoxon"] or {}).values():
            lines.append(f"- {r['name']} vs {r['against']}: {w['describe']}")
    lines += [
        "",
        "The per-seed test is the one comparable to the paper's; the per-sequence test treats sequences of one "
        "trial and of different seeds as independent, which they are not: read it as descriptive.",
        "",
    ]
    return "\n".join(lines)
