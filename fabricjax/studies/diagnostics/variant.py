"""A variant of a training study against its baseline: two results files, row by row.

    python -m experiments.ablation --seeds=5 --set=compute_dtype=bfloat16 --results=results/bfloat16
    python -m experiments.variant --baseline=results/ablation.json --variant=results/bfloat16/ablation.json \
        --results=results/bfloat16

A variant is one training study (ablation, bandwidth, noise, ...) rerun with some `Config` fields
changed (`--set`) on the same dataset and seeds. The baseline's published file is read, not
retrained. Per row trained in both, and per split: both means, the difference (variant minus
baseline) and the sample SD over seeds of the per-seed differences. A seed starts from the same
initial key in both runs, so each pair shares everything but the change, and a paired Wilcoxon
test over seeds says whether the difference is more than seed noise. The rows' training times
stand beside them: what the change costs or saves.

The two files must be the same study on the same dataset and seeds, and must differ in at least
one config field; otherwise the comparison is refused with one line naming the file and field.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from fabricjax.errors import UserError
from fabricjax.reporting import results_files, stats
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents

STUDY = "variant"
SPLITS = ("val", "test")
HEAD = "fabric"  # the class head every training study reports; property heads are not compared
PAIRING = "per seed: the same seed's accuracy in both runs"


def read(path: Path | str) -> dict[str, Any]:
    """A training study's results JSON (`results_files.write`), checked for the fields compared."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise UserError(f"{path}: no such results file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise UserError(f"{path}: not a readable results JSON ({e})") from None
    for field in ("study", "seeds", "dataset", "rows"):
        if not isinstance(doc, dict) or field not in doc:
            raise UserError(f"{path}: field '{field}' missing: not a training study's results file")
    return doc


def _same(field: str, baseline_value: Any, variant_value: Any, variant_path: Path) -> None:
    if baseline_value != variant_value:
        raise UserError(
            f"{variant_path}: field '{field}' is {variant_value!r} against the baseline's {baseline_value!r}: "
            "a variant must be the same study on the same data and seeds"
        )


def config_changes(baseline_rows: Sequence[dict], variant_rows: Sequence[dict]) -> dict[str, list]:
    """{field: [baseline value, variant value]} for every config field that differs in any
    compared row (rows are paired by name)."""
    changes: dict[str, list] = {}
    for b, v in zip(baseline_rows, variant_rows):
        for field in sorted(set(b["config"]) | set(v["config"])):
            old, new = b["config"].get(field), v["config"].get(field)
            if old != new:
                changes.setdefault(field, [old, new])
    return changes


def compare_row(b: dict[str, Any], v: dict[str, Any]) -> dict[str, Any]:
    """One row's comparison: per split, both runs' mean and SD, the mean difference and the SD of
    the per-seed differences, and the paired Wilcoxon test; the training wall times."""
    out: dict[str, Any] = {
        "name": b["name"],
        "display_name": b["display_name"],
        "baseline_wall_s": b.get("wall_s"),
        "variant_wall_s": v.get("wall_s"),
    }
    for split in SPLITS:
        base = np.asarray(b["accuracy"][split][HEAD], np.float64)
        var = np.asarray(v["accuracy"][split][HEAD], np.float64)
        diff_mean, diff_sd = stats.mean_sd(var - base)
        out[split] = {
            "baseline": stats.mean_sd(base),
            "variant": stats.mean_sd(var),
            "difference": diff_mean,
            "difference_sd": diff_sd,
            "wilcoxon": documents.wilcoxon_doc(stats.wilcoxon(var, base, pairing=PAIRING)),
        }
    return out


def compare(baseline_path: Path | str, variant_path: Path | str, *, command: str | None) -> dict[str, Any]:
    """The comparison document of `variant_path` against `baseline_path` (both `read`)."""
    baseline_path, variant_path = Path(baseline_path), Path(variant_path)
    baseline, variant = read(baseline_path), read(variant_path)
    for field in ("study", "seeds", "preset"):
        _same(field, baseline[field], variant[field], variant_path)
    for field in ("folder", "sequences"):
        _same(f"dataset.{field}", baseline["dataset"].get(field), variant["dataset"].get(field), variant_path)
    by_name = {r["name"]: r for r in baseline["rows"]}
    pairs = [(by_name[r["name"]], r) for r in variant["rows"] if r["name"] in by_name]
    if not pairs:
        raise UserError(f"{variant_path}: field 'rows' shares no row with {baseline_path}")
    changes = config_changes([b for b, _ in pairs], [v for _, v in pairs])
    if not changes:
        raise UserError(
            f"{variant_path}: field 'rows' trains every compared row with the baseline's config: nothing is varied"
        )
    header = documents.header(STUDY, module=__name__, command=command, seeds=variant["seeds"], preset=variant["preset"])
    return {
        **header,
        "of_study": variant["study"],
        "dataset": variant["dataset"],
        "baseline": {
            "file": str(baseline_path),
            "code": baseline.get("code"),
            "date": baseline.get("date"),
            "command": baseline.get("command"),
        },
        "variant": {
            "file": str(variant_path),
            "code": variant.get("code"),
            "date": variant.get("date"),
            "command": variant.get("command"),
        },
        "changes": changes,
        "rows": [compare_row(b, v) for b, v in pairs],
        "rows_not_compared": sorted(set(by_name) ^ {r["name"] for r in variant["rows"]}),
    }


