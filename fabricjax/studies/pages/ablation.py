"""The modality ablation's page and figures, drawn from its result (`results.Ablation`) as its
results JSON holds it: the table beside the paper's (or, on recorded data, row against row and
against each row's probe), the recipes, the fusion validation picks, the findings checklist, the
Wilcoxon tests, the confusion matrices and every row's time-to-accuracy curve.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from fabricjax.reporting import plots, results_files, stats
from fabricjax.sequences import data
from fabricjax.studies.machinery import documents, findings, recipe
from fabricjax.studies.machinery.ablation_rows import CONFUSION_ROWS, STEP_LAYERNORM, display_name
from fabricjax.studies.machinery.results import Ablation, AblationRow

TITLE, PAPER = "Modality ablation", "Table ablation_table"  # how results name the study, and what of the paper
BELOW_PROBE_PP = 10.0  # on recorded data, a row this many points below its probe's test accuracy is said so
# how recorded-data tables name the fusions (config.FUSION_NORMS); the paper's is not named after it there
FUSION_NAMES = {"sequence_minmax": "[0, 1] rescale over the sequence", STEP_LAYERNORM: "step-LayerNorm"}


def figures(doc: dict[str, Any], results: Path) -> list[Path | None]:
    """From the results JSON: the confusion matrices of `CONFUSION_ROWS`, pooled over seeds
    (results/ablation_confusion.png, where any of them ran), and each row's validation accuracy
    against its training seconds (results/ablation_time_to_accuracy.png)."""
    result = Ablation.from_json(doc)
    names, seeds = documents.stream_names(doc), len(doc["seeds"])
    panels = [(f"{data.inputs_name((n,), names)} only, {seeds} seeds pooled", c) for n, c in result.confusion.items()]
    recorded = documents.recorded(doc)
    confusion = (
        plots.plot_confusions(
            results / "ablation_confusion.png", panels, class_names=doc["dataset"]["classes"] if recorded else None
        )
        if panels
        else None
    )
    curves = [
        (c["label"], np.asarray(c["seconds"], np.float64), np.asarray(c["val_accuracy"], np.float64))
        for c in result.time_to_accuracy
    ]
    title = f"What accuracy costs in training time, {seeds} seeds a row in one program"
    return [confusion, plots.plot_time_to_accuracy(results / "ablation_time_to_accuracy.png", curves, title)]


def markdown(doc: dict[str, Any]) -> str:
    """The page of the results JSON `doc`: on recorded data `recorded_markdown`'s."""
    result = Ablation.from_json(doc)
    if documents.recorded(doc):
        return recorded_markdown(doc, result)
    paper = not documents.counts_no_claims(doc)  # the paper's columns only where the results are its table's
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc),
        table(result.rows, result.majority, paper=paper),
        findings.baseline_note(),
        "",
        *_variant_note(result, paper),
        *recipe.markdown([r.to_json() for r in result.rows]),
        *fusion_choice_markdown(result.fusion_choice or ()),
        "## Findings checklist (the paper's claims about this table)",
        "",
        findings.markdown(doc["findings"], counted=not documents.counts_no_claims(doc)),
        *_wilcoxon_markdown(result.wilcoxon, paper_p=True),
    ]
    if "ablation_confusion.png" in doc["figures"]:
        lines += ["Confusion matrices (proprioception only, optical flow only): `ablation_confusion.png`.", ""]
    lines += _time_to_accuracy_line(doc)
    lines += [
        "The simulator is the same for every row (never tuned per row): differences from the paper are findings.",
        "",
    ]
    return "\n".join(lines)


def _variant_note(result: Ablation, paper: bool) -> list[str]:
    """What the rows of our step-LayerNorm fusion are, where the table has any."""
    if not any(r.fusion_norm == STEP_LAYERNORM for r in result.rows):
        return []
    return [
        "Rows marked *our step-LayerNorm fusion* are not in the paper: the same inputs with each step's "
        "concatenated features normalised by a LayerNorm instead of the paper's per-sequence [0, 1] rescale "
        "(`Config.fusion_norm`)"
        + ("; the paper column repeats the paper's row with the same inputs for reference." if paper else "."),
        "",
    ]


