"""Property perception (the paper's Table property_perception): stretchiness, roughness, thickness.

    python -m experiments.properties --seeds=5

Three property heads replace the fabric head (`property_heads=True, fabric_head=False`) and are
trained jointly. Fabrics 1 and 10 and the new fabrics 21-23 (`catalog.PROPERTY_HOLDOUTS`) are
never trained on; accuracies are reported on the test day's training fabrics (class 0 has no
properties: its labels are unknown and ignored) and on the five holdouts. Rows: the paper's
"Minsound" and "Minsound + Minsight", named here by what they read: internal+proprio (Minsound and
proprioception) and internal+proprio+image (and the 60x80 Minsight image); proprioception is always
on, as in the paper. Each accuracy stands beside its split's majority level
(`findings.majority`: always answering the split's most frequent level, from its labels) with a
collapse flag where a seed answers one level for nearly every sequence; the paper's chance,
1 / levels, is shown too, but the levels are not balanced, so "above chance" counts only above
the majority level.

The paper's claims about the table are checked by `checklist` on the holdout fabrics. On recorded
data (`--data_dir`) the rows are compared with each other instead (`documents.recorded`), and the
holdouts are the trials of its holdout split (no class is excluded by the catalog's fabric ids);
the tables name each row by the data's names for its inputs (`data.inputs_name`: the rig file's
microphones and joints), while --rows takes the row names (internal+proprio, internal+proprio+image)
or their labels on simulated data (Minsound + proprioception, ...).

The trained models (all seeds) are saved as an orbax checkpoint per row; `experiments.latents
--checkpoint=DIR` restores one for the t-SNE figure.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from fabricjax import catalog
from fabricjax.reporting import results_files, stats
from fabricjax.sequences import data
from fabricjax.studies.machinery import documents, findings, runner
from fabricjax.studies.machinery.rows import RowSpec
from fabricjax.studies.machinery.trained import TrainingRun

TITLE, PAPER = (
    "Property perception",
    "Table property_perception",
)  # how results name the study, and what of the paper it reproduces

PROPERTIES = tuple(catalog.PROPERTY_LEVELS)
SPLITS = {"test": "training fabrics", "holdout": "holdout fabrics"}
SETTINGS = dict(
    property_heads=True, fabric_head=False, exclude_fabrics=catalog.PROPERTY_HOLDOUTS, image_resolution="down"
)


def _row(modalities: tuple[str, ...], train: tuple[float, ...], holdout: tuple[float, ...]) -> RowSpec:
    """The row of `modalities`, named and labelled by them, and the paper's mean accuracy [%]
    (5 seeds) per property (`PROPERTIES` order) on the training fabrics and on the holdout fabrics."""
    paper = {"train": dict(zip(PROPERTIES, train)), "holdout": dict(zip(PROPERTIES, holdout))}
    return RowSpec("+".join(modalities), {**SETTINGS, "modalities": modalities}, data.inputs_name(modalities), paper)


# The paper's Table property_perception (its rows "Minsound" and "Minsound + Minsight"); proprioception is always on.
ROWS = (
    _row(("internal", "proprio"), (97.40, 97.47, 97.59), (76.15, 40.23, 70.56)),
    _row(("internal", "proprio", "image"), (85.99, 82.38, 90.43), (82.95, 33.94, 90.47)),
)


def document(trained: TrainingRun, chosen: Sequence[RowSpec]) -> dict[str, Any]:
    """Per row its checkpoint, accuracies per property and, per split and property, the level
    each seed collapsed to (`findings.collapsed`, None where it did not); chance (1 / levels), the
    majority level (`findings.majority`) and the fabrics of each evaluated split; the paper's numbers."""
    ds = trained.dataset
    out_rows = []
    for r in chosen:
        row = trained.rows[r.name]
        collapsed = {
            s: {p: findings.collapsed(row.predictions(s, p), ds.sets[s].labels[p]) for p in PROPERTIES} for s in SPLITS
        }
        out_rows.append(
            {"name": r.name, "modalities": list(r.modalities), "collapsed": collapsed, **row.doc(list(SPLITS))}
        )
    paper = {
        p: {f"{split}_{r.name}": r.paper[split][p] for r in ROWS for split in ("train", "holdout")} for p in PROPERTIES
    }
    return {
        "chance": {p: 100.0 / n for p, n in catalog.PROPERTY_LEVELS.items()},
        "majority": {s: {p: findings.majority(ds.sets[s].labels[p]) for p in PROPERTIES} for s in SPLITS},
        "fabrics": {s: sorted(set(ds.sets[s].info["fabric_id"].tolist())) for s in SPLITS},
        **({} if ds.recorded else {"paper": paper}),
        "rows": out_rows,
    }