def _pct(mean_sd: Sequence[float]) -> str:
    return f"{100 * mean_sd[0]:.2f} ± {100 * mean_sd[1]:.2f}"


def _seconds(s: float | None) -> str:
    return "" if s is None else f"{s:.0f}"


def markdown(doc: dict[str, Any]) -> str:
    changed = ", ".join(f"`{f}`: {old!r} → {new!r}" for f, (old, new) in doc["changes"].items())
    lines = [
        f"# {doc['of_study']}: a variant against its baseline",
        "",
        documents.header_markdown(doc).rstrip("\n"),
        f"- baseline: `{doc['baseline']['file']}` ({doc['baseline']['code']}, {doc['baseline']['date']}): "
        f"`{doc['baseline']['command']}`",
        f"- variant: `{doc['variant']['file']}` ({doc['variant']['code']}, {doc['variant']['date']}): "
        f"`{doc['variant']['command']}`",
        f"- changed: {changed}",
        f"- difference: variant − baseline in pp, mean ± SD over seeds of the per-seed differences (the same "
        f"seed in both runs); "
        "p: paired Wilcoxon signed-rank test over seeds, two-sided, exact "
        f"(smallest attainable p with {len(doc['seeds'])} seeds: {stats.min_exact_p(len(doc['seeds'])):.4g}); "
        "train [s]: each row's multi-seed training, compilation included, as each run measured it",
        "",
    ]
    table = []
    for r in doc["rows"]:
        val, test = r["val"], r["test"]
        table.append(
            [
                r["display_name"],
                _pct(test["baseline"]),
                _pct(test["variant"]),
                f"{100 * test['difference']:+.2f} ± {100 * test['difference_sd']:.2f}",
                f"{test['wilcoxon']['p_value']:.4g}",
                f"{100 * val['difference']:+.2f} ± {100 * val['difference_sd']:.2f}",
                _seconds(r["baseline_wall_s"]),
                _seconds(r["variant_wall_s"]),
            ]
        )
    lines.append(
        results_files.markdown_table(
            [
                "row",
                "baseline test [%]",
                "variant test [%]",
                "test difference [pp]",
                "p",
                "val difference [pp]",
                "baseline train [s]",
                "variant train [s]",
            ],
            table,
        )
    )
    agree = [
        r["display_name"]
        for r in doc["rows"]
        if r["test"]["wilcoxon"]["n_nonzero"] == len(doc["seeds"])
        and r["test"]["wilcoxon"]["p_value"] <= r["test"]["wilcoxon"]["min_attainable_p"]
    ]
    same = [r["display_name"] for r in doc["rows"] if r["test"]["wilcoxon"]["n_nonzero"] == 0]
    mean_abs = np.mean([abs(r["test"]["difference"]) for r in doc["rows"]])
    lines.append(
        f"Test accuracy: mean absolute difference over the {len(doc['rows'])} rows {100 * mean_abs:.2f} pp; "
        f"every seed moved the same way (p at its floor) in {len(agree)} rows"
        + (f" ({', '.join(agree)})" if agree else "")
        + f"; no seed moved in {len(same)} rows"
        + (f" ({', '.join(same)})." if same else ".")
    )
    if doc["rows_not_compared"]:
        lines.append(f"\nRows in only one of the files, not compared: {', '.join(doc['rows_not_compared'])}.")
    return "\n".join(lines) + "\n"


def run(baseline: Path | str, variant: Path | str, *, where: Location = Location()) -> dict[str, Any]:
    """Compare and write variant.md and .json into `where`'s results folder."""
    doc = compare(baseline, variant, command=where.command)
    results_files.write(where.results_dir(), doc, markdown)
    print(markdown(doc))
    return doc