def _wilcoxon_markdown(w: Mapping[str, Any] | None, paper_p: bool) -> list[str]:
    """The Wilcoxon tests of the ablation's pair, per seed and per sequence (`paper_p`: beside the
    paper's p, with how to read each)."""
    if not w:
        return []
    heading = f"## Wilcoxon signed-rank: {w['compared']} against {w['baseline']}"
    lines = [
        heading + (f" (paper: p = {w['paper_p']})" if paper_p else ""),
        "",
        f"- {w['per_seed']['describe']}",
        f"- {w['per_sample']['describe']}",
        "",
    ]
    if paper_p:
        lines += [
            "The per-seed test is the one comparable to the paper's; its smallest attainable p is the floor above. "
            "The per-sequence test treats sequences of one trial and of different seeds as independent, "
            "which they are not: read it as descriptive.",
            "",
        ]
    return lines


def table(
    rows: Sequence[AblationRow], majority: Mapping[str, Any] | None, recorded: bool = False, paper: bool = True
) -> str:
    """Our accuracy, flagged where seeds collapsed (each row's `collapsed`), beside the test
    split's `majority` class and the paper's, with the difference, one line per row; on recorded
    data each row beside the best row instead; without the paper's columns where `paper` is False
    (a preset whose results are not the paper's table)."""
    means = [stats.mean_sd(100 * r.accuracy("test")) for r in rows]
    gaps = documents.best_gaps([m for m, _ in means])
    body = []
    for r, (mean, sd), gap in zip(rows, means, gaps):
        body.append(
            [
                "TCN" if r.backbone == "tcn" else "Transformer",
                r.display_name.removeprefix("TCN: "),
                f"{mean:.2f} ± {sd:.2f}{findings.collapse_text(r.collapsed['test'])}",
                findings.majority_cell(majority),
                *(
                    [gap]
                    if recorded
                    else [f"{r.paper[0]:.2f} ± {r.paper[1]:.2f}", f"{mean - r.paper[0]:+.2f}"]
                    if paper
                    else []
                ),
                f"{r.wall_s:.1f}",
            ]
        )
    accuracy = f"Test accuracy [%] ({'recorded data' if recorded else 'ours'}, {len(rows[0].seeds)} seeds)"
    compared = [documents.BEST_GAP] if recorded else ["Paper [%]", "Ours − paper [pp]"] if paper else []
    return results_files.markdown_table(
        ["Backbone", "Modalities", accuracy, "Majority class, test [%]", *compared, "Train wall time [s]"], body
    )


def fusion_choice_markdown(choices: Sequence[Mapping[str, Any]]) -> list[str]:
    """The table's rows trained under both fusions, each with the fusion validation picks."""
    if not choices:
        return []
    lines = [
        "## The fusion chosen by validation (rows trained under both)",
        "",
        "| Inputs | Validation [%]: rescale / step-LayerNorm | Chosen | Test of the chosen [%] |",
        "|---|---|---|---|",
    ]
    for c in choices:
        lines.append(
            f"| {display_name(c['name'])} | {c['val']['sequence_minmax']:.2f} / {c['val'][STEP_LAYERNORM]:.2f} | "
            f"{FUSION_NAMES[c['chosen']]} | {c['test'][c['chosen']]:.2f} |"
        )
    return lines + [
        "",
        "The choice is made on the validation split alone, as on recorded data; the paper's rows above stay "
        "under its rescale.",
        "",
    ]