def checklist(
    holdout: dict[str, dict[str, np.ndarray]],
    chance: dict[str, float],
    majority: dict[str, dict[str, Any] | None],
    notes: dict[str, dict[str, str]] | None = None,
    collapsed: dict[str, dict[str, list[int | None]]] | None = None,
) -> list[findings.Finding]:
    """The paper's claims about property perception on the holdout fabrics, as predicates over
    per-seed accuracies (`holdout`: row name -> property -> per-seed accuracy in [0, 1]; rows not
    run are skipped). `chance`: property -> the paper's chance, 1 / levels, in percent;
    `majority`: property -> the holdouts' `findings.majority` baseline. "Above chance" counts only
    where every property's mean over seeds is above its majority level (`findings.above_majority`),
    the strongest trivial baseline; the evidence gives both readings. `notes`: row name ->
    property -> what the evidence adds to its accuracy (`findings.collapse_text`); `collapsed`: row
    name -> property -> the level each seed collapsed to. A verdict counts only where every
    accuracy it reads can carry it (`findings.counted_where`)."""
    notes, collapsed = notes or {}, collapsed or {}

    def gated(f: findings.Finding, reads: list[tuple[str, str]], compared: bool = True) -> findings.Finding:
        """`compared`: a claim that one accuracy beats another, which a row at or below its majority
        level cannot carry; a claim that each is above that level reads it as its rule instead."""
        return findings.counted_where(
            f,
            [
                (
                    f"{STUDY.row(r).label}, {p}",
                    holdout[r][p],
                    collapsed.get(r, {}).get(p, []),
                    majority[p] if compared else None,
                )
                for r, p in reads
            ],
        )

    def named(row: str, prop: str) -> str:
        return f"{STUDY.row(row).label}, {prop}{notes.get(row, {}).get(prop, '')}"

    out = []
    for name in (r.name for r in ROWS):
        claim = (
            f"{STUDY.row(name).label}: every property is above chance on the holdout fabrics "
            "(rule: each property's mean over seeds above its majority level; above 1 / levels shown beside it)"
        )
        if not (f := findings.missing(claim, [name], holdout)):
            above = {p: findings.above_majority(holdout[name][p], majority[p]) for p in PROPERTIES}
            evidence = []
            for p in PROPERTIES:
                base, mean = majority[p], findings.mean_pct(holdout[name][p])
                said = (
                    "no level known"
                    if base is None
                    else f"{'above' if above[p] else 'not above'} its majority level {base['accuracy']:.1f} % "
                    f"(level {base['label']})"
                )
                evidence.append(
                    f"{findings.describe(p, holdout[name][p])}{notes.get(name, {}).get(p, '')}: {said}; "
                    f"{'above' if mean > chance[p] else 'not above'} 1 / levels {chance[p]:.1f} %"
                )
            f = gated(
                findings.Finding(claim, None if None in above.values() else all(above.values()), "; ".join(evidence)),
                [(name, p) for p in PROPERTIES],
                compared=False,
            )
        out.append(f)
    ours, both = (r.name for r in ROWS)
    for prop, better, worse in (("stretchiness", both, ours), ("thickness", both, ours), ("roughness", ours, both)):
        claim = f"{STUDY.row(better).label} beats {STUDY.row(worse).label} on {prop} on the holdout fabrics"
        out.append(
            findings.missing(claim, [better, worse], holdout)
            or gated(
                findings.at_least(
                    claim,
                    (named(better, prop), holdout[better][prop]),
                    (named(worse, prop), holdout[worse][prop]),
                    strict=True,
                ),
                [(better, prop), (worse, prop)],
            )
        )
    return out


def row_title(row: dict[str, Any], names: dict[str, str]) -> str:
    """How the tables name a row: by its inputs, under the data's names on recorded data (`names`,
    `documents.stream_names`), else the paper's sensors."""
    return data.inputs_name(row["modalities"], names)


