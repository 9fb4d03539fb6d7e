"""The paper's modality ablation (Table ablation_table): 12 transformer rows and the TCN row, and
9 of them again under our step-LayerNorm fusion (every camera row and the non-camera fusion rows).

    python -m experiments.ablation --seeds=5                          # default preset, whole table
    python -m experiments.ablation --seeds=5 --rows=internal,internal+external
    python -m experiments.ablation --preset=paper --set=width=64      # any Config field no row sets, by --set

Each row trains all seeds in one vmapped program and reports mean ± SD test accuracy beside the
paper's number and the difference. Internal audio is compared with internal + palm audio by
Wilcoxon signed-rank tests (per seed and per test sequence, see `runner.paired_tests`), and the
proprioception-only and flow-only models' confusion matrices are drawn (results/ablation_confusion.png).
The simulator is the same for every row: differences from the paper are findings, not tuning targets.
On recorded data (`--data_dir`, only the rows the data supports, chosen with --rows) the rows are
compared with each other: no paper column, no checklist of the paper's claims, the data's own classes.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Sequence

import numpy as np

from fabricjax import catalog, findings, paper_tables, plots, report, stats
from fabricjax.config import MODALITY_NAMES, Config
from fabricjax.studies import documents, loading, runner

WILCOXON_PAIR = ("internal", "internal+external")  # (baseline, compared), as in the paper
CONFUSION_ROWS = ("proprio", "flow")
VARIANT = "step_layernorm"  # our fusion normalisation (config.FUSION_NORMS), beside the paper's


@dataclasses.dataclass(frozen=True)
class Row:
    """A row of the table: the paper's, or our fusion-normalisation variant of one (`paper_*` then
    are the paper's row with the same inputs, for reference)."""

    name: str
    backbone: str
    modalities: tuple[str, ...]
    paper_mean: float
    paper_sd: float
    fusion_norm: str = "sequence_minmax"


def _variant(name: str) -> Row:
    r = next(r for r in paper_tables.ABLATION if r.name == name)
    return Row(f"{VARIANT}:{r.name}", r.backbone, r.modalities, r.paper_mean, r.paper_sd, VARIANT)


# Every camera row and the fusion rows without camera inputs, again under our step-LayerNorm fusion:
# the paper's rescale over the sequence removes a stream's steady level, which is where a camera
# frame's contact patch and a joint's load show, so a row at chance under it alone is no verdict.
VARIANT_ROWS = tuple(
    _variant(n)
    for n in (
        "image", "flow", "image+internal", "image+internal+external+proprio", "flow+internal",
        "flow+internal+external+proprio", "internal+proprio", "internal+external+proprio", "internal+external",
    )
)
ROWS = tuple(Row(r.name, r.backbone, r.modalities, r.paper_mean, r.paper_sd) for r in paper_tables.ABLATION) + VARIANT_ROWS
VARIANT_PAIRS = ((WILCOXON_PAIR[0], f"{VARIANT}:{WILCOXON_PAIR[1]}"),)  # Minsound (no fusion) vs our fused variant


def label(modalities: Sequence[str], backbone: str, fusion_norm: str = "sequence_minmax") -> str:
    """How the table names a row: 'TCN: Minsound + palm mic', '... (our step-LayerNorm fusion)'."""
    text = " + ".join(MODALITY_NAMES[m] for m in modalities)
    text = f"TCN: {text}" if backbone == "tcn" else text
    return f"{text} (our step-LayerNorm fusion)" if fusion_norm == VARIANT else text


def display_name(row_name: str) -> str:
    """The label of row `row_name` of `ROWS`."""
    r = next(r for r in ROWS if r.name == row_name)
    return label(r.modalities, r.backbone, r.fusion_norm)


def row_settings(row: Row) -> dict[str, Any]:
    """The `Config` fields a row sets itself, on top of the preset and the overrides."""
    return {"backbone": row.backbone, "modalities": row.modalities, "fusion_norm": row.fusion_norm}


# What every row sets (row name -> fields): an override of one of these fields is an error
# (`runner.check_overrides`), since the row would replace it or it would change what the row is.
ROW_SETTINGS = {r.name: row_settings(r) for r in ROWS}