def recorded_table(rows: Sequence[AblationRow], majority: Mapping[str, Any] | None) -> str:
    """Recorded data: each row under its fusion (by validation), flagged where seeds collapsed
    (each row's `collapsed`), beside the test split's `majority` class, the other fusion's test
    accuracy, its probe's, model − probe and the gap to the best row."""
    means = [stats.mean_sd(100 * r.accuracy("test")) for r in rows]
    body = []
    for r, (mean, sd), gap in zip(rows, means, documents.best_gaps([m for m, _ in means])):
        choice, probe_test = r.fusion_choice, 100 * r.probe["accuracy"]["test"]
        other = [f"{FUSION_NAMES[f]} {choice['test'][f]:.2f}" for f in choice["test"] if f != r.fusion_norm]
        val = ", ".join(f"{FUSION_NAMES[f]} {v:.2f}" for f, v in choice["val"].items())
        body.append(
            [
                "TCN" if r.backbone == "tcn" else "Transformer",
                r.display_name,
                f"{FUSION_NAMES[r.fusion_norm]} (val {val})",
                f"{mean:.2f} ± {sd:.2f}{findings.collapse_text(r.collapsed['test'])}",
                findings.majority_cell(majority),
                ", ".join(other) or "–",
                f"{probe_test:.2f}{findings.collapse_text(r.probe['collapsed']['test'])}",
                f"{mean - probe_test:+.2f}",
                gap,
                f"{r.wall_s:.1f}",
            ]
        )
    header = [
        "Backbone",
        "Inputs",
        "Fusion (by validation)",
        f"Test accuracy [%] (recorded data, {len(rows[0].seeds)} seeds)",
        "Majority class, test [%]",
        "Other fusion, test [%]",
        "Linear probe, test [%]",
        "Model − probe [pp]",
        documents.BEST_GAP,
        "Train wall time [s]",
    ]
    return results_files.markdown_table(header, body)


def recorded_notes(result: Ablation) -> list[str]:
    """A line per row more than `BELOW_PROBE_PP` below its probe, and per input steady within sequences."""
    lines = []
    for r in result.rows:
        mean, probe_test = 100 * float(np.mean(r.accuracy("test"))), 100 * r.probe["accuracy"]["test"]
        if mean < probe_test - BELOW_PROBE_PP:
            lines.append(
                f"- **{r.display_name}** is {probe_test - mean:.1f} pp below the linear probe of its inputs "
                f"({mean:.1f} % against {probe_test:.1f} %): the model does not read what the inputs carry."
            )
    s = result.steadiness
    for m, ratio in s.shares.items():
        if ratio < s.steady_below:
            lines.append(
                f"- {s.names.get(m, m)} is steady within sequences: its within-sequence variance is "
                f"{100 * ratio:.1f} % of "
                "its total (median over its dimensions); the [0, 1] rescale over the sequence erases it, "
                "step-LayerNorm keeps it."
            )
    return lines + [""] if lines else []


def recorded_markdown(doc: dict[str, Any], result: Ablation) -> str:
    """The page of a `--data_dir` run: recorded data, rows compared with each other and with their probes."""
    s = result.steadiness
    steadiness = ", ".join(f"{s.names.get(m, m)} {100 * v:.1f} %" for m, v in s.shares.items())
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc),
        recorded_table(result.rows, result.majority),
        findings.baseline_note(),
        "",
        documents.RECORDED_NOTE
        + " Each row is trained under both fusion normalisations and shown under the one with the better "
        "validation accuracy (step-LayerNorm on a tie: it keeps the steady level the rescale erases). The "
        "probe is a logistic regression on each sequence's per-dimension mean and SD "
        f"(`experiments.probe`), on the same sequences. Within-sequence share of each input's variance: {steadiness}.",
        "",
        *recorded_notes(result),
        *recipe.markdown([r.to_json() for r in result.rows]),
        *_wilcoxon_markdown(result.wilcoxon, paper_p=False),
    ]
    if "ablation_confusion.png" in doc["figures"]:
        shown = ", ".join(f"{s.names.get(m, m)} only" for m in CONFUSION_ROWS if any(r.name == m for r in result.rows))
        lines += [f"Confusion matrices ({shown}): `ablation_confusion.png`.", ""]
    lines += _time_to_accuracy_line(doc)
    return "\n".join(lines)


def _time_to_accuracy_line(doc: Mapping[str, Any]) -> list[str]:
    if "ablation_time_to_accuracy.png" not in doc["figures"]:
        return []
    return [
        "What accuracy costs in training time, row by row (validation accuracy after each epoch against the "
        "row's training seconds): `ablation_time_to_accuracy.png`.",
        "",
    ]
