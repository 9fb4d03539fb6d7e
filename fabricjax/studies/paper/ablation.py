"""The paper's modality ablation (Table ablation_table): 12 transformer rows and the TCN row, and
9 of them again under our step-LayerNorm fusion (every camera row and the non-camera fusion rows).

    python -m experiments.ablation --seeds=5                          # default preset, the paper's 13 rows
    python -m experiments.ablation --seeds=5 --rows=all               # and our 9 fusion-variant rows
    python -m experiments.ablation --seeds=5 --rows=internal,internal+external
    python -m experiments.ablation --preset=paper --set=width=64      # any Config field no row sets, by --set

Each row trains all seeds in one vmapped program and reports mean ± SD test accuracy beside the
paper's number and the difference. Internal audio is compared with internal + palm audio by
Wilcoxon signed-rank tests (per seed and per test sequence, see `wilcoxon.paired_tests`), and the
proprioception-only and flow-only models' confusion matrices are drawn (results/ablation_confusion.png).
Each row's models are kept as a checkpoint (its row's "checkpoint" in the results JSON), which
`experiments.decide` restores.
The simulator is the same for every row: differences from the paper are findings, not tuning targets.
On recorded data (`--data_dir`, only the rows the data supports, chosen with --rows) the rows are
compared with each other: no paper column, no checklist of the paper's claims, the data's own classes
and the data's own names for its streams (the rig file's microphones and joints; --rows still names
inputs by role). Each row is trained under both fusion normalisations and reported under the one
with the better validation accuracy (mean over seeds; step-LayerNorm on a tie), the other's beside it: another rig may
carry
its cue in a level that is steady within a sequence, which the paper's rescale erases. Each input's
steadiness (`linear_probe.steadiness`) is reported once, flagged below `STEADY_BELOW`, and the linear probe
of each row's inputs on the same sequences (`linear_probe.fit_rows`) stands beside it; a row more than
`BELOW_PROBE_PP` below its probe is said so.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from absl import logging

from fabricjax.config import MODALITY_NAMES
from fabricjax.reporting import plots, results_files, stats
from fabricjax.sequences import data
from fabricjax.studies.machinery import documents, findings, linear_probe, loading, recipe, runner, wilcoxon
from fabricjax.studies.machinery.ablation_rows import ROW_GROUPS, ROWS, STEP_LAYERNORM, display_name, label
from fabricjax.studies.machinery.rows import RowSpec
from fabricjax.studies.machinery.trained import TrainedRow, TrainingRun

TITLE, PAPER = (
    "Modality ablation",
    "Table ablation_table",
)  # how results name the study, and what of the paper it reproduces

WILCOXON_PAIR = ("internal", "internal+external")  # (baseline, compared), as in the paper
PAPER_WILCOXON_P = 0.0254  # the paper's test of that pair
SIGNIFICANCE = 0.05  # the level "significantly higher" claims, as the paper's p reads against it
CONFUSION_ROWS = ("proprio", "flow")
BELOW_PROBE_PP = 10.0  # on recorded data, a row this many points below its probe's test accuracy is said so
# an input whose within-sequence variance is below this fraction of its total (median over its
# dimensions, `linear_probe.steadiness`) is steady within a sequence: reported, since the paper's rescale erases it
STEADY_BELOW = 0.2


STEP_LAYERNORM_PAIRS = ((WILCOXON_PAIR[0], f"{STEP_LAYERNORM}:{WILCOXON_PAIR[1]}"),)


def document(trained: TrainingRun, chosen: Sequence[RowSpec]) -> dict[str, Any]:
    """The rows beside the paper's, each with the class each seed collapsed to (`findings.collapsed`),
    the test split's majority class (`findings.majority`), the Wilcoxon tests of `WILCOXON_PAIR`,
    the confusion counts of `CONFUSION_ROWS` and every trained row's time-to-accuracy curve (what
    `figures` draws)."""
    rows, seeds = trained.rows, next(iter(trained.rows.values())).results.seeds
    test = trained.dataset.sets["test"]
    labels = test.labels["fabric"]
    recorded = trained.dataset.recorded
    base, compared = WILCOXON_PAIR
    tests = (
        wilcoxon.paired_tests(rows[base], rows[compared], "test", labels) if base in rows and compared in rows else {}
    )
    names = test.names if recorded else {}
    drawn = {
        "confusion": {
            n: stats.confusion_matrix(
                np.tile(labels, len(seeds)), rows[n].predictions("test").ravel(), trained.dataset.n_classes
            ).tolist()
            for n in CONFUSION_ROWS
            if n in rows
        },
        # every row trained, so that on recorded data each input shows under both fusions, the one its
        # table reports (chosen by validation) among them
        "time_to_accuracy": [_time_to_accuracy(t, names) for t in rows.values()],
    }
    if recorded:
        return {**_recorded_body(trained, chosen, tests), **drawn}
    return {
        "rows": [
            {
                "name": r.name,
                "backbone": rows[r.name].config.backbone,
                "modalities": list(r.modalities),
                "display_name": r.label,
                "fusion_norm": r.settings["fusion_norm"],
                **({} if recorded else {"paper_mean": r.paper["mean"], "paper_sd": r.paper["sd"]}),
                "collapsed": {"test": findings.collapsed(rows[r.name].predictions("test"), labels)},
                **rows[r.name].doc(["test"]),
            }
            for r in chosen
        ],
        "fusion_choice": fusion_choices(rows),
        "majority": {"test": findings.majority(labels)},
        "wilcoxon": {
            "baseline": base,
            "compared": compared,
            **({} if recorded else {"paper_p": PAPER_WILCOXON_P}),
            **{k: documents.wilcoxon_doc(v) for k, v in tests.items()},
        }
        if tests
        else None,
        **drawn,
    }


def _time_to_accuracy(row: TrainedRow, names: Mapping[str, str]) -> dict[str, Any]:
    """A row's curve of `TrainedRow.time_to_accuracy` as the results JSON holds it (None: an
    epoch a seed did not train), under its table label."""
    seconds, per_seed = row.time_to_accuracy()
    return {
        "label": label(
            row.config.modalities, row.config.backbone, row.config.fusion_norm, names, row.config.augment_rotation
        ),
        "seconds": seconds.tolist(),
        "val_accuracy": [[None if np.isnan(x) else float(x) for x in s] for s in per_seed],
    }


def figures(doc: dict[str, Any], results: Path) -> list[Path | None]:
    """From the results JSON: the confusion matrices of `CONFUSION_ROWS`, pooled over seeds
    (results/ablation_confusion.png, where any of them ran), and each row's validation accuracy
    against its training seconds (results/ablation_time_to_accuracy.png)."""
    names, seeds = documents.stream_names(doc), len(doc["seeds"])
    panels = [(f"{data.inputs_name((n,), names)} only, {seeds} seeds pooled", c) for n, c in doc["confusion"].items()]
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
        for c in doc["time_to_accuracy"]
    ]
    title = f"What accuracy costs in training time, {seeds} seeds a row in one program"
    return [confusion, plots.plot_time_to_accuracy(results / "ablation_time_to_accuracy.png", curves, title)]


def fusion_choices(rows: Mapping[str, TrainedRow]) -> list[dict[str, Any]]:
    """For each row trained under both fusions (the paper's and its `STEP_LAYERNORM_ROWS` twin),
    the fusion its validation accuracy picks (mean over seeds; step-LayerNorm on a tie), as on
    recorded data, with both fusions' validation and test accuracy [%]."""
    out = []
    for name, row in rows.items():
        twin = rows.get(f"{STEP_LAYERNORM}:{name}")
        if twin is None or row.config.fusion_norm == STEP_LAYERNORM:
            continue
        val = {r.config.fusion_norm: stats.mean_sd(100 * r.accuracy("val"))[0] for r in (row, twin)}
        out.append(
            {
                "name": name,
                "chosen": max(val, key=lambda f: (val[f], f == STEP_LAYERNORM)),
                "val": val,
                "test": {r.config.fusion_norm: stats.mean_sd(100 * r.accuracy("test"))[0] for r in (row, twin)},
            }
        )
    return out


def fusion_choice_markdown(choices: Sequence[dict[str, Any]]) -> list[str]:
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


def _recorded_body(trained: TrainingRun, chosen: Sequence[RowSpec], tests) -> dict[str, Any]:
    """The rows on recorded data: each under the fusion its validation accuracy picks, beside the
    other fusion and the probe of its inputs; every input's steadiness."""
    sets, rows = trained.dataset.sets, trained.rows
    names = sets["test"].names
    twins = {runner.fusion_twin(r.name, STEP_LAYERNORM) for r in chosen}
    chosen = [r for r in chosen if r.name not in twins]  # a chosen row's twin: reported within that row
    probes = linear_probe.fit_rows(sets, [r.modalities for r in chosen])
    steady = {m: linear_probe.steadiness(a) for m, a in sets["train"].inputs.items()}
    for m, ratio in steady.items():
        if ratio < STEADY_BELOW:
            logging.warning(
                "%s is steady within sequences: its within-sequence variance is %.1f %% of its total (median over its "
                "dimensions); the [0, 1] rescale over the sequence erases it, step-LayerNorm fusion keeps it",
                names.get(m, m),
                100 * ratio,
            )
    out = []
    for r in chosen:
        trained_as = [rows[n] for n in (r.name, runner.fusion_twin(r.name, STEP_LAYERNORM)) if n in rows]
        val = {t.config.fusion_norm: stats.mean_sd(100 * t.accuracy("val"))[0] for t in trained_as}
        # on a tie, step-LayerNorm: it keeps the steady level the rescale erases, and loses nothing the rescale keeps
        best = max(trained_as, key=lambda t: (val[t.config.fusion_norm], t.config.fusion_norm == STEP_LAYERNORM))
        p = probes[frozenset(r.modalities)]
        out.append(
            {
                "name": r.name,
                "backbone": best.config.backbone,
                "modalities": list(r.modalities),
                "display_name": label(
                    r.modalities, best.config.backbone, names=names, rotated=best.config.augment_rotation
                ),
                "fusion_norm": best.config.fusion_norm,
                "fusion_choice": {
                    "by": "validation accuracy, mean over seeds [%]",
                    "val": val,
                    "test": {t.config.fusion_norm: stats.mean_sd(100 * t.accuracy("test"))[0] for t in trained_as},
                },
                "probe": {
                    "C": p["C"],
                    "accuracy": p["accuracy"],
                    "collapsed": {"test": findings.collapsed(p["predictions"].get("test", []))},
                },
                "collapsed": {"test": findings.collapsed(best.predictions("test"), sets["test"].labels["fabric"])},
                **best.doc(["test"]),
            }
        )
    return {
        "rows": out,
        "names": dict(names),
        "steady_below": STEADY_BELOW,
        "steadiness": steady,
        "majority": {"test": findings.majority(sets["test"].labels["fabric"])},
        "wilcoxon": {
            "baseline": WILCOXON_PAIR[0],
            "compared": WILCOXON_PAIR[1],
            **{k: documents.wilcoxon_doc(v) for k, v in tests.items()},
        }
        if tests
        else None,
    }


CLEARLY_WORSE_PP = 10.0  # "clearly worse": at least this many points below (the paper: 36)
SIMILAR_PP = 10.0  # "similar": within this many points of each other (the paper: 0.06)
WELL_ABOVE_CHANCE_PP = 10.0  # "well above chance": at least this many points above the test split's majority class


def _best_single(c: findings.Claim, e: findings.Evidence) -> tuple[findings.Finding, Sequence[str]]:
    """Minsound above the best of the other single inputs (strictly), comparing the two."""
    best_other = max(SINGLES, key=lambda r: findings.mean_pct(e.values[r]))
    best = (f"best other, {e.named(best_other)}", e.values[best_other])
    return findings.at_least(c.claim, e.of("internal"), best, strict=True), ["internal", best_other]


def _similar_above_chance(c: findings.Claim, e: findings.Evidence) -> tuple[findings.Finding, Sequence[str]]:
    """Proprioception and flow within `SIMILAR_PP` of each other, each `WELL_ABOVE_CHANCE_PP` above
    the majority class (not evaluated without known test labels)."""
    p, fl = findings.mean_pct(e.values["proprio"]), findings.mean_pct(e.values["flow"])
    evidence = (
        f"{findings.describe(e.named('proprio'), e.values['proprio'])}; "
        f"{findings.describe(e.named('flow'), e.values['flow'])}; "
        f"1 / classes {100 / e.n_classes:.1f} %"
    )
    if e.majority is None:
        return findings.Finding(c.claim, None, f"{evidence}; no test label known, so no majority class"), c.rows
    floor = e.majority["accuracy"] + WELL_ABOVE_CHANCE_PP
    holds = abs(p - fl) <= SIMILAR_PP and min(p, fl) >= floor
    said = f"{evidence}; majority class {e.majority['accuracy']:.1f} % (class {e.majority['label']}), so at least"
    return findings.Finding(c.claim, holds, f"{said} {floor:.1f} %"), c.rows


def _significantly_above(c: findings.Claim, e: findings.Evidence) -> tuple[findings.Finding, Sequence[str]]:
    """Minsound + palm mic strictly above Minsound, and the per-sequence Wilcoxon test below
    `SIGNIFICANCE` (not evaluated without the test)."""
    base, compared = WILCOXON_PAIR
    above = findings.at_least(c.claim, e.of(compared), e.of(base), strict=True)
    tests = e.tests or {}
    if "per_sample" not in tests:
        return findings.Finding(c.claim, None, f"{above.evidence}; no Wilcoxon test in the results"), c.rows
    p_sample, p_seed = tests["per_sample"]["p_value"], tests["per_seed"]["p_value"]
    evidence = (
        f"{above.evidence}; p = {p_sample:.3g} per test sequence, the pairing that can reach the "
        f"paper's p at five seeds (per seed: p = {p_seed:.3g})"
    )
    return findings.Finding(c.claim, bool(above.holds and p_sample < SIGNIFICANCE), evidence), c.rows


def _transformer_above_tcn(c: findings.Claim, e: findings.Evidence) -> tuple[findings.Finding, Sequence[str]]:
    transformer, tcn = c.rows
    return findings.at_least(
        c.claim, ("Transformer", e.values[transformer]), ("TCN", e.values[tcn]), strict=True
    ), c.rows


SINGLES = ("image", "flow", "external", "proprio")  # the single inputs Minsound is compared with
# The paper's claims about the table, and ours about our variant, each checked by `findings.evaluate`.
CLAIMS = (
    findings.Claim("Minsound (internal audio) is the best single modality", ("internal", *SINGLES), _best_single),
    findings.Claim(
        f"the palm mic alone is clearly worse than Minsound (>= {CLEARLY_WORSE_PP:.0f} pp below)",
        ("internal", "external"),
        findings.above("internal", "external", CLEARLY_WORSE_PP),
    ),
    findings.Claim(
        f"proprioception and optical flow alone are similar (within {SIMILAR_PP:.0f} pp) and well above chance "
        f"(rule: each >= {WELL_ABOVE_CHANCE_PP:.0f} pp above the test split's majority class; 1 / classes "
        f"shown beside it)",
        ("proprio", "flow"),
        _similar_above_chance,
    ),
    findings.Claim(
        "Minsight images alone are the weakest camera input (below optical flow)",
        ("image", "flow"),
        findings.above("flow", "image", strict=True),
    ),
    findings.Claim(
        f"Minsound + palm mic is significantly above Minsound (Wilcoxon signed-rank per test sequence, "
        f"p < {SIGNIFICANCE}; the paper: p = {PAPER_WILCOXON_P})",
        WILCOXON_PAIR,
        _significantly_above,
    ),
    *(
        findings.Claim(
            "Minsound + palm mic >= Minsound (our step-LayerNorm fusion)",
            (base, compared),
            findings.above(compared, base),
            variant=True,
        )
        for base, compared in STEP_LAYERNORM_PAIRS
    ),
    findings.Claim(
        "the TCN is below the transformer on the same inputs (Minsound + palm mic + proprioception)",
        ("internal+external+proprio", "tcn:internal+external+proprio"),
        _transformer_above_tcn,
    ),
)


def checklist(
    test: dict[str, np.ndarray],
    majority: Mapping[str, Any] | None,
    n_classes: int,
    collapsed: Mapping[str, Sequence[int | None]] | None = None,
    wilcoxon: Mapping[str, Any] | None = None,
) -> list[findings.Finding]:
    """`CLAIMS` checked on per-seed test accuracies (`test`: row name -> per-seed accuracies in
    [0, 1]; rows not run are skipped). `majority`: the test split's `findings.majority` baseline,
    which "above chance" is counted against; `n_classes`: the data's classes, whose 1 / classes is
    the paper's chance, shown beside it; `collapsed`: row name -> the class each seed collapsed to
    (`findings.collapsed`); `wilcoxon`: the results JSON's tests of `WILCOXON_PAIR`, which the
    paper's significance claim reads."""
    return findings.evaluate(CLAIMS, findings.Evidence(test, majority, n_classes, collapsed or {}, wilcoxon, _plain))


def _plain(row: str) -> str:
    """How a claim's evidence names a row: a single input by its sensor, else by its label."""
    return MODALITY_NAMES[row] if row in MODALITY_NAMES else display_name(row)


def table(
    rows: Sequence[dict[str, Any]], majority: Mapping[str, Any] | None, recorded: bool = False, paper: bool = True
) -> str:
    """Our accuracy, flagged where seeds collapsed (each row's "collapsed"), beside the test
    split's `majority` class and the paper's, with the difference, one line per row; on recorded
    data each row beside the best row instead; without the paper's columns where `paper` is False
    (a preset whose results are not the paper's table)."""
    means = [stats.mean_sd(100 * np.asarray(r["accuracy"]["test"]["fabric"])) for r in rows]
    gaps = documents.best_gaps([m for m, _ in means])
    body = []
    for r, (mean, sd), gap in zip(rows, means, gaps):
        body.append(
            [
                "TCN" if r["backbone"] == "tcn" else "Transformer",
                r["display_name"].removeprefix("TCN: "),
                f"{mean:.2f} ± {sd:.2f}{findings.collapse_text(r['collapsed']['test'])}",
                findings.majority_cell(majority),
                *(
                    [gap]
                    if recorded
                    else [f"{r['paper_mean']:.2f} ± {r['paper_sd']:.2f}", f"{mean - r['paper_mean']:+.2f}"]
                    if paper
                    else []
                ),
                f"{r['wall_s']:.1f}",
            ]
        )
    accuracy = f"Test accuracy [%] ({'recorded data' if recorded else 'ours'}, {len(rows[0]['seeds'])} seeds)"
    compared = [documents.BEST_GAP] if recorded else ["Paper [%]", "Ours − paper [pp]"] if paper else []
    return results_files.markdown_table(
        ["Backbone", "Modalities", accuracy, "Majority class, test [%]", *compared, "Train wall time [s]"], body
    )


def markdown(doc: dict[str, Any]) -> str:
    if documents.recorded(doc):
        return _recorded_markdown(doc)
    paper = not documents.counts_no_claims(doc)  # the paper's columns only where the results are its table's
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc),
        table(doc["rows"], doc["majority"]["test"], paper=paper),
        findings.baseline_note(),
        "",
        *(
            [
                "Rows marked *our step-LayerNorm fusion* are not in the paper: the same inputs with each step's "
                "concatenated features normalised by a LayerNorm instead of the paper's per-sequence [0, 1] rescale "
                "(`Config.fusion_norm`)"
                + ("; the paper column repeats the paper's row with the same inputs for reference." if paper else "."),
                "",
            ]
            if any(r.get("fusion_norm") == STEP_LAYERNORM for r in doc["rows"])
            else []
        ),
        *recipe.markdown(doc["rows"]),
        *fusion_choice_markdown(doc.get("fusion_choice", [])),
        "## Findings checklist (the paper's claims about this table)",
        "",
        findings.markdown(doc["findings"], counted=not documents.counts_no_claims(doc)),
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
    if "ablation_confusion.png" in doc["figures"]:
        lines += ["Confusion matrices (proprioception only, optical flow only): `ablation_confusion.png`.", ""]
    lines += _time_to_accuracy_line(doc)
    lines += [
        "The simulator is the same for every row (never tuned per row): differences from the paper are findings.",
        "",
    ]
    return "\n".join(lines)