def row_config(row: Row, preset: str, overrides: dict[str, Any]) -> Config:
    """The config a row trains with: the preset, `overrides`, then the row's own fields (`row_settings`)."""
    return Config.from_preset(preset, **{**overrides, **row_settings(row)})


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
    overrides = runner.check_overrides("ablation", overrides, ROW_SETTINGS, "choose them with --rows")
    chosen = runner.select_rows(ROWS, rows)
    seeds = runner.seed_list(n_seeds)
    named = [(r.name, row_config(r, preset, overrides)) for r in chosen]
    study = runner.train_rows(
        "ablation", named, seeds, eval_splits=["test"], split_names=loading.TRAIN_VAL_TEST, data_dir=data_dir, workdir=workdir,
        label=display_name,
    )
    trained = study.rows

    test = study.dataset.sets["test"]
    labels = test.labels["fabric"]
    recorded = study.dataset.recorded
    base, compared = WILCOXON_PAIR
    tests = runner.paired_tests(trained[base], trained[compared], "test", labels) if base in trained and compared in trained else {}
    panels = [
        (f"{MODALITY_NAMES[n]} only, {len(seeds)} seeds pooled", np.tile(labels, len(seeds)), trained[n].predictions("test").ravel())
        for n in CONFUSION_ROWS
        if n in trained
    ]
    figure = plots.plot_confusions(
        documents.results_path(results) / "ablation_confusion.png", panels, class_names=study.dataset.classes if recorded else None
    ) if panels else None

    doc = {
        **documents.header("ablation", command=command, preset=preset, seeds=seeds, dataset=study.dataset, train_s=study.train_s),
        "rows": [
            {
                "name": r.name,
                "backbone": trained[r.name].config.backbone,
                "modalities": list(r.modalities),
                "display_name": display_name(r.name),
                "fusion_norm": r.fusion_norm,
                **({} if recorded else {"paper_mean": r.paper_mean, "paper_sd": r.paper_sd}),
                **documents.row_doc(trained[r.name], ["test"]),
            }
            for r in chosen
        ],
        "test_samples": documents.samples_doc(test),
        "wilcoxon": {
            "baseline": base,
            "compared": compared,
            **({} if recorded else {"paper_p": paper_tables.ABLATION_WILCOXON_P}),
            **{k: documents.wilcoxon_doc(v) for k, v in tests.items()},
        }
        if tests
        else None,
        "confusion_png": str(figure) if figure else None,
    }
    # the checklist holds the paper's claims: recorded data is not the paper's
    doc["findings"] = [] if recorded else [f.to_json() for f in checklist({r["name"]: np.asarray(r["accuracy"]["test"]["fabric"]) for r in doc["rows"]})]
    documents.write_outputs(results, "ablation", markdown(doc), doc)
    return doc


CLEARLY_WORSE_PP = 10.0  # "clearly worse": at least this many points below (the paper: 36)
SIMILAR_PP = 10.0  # "similar": within this many points of each other (the paper: 0.06)
WELL_ABOVE_CHANCE_PP = 10.0  # "well above chance": at least this many points above 1/21


