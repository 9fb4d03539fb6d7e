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
`page.BELOW_PROBE_PP` below its probe is said so. The page and figures are drawn from what the study
measures (`measure`, an `Ablation`) by `pages.ablation`.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np
from absl import logging

from fabricjax.config import MODALITY_NAMES
from fabricjax.reporting import stats
from fabricjax.studies.machinery import documents, findings, linear_probe, loading, runner, wilcoxon
from fabricjax.studies.machinery.ablation_rows import (
    CONFUSION_ROWS,
    ROW_GROUPS,
    ROWS,
    STEP_LAYERNORM,
    display_name,
    label,
)
from fabricjax.studies.machinery.results import Ablation, AblationRow, Steadiness
from fabricjax.studies.pages import ablation as page
from fabricjax.studies.machinery.rows import RowSpec
from fabricjax.studies.machinery.trained import TrainedRow, TrainingRun

TITLE, PAPER = page.TITLE, page.PAPER  # how results name the study (reproduce's plan reads every study's)

WILCOXON_PAIR = ("internal", "internal+external")  # (baseline, compared), as in the paper
PAPER_WILCOXON_P = 0.0254  # the paper's test of that pair
SIGNIFICANCE = 0.05  # the level "significantly higher" claims, as the paper's p reads against it
# an input whose within-sequence variance is below this fraction of its total (median over its
# dimensions, `linear_probe.steadiness`) is steady within a sequence: reported, since the paper's rescale erases it
STEADY_BELOW = 0.2


STEP_LAYERNORM_PAIRS = ((WILCOXON_PAIR[0], f"{STEP_LAYERNORM}:{WILCOXON_PAIR[1]}"),)


def measure(trained: TrainingRun, chosen: Sequence[RowSpec]) -> Ablation:
    """The rows beside the paper's, each with the class each seed collapsed to (`findings.collapsed`),
    the test split's majority class (`findings.majority`), the Wilcoxon tests of `WILCOXON_PAIR`,
    the confusion counts of `CONFUSION_ROWS` and every trained row's time-to-accuracy curve (what
    the page's figures draw); on recorded data each row as `_recorded_rows` measures it."""
    rows, seeds = trained.rows, next(iter(trained.rows.values())).results.seeds
    test = trained.dataset.sets["test"]
    labels = test.labels["fabric"]
    recorded = trained.dataset.recorded
    base, compared = WILCOXON_PAIR
    tests = (
        wilcoxon.paired_tests(rows[base], rows[compared], "test", labels) if base in rows and compared in rows else {}
    )
    names = test.names if recorded else {}
    confusion = {
        n: stats.confusion_matrix(
            np.tile(labels, len(seeds)), rows[n].predictions("test").ravel(), trained.dataset.n_classes
        ).tolist()
        for n in CONFUSION_ROWS
        if n in rows
    }
    # every row trained, so that on recorded data each input shows under both fusions, the one its
    # table reports (chosen by validation) among them
    curves = tuple(_time_to_accuracy(t, names) for t in rows.values())
    tested = {
        "baseline": base,
        "compared": compared,
        **({} if recorded else {"paper_p": PAPER_WILCOXON_P}),
        **{k: documents.wilcoxon_doc(v) for k, v in tests.items()},
    }
    measured = dict(majority=findings.majority(labels), wilcoxon=tested if tests else None, confusion=confusion)
    if recorded:
        out_rows, steadiness = _recorded_rows(trained, chosen)
        return Ablation(out_rows, **measured, time_to_accuracy=curves, steadiness=steadiness)
    out_rows = tuple(
        AblationRow(
            r.name,
            rows[r.name].config.backbone,
            r.modalities,
            r.label,
            r.settings["fusion_norm"],
            {"test": findings.collapsed(rows[r.name].predictions("test"), labels)},
            rows[r.name].doc(["test"]),
            (r.paper["mean"], r.paper["sd"]),
        )
        for r in chosen
    )
    return Ablation(out_rows, **measured, time_to_accuracy=curves, fusion_choice=tuple(fusion_choices(rows)))


def document(trained: TrainingRun, chosen: Sequence[RowSpec]) -> dict[str, Any]:
    """The study's own part of its results JSON: what `measure` gives."""
    return measure(trained, chosen).to_json()


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


def _recorded_rows(trained: TrainingRun, chosen: Sequence[RowSpec]) -> tuple[tuple[AblationRow, ...], Steadiness]:
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
            AblationRow(
                r.name,
                best.config.backbone,
                r.modalities,
                label(r.modalities, best.config.backbone, names=names, rotated=best.config.augment_rotation),
                best.config.fusion_norm,
                {"test": findings.collapsed(best.predictions("test"), sets["test"].labels["fabric"])},
                best.doc(["test"]),
                fusion_choice={
                    "by": "validation accuracy, mean over seeds [%]",
                    "val": val,
                    "test": {t.config.fusion_norm: stats.mean_sd(100 * t.accuracy("test"))[0] for t in trained_as},
                },
                probe={
                    "C": p["C"],
                    "accuracy": p["accuracy"],
                    "collapsed": {"test": findings.collapsed(p["predictions"].get("test", []))},
                },
            )
        )
    return tuple(out), Steadiness(dict(names), STEADY_BELOW, steady)


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


def claims_of(result: Ablation, n_classes: int) -> list[findings.Finding]:
    """`checklist` on what the ablation measured, on data of `n_classes` classes."""
    collapsed = {r.name: r.collapsed["test"] for r in result.rows}
    return checklist(result.test_accuracies(), result.majority, n_classes, collapsed, result.wilcoxon)


def _plain(row: str) -> str:
    """How a claim's evidence names a row: a single input by its sensor, else by its label."""
    return MODALITY_NAMES[row] if row in MODALITY_NAMES else display_name(row)


STUDY = runner.Study(
    "ablation",
    ROWS,
    n_seeds=5,
    eval_splits=("test",),
    split_names=loading.TRAIN_VAL_TEST,
    document=document,
    checklist=lambda doc: claims_of(Ablation.from_json(doc), len(doc["dataset"]["classes"])),
    markdown=page.markdown,
    module=__name__,
    figures=page.figures,
    recorded_fusions=(STEP_LAYERNORM,),
    checkpoints=True,
    groups=ROW_GROUPS,
    default_rows=ROW_GROUPS["paper"],
)
run = STUDY.run  # every study module has `run`: the training studies through `runner.run_study`