def recorded_table(rows: Sequence[dict[str, Any]], majority: Mapping[str, Any] | None) -> str:
    """Recorded data: each row under its fusion (by validation), flagged where seeds collapsed
    (each row's "collapsed"), beside the test split's `majority` class, the other fusion's test
    accuracy, its probe's, model − probe and the gap to the best row."""
    means = [stats.mean_sd(100 * np.asarray(r["accuracy"]["test"]["fabric"])) for r in rows]
    body = []
    for r, (mean, sd), gap in zip(rows, means, documents.best_gaps([m for m, _ in means])):
        choice, probe_test = r["fusion_choice"], 100 * r["probe"]["accuracy"]["test"]
        other = [f"{FUSION_NAMES[f]} {choice['test'][f]:.2f}" for f in choice["test"] if f != r["fusion_norm"]]
        val = ", ".join(f"{FUSION_NAMES[f]} {v:.2f}" for f, v in choice["val"].items())
        body.append(
            [
                "TCN" if r["backbone"] == "tcn" else "Transformer",
                r["display_name"],
                f"{FUSION_NAMES[r['fusion_norm']]} (val {val})",
                f"{mean:.2f} ± {sd:.2f}{findings.collapse_text(r['collapsed']['test'])}",
                findings.majority_cell(majority),
                ", ".join(other) or "–",
                f"{probe_test:.2f}{findings.collapse_text(r['probe']['collapsed']['test'])}",
                f"{mean - probe_test:+.2f}",
                gap,
                f"{r['wall_s']:.1f}",
            ]
        )
    header = [
        "Backbone",
        "Inputs",
        "Fusion (by validation)",
        f"Test accuracy [%] (recorded data, {len(rows[0]['seeds'])} seeds)",
        "Majority class, test [%]",
        "Other fusion, test [%]",
        "Linear probe, test [%]",
        "Model − probe [pp]",
        documents.BEST_GAP,
        "Train wall time [s]",
    ]
    return results_files.markdown_table(header, body)