def checklist(test: dict[str, np.ndarray]) -> list[findings.Finding]:
    """The paper's qualitative claims about the ablation, as predicates over per-seed test
    accuracies (`test`: row name -> per-seed accuracies in [0, 1]; rows not run are skipped)."""
    out = []
    singles = ["image", "flow", "external", "proprio"]
    claim = "Minsound (internal audio) is the best single modality"
    if not (f := findings.missing(claim, ["internal", *singles], test)):
        best_other = max(singles, key=lambda r: findings.mean_pct(test[r]))
        f = findings.at_least(claim, (MODALITY_NAMES["internal"], test["internal"]), (f"best other, {MODALITY_NAMES[best_other]}", test[best_other]), strict=True)
    out.append(f)
    claim = f"the palm mic alone is clearly worse than Minsound (>= {CLEARLY_WORSE_PP:.0f} pp below)"
    out.append(findings.missing(claim, ["internal", "external"], test) or findings.at_least(
        claim, (MODALITY_NAMES["internal"], test["internal"]), (MODALITY_NAMES["external"], test["external"]), CLEARLY_WORSE_PP))
    claim = (f"proprioception and optical flow alone are similar (within {SIMILAR_PP:.0f} pp) and well above chance "
             f"(>= {WELL_ABOVE_CHANCE_PP:.0f} pp above {100 / catalog.N_CLASSES:.1f} %)")
    if not (f := findings.missing(claim, ["proprio", "flow"], test)):
        p, fl = findings.mean_pct(test["proprio"]), findings.mean_pct(test["flow"])
        floor = 100 / catalog.N_CLASSES + WELL_ABOVE_CHANCE_PP
        f = findings.Finding(claim, abs(p - fl) <= SIMILAR_PP and min(p, fl) >= floor,
                             f"{findings.describe(MODALITY_NAMES['proprio'], test['proprio'])}; {findings.describe(MODALITY_NAMES['flow'], test['flow'])}")
    out.append(f)
    claim = "Minsight images alone are the weakest camera input (below optical flow)"
    out.append(findings.missing(claim, ["image", "flow"], test) or findings.at_least(
        claim, (MODALITY_NAMES["flow"], test["flow"]), (MODALITY_NAMES["image"], test["image"]), strict=True))
    for base, compared, variant in ((WILCOXON_PAIR[0], WILCOXON_PAIR[1], ""), *[(b, c, " (our step-LayerNorm fusion)") for b, c in VARIANT_PAIRS]):
        claim = f"Minsound + palm mic >= Minsound{variant}"
        out.append(findings.missing(claim, [base, compared], test) or findings.at_least(
            claim, (display_name(compared), test[compared]), (display_name(base), test[base])))
    claim = "the TCN is below the transformer on the same inputs (Minsound + palm mic + proprioception)"
    out.append(findings.missing(claim, ["internal+external+proprio", "tcn:internal+external+proprio"], test) or findings.at_least(
        claim, ("Transformer", test["internal+external+proprio"]), ("TCN", test["tcn:internal+external+proprio"]), strict=True))
    return out


def table(rows: Sequence[dict[str, Any]], recorded: bool = False) -> str:
    """Our accuracy beside the paper's, with the difference, one line per row; on recorded data
    each row beside the best row instead."""
    means = [stats.mean_sd(100 * np.asarray(r["accuracy"]["test"]["fabric"])) for r in rows]
    gaps = documents.best_gaps([m for m, _ in means])
    body = []
    for r, (mean, sd), gap in zip(rows, means, gaps):
        body.append([
            "TCN" if r["backbone"] == "tcn" else "Transformer",
            label(r["modalities"], r["backbone"], r.get("fusion_norm", "sequence_minmax")).removeprefix("TCN: "),
            f"{mean:.2f} ± {sd:.2f}",
            *([gap] if recorded else [f"{r['paper_mean']:.2f} ± {r['paper_sd']:.2f}", f"{mean - r['paper_mean']:+.2f}"]),
            f"{r['wall_s']:.1f}",
        ])
    accuracy = f"Test accuracy [%] ({'recorded data' if recorded else 'ours'}, {len(rows[0]['seeds'])} seeds)"
    compared = [documents.BEST_GAP] if recorded else ["Paper [%]", "Ours − paper [pp]"]
    return report.markdown_table(["Backbone", "Modalities", accuracy, *compared, "Train wall time [s]"], body)


def markdown(doc: dict[str, Any]) -> str:
    if documents.recorded(doc):
        return _recorded_markdown(doc)
    lines = [
        documents.title(doc, "Modality ablation", "Table ablation_table"),
        "",
        documents.header_markdown(doc),
        table(doc["rows"]),
        "Rows marked *our step-LayerNorm fusion* are not in the paper: the same inputs with each step's "
        "concatenated features normalised by a LayerNorm instead of the paper's per-sequence [0, 1] rescale "
        "(`Config.fusion_norm`); the paper column repeats the paper's row with the same inputs for reference.",
        "",
        "## Findings checklist (the paper's claims about this table)",
        "",
        findings.markdown(doc["findings"]),
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


def _recorded_markdown(doc: dict[str, Any]) -> str:
    """The table of a `--data_dir` run: recorded data, rows compared with each other."""
    lines = [
        documents.title(doc, "Modality ablation", "Table ablation_table"),
        "",
        documents.header_markdown(doc),
        table(doc["rows"], recorded=True),
        documents.RECORDED_NOTE,
        "",
    ]
    w = doc["wilcoxon"]
    if w:
        lines += [f"## Wilcoxon signed-rank: {w['compared']} against {w['baseline']}", "", f"- {w['per_seed']['describe']}",
                  f"- {w['per_sample']['describe']}", ""]
    if doc["confusion_png"]:
        lines += ["Confusion matrices (proprioception only, optical flow only, where run): `ablation_confusion.png`.", ""]
    return "\n".join(lines)
