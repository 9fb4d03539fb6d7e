"""Property perception (the paper's Table property_perception): stretchiness, roughness, thickness.

    python -m experiments.properties --seeds=5

Three property heads replace the fabric head (`property_heads=True, fabric_head=False`) and are
trained jointly. Fabrics 1 and 10 and the new fabrics 21-23 (`catalog.PROPERTY_HOLDOUTS`) are
never trained on; accuracies are reported on the test day's training fabrics (class 0 has no
properties: its labels are unknown and ignored) and on the five holdouts. Rows: Minsound
(internal audio + proprioception) and Minsound + Minsight (+ 60x80 images); proprioception is
always on, as in the paper. Chance is the paper's 1 / levels; the majority-level rate of each
evaluated split is reported too, since the levels are not balanced.

The paper's claims about the table are checked by `checklist` on the holdout fabrics. On recorded
data (`--data_dir`) the rows are compared with each other instead (`documents.recorded`), and the
holdouts are the trials of its holdout split (no class is excluded by the catalog's fabric ids);
the tables name each row by the data's names for its inputs (`data.inputs_name`: the rig file's
microphones and joints), while --rows still takes the row names (minsound, minsound+minsight).

The trained models (all seeds) are saved as an orbax checkpoint per row; `experiments.latents
--checkpoint=DIR` restores one for the t-SNE figure.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from fabricjax import catalog, data, stats
from fabricjax.studies.common import documents, findings, runner
from fabricjax.studies.common.runner import StudyRow

TITLE, PAPER = "Property perception", "Table property_perception"  # how results name the study, and what of the paper it reproduces

PROPERTIES = tuple(catalog.PROPERTY_LEVELS)
SPLITS = {"test": "training fabrics", "holdout": "holdout fabrics"}
SETTINGS = dict(property_heads=True, fabric_head=False, exclude_fabrics=catalog.PROPERTY_HOLDOUTS, image_resolution="down")


def _row(name: str, modalities: tuple[str, ...], train: tuple[float, ...], holdout: tuple[float, ...]) -> StudyRow:
    """A row and the paper's mean accuracy [%] (5 seeds) per property (`PROPERTIES` order) on
    the training fabrics and on the holdout fabrics."""
    paper = {"train": dict(zip(PROPERTIES, train)), "holdout": dict(zip(PROPERTIES, holdout))}
    return StudyRow(name, {**SETTINGS, "modalities": modalities}, name, paper)


# The paper's Table property_perception; proprioception is always on.
ROWS = (
    _row("minsound", ("internal", "proprio"), (97.40, 97.47, 97.59), (76.15, 40.23, 70.56)),
    _row("minsound+minsight", ("internal", "proprio", "image"), (85.99, 82.38, 90.43), (82.95, 33.94, 90.47)),
)


def document(trained: runner.Trained, chosen: Sequence[StudyRow], results) -> tuple[dict[str, Any], list]:
    """Per row its checkpoint and accuracies per property; chance, the majority-level rate and
    the fabrics of each evaluated split; the paper's numbers."""
    ds = trained.dataset
    out_rows = [
        {"name": r.name, "modalities": list(r.modalities), **trained.rows[r.name].doc(list(SPLITS))}
        for r in chosen
    ]
    paper = {p: {f"{split}_{r.name}": r.paper[split][p] for r in ROWS for split in ("train", "holdout")} for p in PROPERTIES}
    return {
        "chance": {p: 100.0 / n for p, n in catalog.PROPERTY_LEVELS.items()},
        "majority": {s: {p: majority_rate(ds.sets[s].labels[p]) for p in PROPERTIES} for s in SPLITS},
        "fabrics": {s: sorted(set(ds.sets[s].info["fabric_id"].tolist())) for s in SPLITS},
        **({} if ds.recorded else {"paper": paper}),
        "rows": out_rows,
        "samples": {s: documents.samples_doc(ds.sets[s]) for s in SPLITS},
    }, []