# how recorded-data tables name the fusions (config.FUSION_NORMS); the paper's is not named after it there
FUSION_NAMES = {"sequence_minmax": "[0, 1] rescale over the sequence", STEP_LAYERNORM: "step-LayerNorm"}


def recorded_notes(doc: dict[str, Any]) -> list[str]:
    """A line per row more than `BELOW_PROBE_PP` below its probe, and per input steady within sequences."""
    lines = []
    for r in doc["rows"]:
        mean, probe_test = 100 * float(np.mean(r["accuracy"]["test"]["fabric"])), 100 * r["probe"]["accuracy"]["test"]
        if mean < probe_test - BELOW_PROBE_PP:
            lines.append(
                f"- **{r['display_name']}** is {probe_test - mean:.1f} pp below the linear probe of its inputs "
                f"({mean:.1f} % against {probe_test:.1f} %): the model does not read what the inputs carry."
            )
    for m, ratio in doc["steadiness"].items():
        if ratio < doc["steady_below"]:
            lines.append(
                f"- {doc['names'].get(m, m)} is steady within sequences: its within-sequence variance is "
                f"{100 * ratio:.1f} % of "
                "its total (median over its dimensions); the [0, 1] rescale over the sequence erases it, "
                "step-LayerNorm keeps it."
            )
    return lines + [""] if lines else []