def collapse_notes(doc: dict[str, Any], split: str) -> dict[str, dict[str, str]]:
    """Row name -> property -> its collapse flag on `split` (`findings.collapse_text`; '' where no
    seed collapsed)."""
    return {
        r["name"]: {p: findings.collapse_text(r["collapsed"][split][p], "level") for p in PROPERTIES}
        for r in doc["rows"]
    }


def table(doc: dict[str, Any]) -> str:
    """One line per property: chance (1 / levels), then per split its majority level and each row's
    accuracy with its collapse flag beside the paper's (on recorded data beside the best row's)."""
    recorded, names = documents.recorded(doc), documents.stream_names(doc)
    header = ["Property", "Chance, 1 / levels [%]"]
    for split, title in SPLITS.items():
        header.append(f"Majority level, {title} [%]")
        header += [
            f"{title}: {row_title(r, names)} [%] "
            f"({'recorded data / row − best row [pp]' if recorded else 'ours / paper'})"
            for r in doc["rows"]
        ]
    notes = {split: collapse_notes(doc, split) for split in SPLITS}
    body = []
    for p in PROPERTIES:
        line = [p, f"{doc['chance'][p]:.2f}"]
        for split in SPLITS:
            line.append(findings.majority_cell(doc["majority"][split][p], "level"))
            ours = [stats.mean_sd(100 * np.asarray(r["accuracy"][split][p])) for r in doc["rows"]]
            gaps = documents.best_gaps([m for m, _ in ours])
            paper = "train" if split == "test" else "holdout"
            for r, (mean, sd), gap in zip(doc["rows"], ours, gaps):
                compared = gap if recorded else f"{doc['paper'][p][paper + '_' + r['name']]:.2f}"
                line.append(f"{mean:.2f} ± {sd:.2f}{notes[split][r['name']][p]} / {compared}")
        body.append(line)
    return results_files.markdown_table(header, body)


def markdown(doc: dict[str, Any]) -> str:
    recorded = documents.recorded(doc)
    fabrics = (
        f"Fabrics of the test trials: {doc['fabrics']['test']}; of the holdout trials: {doc['fabrics']['holdout']} "
        "(trials without a property's level are ignored for it)."
        if recorded
        else f"Training fabrics on the test day: {doc['fabrics']['test']} (class 0 has no properties and is ignored); "
        f"holdout fabrics: {doc['fabrics']['holdout']}. The paper reports means only."
    )
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc),
        fabrics,
        "",
        table(doc),
        findings.baseline_note("level")
        + " A property counts as above chance only where its mean over seeds is above its majority level.",
        "",
        "| Row | Train wall time [s] | Checkpoint (all seeds) |",
        "|---|---|---|",
        *[
            f"| {row_title(r, documents.stream_names(doc))} | {r['wall_s']:.1f} | `{r['checkpoint']}` |"
            for r in doc["rows"]
        ],
        "",
    ]
    lines += findings.claims_markdown(doc, "the paper's claims about this table, on the holdout fabrics")
    return "\n".join(lines)


STUDY = runner.Study(
    "properties",
    ROWS,
    n_seeds=5,
    eval_splits=tuple(SPLITS),
    split_names=data.SPLITS,
    document=document,
    checklist=lambda doc: checklist(
        {r["name"]: {p: np.asarray(r["accuracy"]["holdout"][p]) for p in PROPERTIES} for r in doc["rows"]},
        doc["chance"],
        doc["majority"]["holdout"],
        collapse_notes(doc, "holdout"),
        {r["name"]: r["collapsed"]["holdout"] for r in doc["rows"]},
    ),
    markdown=markdown,
    module=__name__,
    choose_rows="choose the rows with --rows",
    checkpoints=True,
    summary=lambda row: ", ".join(
        f"holdout {p} {stats.format_mean_sd(row.accuracy('holdout', p))} %" for p in PROPERTIES
    ),
    # recorded data's holdouts are its own holdout split: the catalog's fabric ids are not its classes
    recorded_settings={"exclude_fabrics": ()},
)
run = STUDY.run  # every study module has `run`: the training studies through `runner.run_study`