def checklist(holdout: dict[str, dict[str, np.ndarray]], chance: dict[str, float], majority: dict[str, float | None] | None = None) -> list[findings.Finding]:
    """The paper's claims about property perception on the holdout fabrics, as predicates over
    per-seed accuracies (`holdout`: row name -> property -> per-seed accuracy in [0, 1];
    `chance`: property -> chance accuracy in percent, the paper's 1 / levels; rows not run are
    skipped). `majority` (property -> the holdouts' majority-level rate in percent) is quoted in
    the evidence: the holdouts' levels are unbalanced, so 1 / levels is a low bar."""
    majority = majority or {}
    out = []
    for name in (r.name for r in ROWS):
        claim = f"{name}: every property is above chance on the holdout fabrics"
        if not (f := findings.missing(claim, [name], holdout)):
            above = {p: findings.mean_pct(holdout[name][p]) > chance[p] for p in PROPERTIES}
            f = findings.Finding(claim, all(above.values()), "; ".join(
                f"{findings.describe(p, holdout[name][p])} against chance {chance[p]:.1f} %"
                + (f" (majority level {majority[p]:.1f} %)" if majority.get(p) is not None else "") for p in PROPERTIES))
        out.append(f)
    minsound, both = (r.name for r in ROWS)
    for prop, better, worse in (("stretchiness", both, minsound), ("thickness", both, minsound), ("roughness", minsound, both)):
        claim = f"{better} beats {worse} on {prop} on the holdout fabrics"
        out.append(findings.missing(claim, [better, worse], holdout) or findings.at_least(
            claim, (better, holdout[better][prop]), (worse, holdout[worse][prop]), strict=True))
    return out


def majority_rate(labels: np.ndarray) -> float | None:
    """Accuracy [%] of always answering the most frequent known level (None without known labels)."""
    known = np.asarray(labels)[np.asarray(labels) >= 0]
    return None if known.size == 0 else 100.0 * np.bincount(known).max() / known.size


def row_title(row: dict[str, Any], names: dict[str, str]) -> str:
    """How the tables name a row: by the data's names for its inputs on recorded data (`names`,
    `documents.stream_names`), else by the paper's (the row's name)."""
    return data.inputs_name(row["modalities"], names) if names else row["name"]


def table(doc: dict[str, Any]) -> str:
    """One line per property: chance, then ours and the paper's per split and row (on recorded
    data ours and each row beside the best row on that split)."""
    recorded, names = documents.recorded(doc), documents.stream_names(doc)
    header = ["Property", "Chance [%]"]
    for split, title in SPLITS.items():
        header.append(f"Majority level, {title} [%]")
        header += [f"{title}: {row_title(r, names)} [%] ({'recorded data / row − best row [pp]' if recorded else 'ours / paper'})" for r in doc["rows"]]
    body = []
    for p in PROPERTIES:
        line = [p, f"{doc['chance'][p]:.2f}"]
        for split in SPLITS:
            maj = doc["majority"][split][p]
            line.append("–" if maj is None else f"{maj:.2f}")
            ours = [stats.mean_sd(100 * np.asarray(r["accuracy"][split][p])) for r in doc["rows"]]
            gaps = documents.best_gaps([m for m, _ in ours])
            paper = "train" if split == "test" else "holdout"
            for r, (mean, sd), gap in zip(doc["rows"], ours, gaps):
                compared = gap if recorded else f"{doc['paper'][p][paper + '_' + r['name']]:.2f}"
                line.append(f"{mean:.2f} ± {sd:.2f} / {compared}")
        body.append(line)
    return documents.markdown_table(header, body)


def markdown(doc: dict[str, Any]) -> str:
    recorded = documents.recorded(doc)
    fabrics = (f"Fabrics of the test trials: {doc['fabrics']['test']}; of the holdout trials: {doc['fabrics']['holdout']} "
               "(trials without a property's level are ignored for it)." if recorded else
               f"Training fabrics on the test day: {doc['fabrics']['test']} (class 0 has no properties and is ignored); "
               f"holdout fabrics: {doc['fabrics']['holdout']}. The paper reports means only.")
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc),
        fabrics,
        "",
        table(doc),
        "| Row | Train wall time [s] | Checkpoint (all seeds) |",
        "|---|---|---|",
        *[f"| {row_title(r, documents.stream_names(doc))} | {r['wall_s']:.1f} | `{r['checkpoint']}` |" for r in doc["rows"]],
        "",
    ]
    lines += findings.claims_markdown(doc, "the paper's claims about this table, on the holdout fabrics")
    return "\n".join(lines)


STUDY = runner.Study(
    "properties", ROWS, n_seeds=5, eval_splits=tuple(SPLITS),
    split_names=data.SPLITS, document=document,
    checklist=lambda doc: checklist({r["name"]: {p: np.asarray(r["accuracy"]["holdout"][p]) for p in PROPERTIES} for r in doc["rows"]},
                                    doc["chance"], doc["majority"]["holdout"]),
    markdown=markdown, choose_rows="choose the rows with --rows", checkpoints=True,
    summary=lambda row: ", ".join(f"holdout {p} {stats.format_mean_sd(row.accuracy('holdout', p))} %" for p in PROPERTIES),
    # recorded data's holdouts are its own holdout split: the catalog's fabric ids are not its classes
    recorded_settings={"exclude_fabrics": ()},
)
run = STUDY.run  # every study module has `run`: the training studies through `runner.run_study`