def _recorded_markdown(doc: dict[str, Any]) -> str:
    """The table of a `--data_dir` run: recorded data, rows compared with each other and with their probes."""
    steadiness = ", ".join(f"{doc['names'].get(m, m)} {100 * v:.1f} %" for m, v in doc["steadiness"].items())
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc),
        recorded_table(doc["rows"], doc["majority"]["test"]),
        findings.baseline_note(),
        "",
        documents.RECORDED_NOTE
        + " Each row is trained under both fusion normalisations and shown under the one with the better "
        "validation accuracy (step-LayerNorm on a tie: it keeps the steady level the rescale erases). The "
        "probe is a logistic regression on each sequence's per-dimension mean and SD "
        f"(`experiments.probe`), on the same sequences. Within-sequence share of each input's variance: {steadiness}.",
        "",
        *recorded_notes(doc),
        *recipe.markdown(doc["rows"]),
    ]
    w = doc["wilcoxon"]
    if w:
        lines += [
            f"## Wilcoxon signed-rank: {w['compared']} against {w['baseline']}",
            "",
            f"- {w['per_seed']['describe']}",
            f"- {w['per_sample']['describe']}",
            "",
        ]
    if "ablation_confusion.png" in doc["figures"]:
        shown = ", ".join(
            f"{doc['names'].get(m, m)} only" for m in CONFUSION_ROWS if any(r["name"] == m for r in doc["rows"])
        )
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


STUDY = runner.Study(
    "ablation",
    ROWS,
    n_seeds=5,
    eval_splits=("test",),
    split_names=loading.TRAIN_VAL_TEST,
    document=document,
    checklist=lambda doc: checklist(
        {r["name"]: np.asarray(r["accuracy"]["test"]["fabric"]) for r in doc["rows"]},
        doc["majority"]["test"],
        len(doc["dataset"]["classes"]),
        {r["name"]: r["collapsed"]["test"] for r in doc["rows"]},
        doc.get("wilcoxon"),
    ),
    markdown=markdown,
    module=__name__,
    figures=figures,
    recorded_fusions=(STEP_LAYERNORM,),
    checkpoints=True,
    groups=ROW_GROUPS,
    default_rows=ROW_GROUPS["paper"],
)
run = STUDY.run  # every study module has `run`: the training studies through `runner.run_study`
