"""A recipe sweep: every point of a grid over `Config` fields, trained on the ablation's rows.

    python -m experiments.sweep --grid=width=32,64 --grid=epochs=2,4 --seeds=2
    python -m experiments.sweep --grid='cnn_features=4,8;8,16' --rows=image,flow,internal

A recipe (width, epochs, learning rate, the camera encoder's size, ...) is chosen for every row
of the modality ablation at once, so it is judged by the validation accuracy averaged over the
rows, not by one row's. The grid is the cartesian product of the `--grid` fields' values; every
point is the preset, the `--set` overrides and the point's fields (`RowSpec.config`: a row
sets its backbone, inputs and fusion itself, so those are chosen with `--rows`, never swept). Every
(point, row) trains all seeds in one vmapped program (`row_training.train_rows`) on sequences loaded
once for the whole sweep, or once per distinct value of the fields that decide the sequences
(`loading.SEQUENCE_FIELDS`, e.g. seq_len) where the grid varies one. No checkpoints: a rerun
measures afresh.

Per (point, row): validation and test accuracy (mean ± SD over seeds, the best-validation
model's), the last epoch's training accuracy (counted on minibatches with dropout on), the
training wall time of the multi-seed program (compilation included) and the parameter count
and single-sequence inference latency (`inference_cost.measure_inference`). Per point: the validation and
test accuracy averaged over the rows and the training time summed over them. The best point is
the one with the highest mean validation accuracy (the first in grid order on a tie); the test
day is reported beside it, never used to choose.
"""

from __future__ import annotations

import itertools
import typing
from typing import Any, Mapping, Sequence

import numpy as np

from fabricjax.config import Config, format_override, parse_override
from fabricjax.errors import UserError
from fabricjax.reporting import results_files, stats
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import ablation_rows, documents, inference_cost, loading, row_training, runner
from fabricjax.studies.machinery.progress import Progress
from fabricjax.studies.machinery.rows import RowSpec, check_overrides
from fabricjax.studies.machinery.trained import TrainedRow

# The separators between a --grid field's values: ';' always (needed when the field is a tuple,
# whose own items are comma-separated, e.g. cnn_features=4,8;8,16), ',' for a scalar field
# without ';'.
TUPLE_SEPARATOR, SCALAR_SEPARATOR = ";", ","
GRID_HELP = (
    "field=v1,v2,... e.g. --grid=epochs=2,4; ';' between values of a tuple field, e.g. --grid='cnn_features=4,8;8,16'"
)
HEAD = "fabric"  # the sweep ranks recipes by fabric accuracy
N_SEEDS = 2  # seeds per (point, row) by default


def parse_grid(texts: Sequence[str]) -> dict[str, tuple]:
    """--grid flags as {field: values typed by the field}, in the order given. Each value is read
    like --set (`config.parse_override`); a mistake is a one-line `UserError` naming the flag."""
    hints = typing.get_type_hints(Config)
    grid: dict[str, tuple] = {}
    for text in texts:
        flag = f"--grid={text}"
        field, sep, raw = (s.strip() for s in text.partition("="))
        if not sep or not field or not raw:
            raise UserError(f"{flag}: expected {GRID_HELP}")
        if field in grid:
            raise UserError(f"{flag}: {field} is swept by an earlier --grid; give all its values in one")
        tuple_field = typing.get_origin(hints.get(field)) is tuple
        separator = TUPLE_SEPARATOR if tuple_field or TUPLE_SEPARATOR in raw else SCALAR_SEPARATOR
        items = [v.strip() for v in raw.split(separator)]
        if not all(items):
            raise UserError(f"{flag}: an empty value between {separator!r} separators")
        try:
            values = tuple(parse_override(f"{field}={v}")[1] for v in items)
        except UserError as e:
            raise UserError(f"{flag}: {e}") from None
        if len(set(values)) < len(values):
            raise UserError(f"{flag}: a value is repeated")
        grid[field] = values
    return grid


def point_name(fields: Mapping[str, Any]) -> str:
    """How tables name a point: its fields as --set would write them, e.g. 'epochs=4 width=64'."""
    return " ".join(format_override(f, v) for f, v in fields.items())


def grid_points(grid: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """The cartesian product of the grid's values, the first field varying slowest."""
    return [dict(zip(grid, values)) for values in itertools.product(*grid.values())]


def check_grid(
    grid: Mapping[str, Sequence[Any]], overrides: Mapping[str, Any], rows: Sequence[RowSpec]
) -> dict[str, tuple]:
    """The grid, after the checks that need no data: not empty, no field the chosen `rows` or the
    preset decide, no field both swept and fixed by --set."""
    if not grid or not all(grid.values()):
        raise UserError(f"--grid: give at least one field with at least one value: {GRID_HELP}")
    grid = check_overrides(
        "sweep", {f: tuple(v) for f, v in grid.items()}, rows, "choose the ablation's rows with --rows"
    )
    if "preset" in grid:
        raise UserError(
            "--grid: the preset is not a grid field (its dataset is loaded once); run one sweep per --preset"
        )
    both = sorted(set(grid) & set(overrides))
    if both:
        raise UserError(
            f"--grid and --set both give {', '.join(both)}: a field is either swept (--grid) or fixed (--set)"
        )
    return grid


def plan(
    preset: str, grid: Mapping[str, Sequence[Any]], overrides: Mapping[str, Any], rows: Sequence[RowSpec]
) -> list[tuple[str, Config, dict[str, Any], RowSpec]]:
    """Every (point, row) as (unit name, config, point fields, row), every config built (and so
    checked) before any data is read. The unit name is also its log folder: <field=value>/.../<row>."""
    units = []
    for fields in grid_points(grid):
        for row in rows:
            try:
                config = row.config(preset, {**overrides, **fields})
            except ValueError as e:
                raise UserError(f"--grid point {point_name(fields)}: {e}") from None
            if not getattr(config, f"{HEAD}_head"):
                raise UserError(
                    f"--grid point {point_name(fields)}: the sweep ranks recipes by {HEAD} accuracy, so "
                    f"{HEAD}_head must stay on"
                )
            units.append(
                ("/".join([*(format_override(f, v) for f, v in fields.items()), row.name]), config, fields, row)
            )
    return units


def _pct(values) -> tuple[float, float]:
    return stats.mean_sd(100 * np.asarray(values, np.float64))


def last_epoch(curves) -> np.ndarray:
    """Each seed's value at its last trained epoch, from (seeds, epochs) curves: early stopping
    leaves the epochs after it NaN."""
    return np.array([seed[~np.isnan(seed)][-1] for seed in np.asarray(curves, np.float64)])


def entry(
    trained: TrainedRow, fields: Mapping[str, Any], row: RowSpec, test, latency_repeats: int, recorded: bool = False
) -> dict[str, Any]:
    """One (point, row): accuracies (per seed and mean ± SD, %), cost, config and curves; on
    `recorded` data the row is named by the data's names for its inputs (`test.names`)."""
    val_mean, val_sd = _pct(trained.accuracy("val", HEAD))
    test_mean, test_sd = _pct(trained.accuracy("test", HEAD))
    last_train = last_epoch(trained.results.metrics["epochs"][f"train/accuracy/{HEAD}"])
    record = trained.doc(["test"])
    return {
        "point": point_name(fields),
        "fields": dict(fields),
        "row": row.name,
        "display_name": ablation_rows.label(
            row.modalities,
            trained.config.backbone,
            trained.config.fusion_norm,
            test.names if recorded else None,
            trained.config.augment_rotation,
        ),
        "val_mean": val_mean,
        "val_sd": val_sd,
        "test_mean": test_mean,
        "test_sd": test_sd,
        "train_last_epoch_mean": float(100 * last_train.mean()),
        "train_s": trained.seconds,
        **inference_cost.measure_inference(trained, test, latency_repeats),
        **record,
    }


def summarise(points: Sequence[dict[str, Any]], entries: Sequence[dict[str, Any]]) -> tuple[list[dict[str, Any]], int]:
    """Per point: validation and test accuracy averaged over its rows (each row weighs the same),
    training time summed over them; and the index of the best point by mean validation accuracy
    (the first in grid order on a tie)."""
    out = []
    for fields in points:
        name = point_name(fields)
        of_point = [e for e in entries if e["point"] == name]
        out.append(
            {
                "name": name,
                "fields": dict(fields),
                "rows": len(of_point),
                "val_mean_over_rows": float(np.mean([e["val_mean"] for e in of_point])),
                "test_mean_over_rows": float(np.mean([e["test_mean"] for e in of_point])),
                "train_s": float(sum(e["train_s"] for e in of_point)),
            }
        )
    best = int(np.argmax([p["val_mean_over_rows"] for p in out]))  # argmax: the first maximum
    return out, best


def _by_load(units: Sequence[tuple]) -> list[list[tuple]]:
    """The units grouped by the sequences they read, one load each (one for a grid that leaves the
    sequences alone), each group in training order."""
    by_key: dict[tuple, list] = {}
    for unit in units:
        by_key.setdefault(loading.sequence_key(unit[1]), []).append(unit)
    return [row_training.in_training_order(group, lambda unit: unit[1]) for group in by_key.values()]


def _train_loads(
    groups: Sequence[Sequence[tuple]], seeds, preset: str, latency_repeats: int, where: Location, progress, labels
) -> tuple[dict[str, dict[str, Any]], list[dict[str, Any]], dict[str, Any]]:
    """Train each load's units on its sequences, one load at a time: (each unit's entry by name,
    what each load read, the results JSON's header from the first load)."""
    summary = lambda r: (  # noqa: E731
        f"val {stats.format_mean_sd(r.accuracy('val', HEAD))} %, test "
        f"{stats.format_mean_sd(r.accuracy('test', HEAD))} %"
    )
    entries, loads, head = {}, [], None
    for group in groups:
        study = row_training.train_rows(
            "sweep",
            [(name, config) for name, config, _, _ in group],
            seeds,
            eval_splits=["test"],
            split_names=loading.TRAIN_VAL_TEST,
            data_dir=where.data_dir,
            workdir=where.workdir,
            label=labels.__getitem__,
            summary=summary,
            progress=progress,
        )
        if head is None:
            head = documents.header(
                "sweep",
                module=__name__,
                command=where.command,
                preset=preset,
                seeds=seeds,
                dataset=study.dataset,
                train_s=0.0,
            )
        loads.append(
            {**{f: getattr(group[0][1], f) for f in loading.SEQUENCE_FIELDS}, **documents.dataset_doc(study.dataset)}
        )
        for name, _, fields, row in group:
            entries[name] = entry(
                study.rows[name], fields, row, study.dataset.sets["test"], latency_repeats, study.dataset.recorded
            )
        del study  # frees these sequences before the next load

    return entries, loads, head


def run(
    *,
    grid: Mapping[str, Sequence[Any]],
    n_seeds: int = N_SEEDS,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    latency_repeats: int = 100,
    where: Location = Location(),
) -> dict[str, Any]:
    """Train every grid point on every chosen row of the ablation (all by default); write
    results/sweep.{md,json}; return the JSON."""
    chosen = ablation_rows.select(rows)
    overrides = check_overrides("sweep", overrides, chosen, "choose the ablation's rows with --rows")
    grid = check_grid(grid, overrides, chosen)
    seeds = runner.seed_list(n_seeds)
    units = plan(preset, grid, overrides, chosen)

    # one load per distinct sequence key, the units of each load trained together; the progress log
    # counts every unit of the sweep
    groups = _by_load(units)
    order = [u for group in groups for u in group]
    progress = Progress(
        "sweep", len(order), [row_training.row_kind(c) for _, c, _, _ in order], [c.epochs for _, c, _, _ in order]
    )
    labels = {name: f"{point_name(fields)} | {row.label}" for name, _, fields, row in order}
    entries, loads, head = _train_loads(groups, seeds, preset, latency_repeats, where, progress, labels)

    flat = [entries[name] for name, _, _, _ in units]  # grid order, then the table's row order
    points, best = summarise(grid_points(grid), flat)
    head["train_s"] = sum(e["train_s"] for e in flat)
    head["dataset"].update({k: sum(d[k] for d in loads) for k in ("generate_s", "load_s", "layout_s")})
    doc = {
        **head,
        "grid": {f: list(v) for f, v in grid.items()},
        "overrides": dict(overrides),
        "rows": [r.name for r in chosen],
        "loads": loads,
        "best": {**points[best], "index": best},
        "points": points,
        "entries": flat,
    }
    return results_files.write(where.results_dir(), doc, markdown)


def _values(values: Sequence[Any]) -> str:
    return ", ".join(",".join(map(str, v)) if isinstance(v, (list, tuple)) else str(v) for v in values)


def markdown(doc: dict[str, Any]) -> str:
    """The page: the grid and how each number is measured, the best point, then every point and
    every point's rows."""
    return "\n".join([*_intro_markdown(doc), *_points_markdown(doc), *_entries_markdown(doc)])


def _intro_markdown(doc: dict[str, Any]) -> list[str]:
    """The title, where the numbers come from, the grid, the loads, the columns and the best point."""
    best, n_rows = doc["best"], len(doc["rows"])
    fixed = (
        ", ".join(
            f"`{format_override(f, tuple(v) if isinstance(v, list) else v)}`" for f, v in doc["overrides"].items()
        )
        or "none"
    )
    lines = [
        "# Recipe sweep over the ablation's rows",
        "",
        documents.header_markdown(doc),
        f"- grid: {'; '.join(f'`{f}` in {{{_values(v)}}}' for f, v in doc['grid'].items())}: "
        f"{len(doc['points'])} points x {n_rows} rows ({', '.join(doc['rows'])})",
        f"- every point is the preset `{doc['preset']}`, the fixed fields ({fixed}) and its own fields; each "
        f"row sets its "
        "backbone, inputs and fusion normalisation",
    ]
    if len(doc["loads"]) > 1:
        lines.append(
            f"- sequences loaded {len(doc['loads'])} times, once per distinct "
            + "; ".join(
                ", ".join(f"{f}={d[f]}" for f in loading.SEQUENCE_FIELDS if f != "preset") + f": {d['sequences']}"
                for d in doc["loads"]
            )
        )
    lines += [
        "- val / test: the best-validation model's accuracy, mean ± SD over seeds; train, last epoch: "
        "training accuracy "
        "of the last epoch, counted on minibatches with dropout on; train [s]: wall time of the row's "
        "multi-seed program, "
        "compilation included; latency: `predict_one` compiled ahead of time on one test sequence after "
        "warm-up, first seed's model",
        "",
        f"**Best point by validation accuracy averaged over the {n_rows} rows: `{best['name']}`**, "
        f"mean validation {best['val_mean_over_rows']:.2f} %, mean test {best['test_mean_over_rows']:.2f} %, "
        f"training {best['train_s']:.0f} s for the {n_rows} rows ({len(doc['seeds'])} seeds each).",
        "",
        "## Points",
        "",
    ]
    return lines


def _points_markdown(doc: dict[str, Any]) -> list[str]:
    """Each point's validation and test accuracy averaged over the rows, the best in bold."""
    best, n_rows = doc["best"], len(doc["rows"])
    body = [
        [
            f"**{p['name']}**" if i == best["index"] else p["name"],
            f"{p['val_mean_over_rows']:.2f}",
            f"{p['test_mean_over_rows']:.2f}",
            f"{p['train_s']:.0f}",
        ]
        for i, p in enumerate(doc["points"])
    ]
    return [
        results_files.markdown_table(
            [
                "point",
                f"val, mean over {n_rows} rows [%]",
                f"test, mean over {n_rows} rows [%]",
                "training, all rows [s]",
            ],
            body,
        )
    ]


def _entries_markdown(doc: dict[str, Any]) -> list[str]:
    """Each point's rows: accuracy, training time, size and latency."""
    body = [
        [
            e["point"],
            e["display_name"],
            f"{e['val_mean']:.2f} ± {e['val_sd']:.2f}",
            f"{e['test_mean']:.2f} ± {e['test_sd']:.2f}",
            f"{e['train_last_epoch_mean']:.1f}",
            f"{e['train_s']:.1f}",
            f"{e['params']:,}",
            f"{e['latency_p50_ms']:.2f}",
            f"{e['latency_p99_ms']:.2f}",
        ]
        for e in doc["entries"]
    ]
    header = [
        "point",
        "row",
        "val [%]",
        "test [%]",
        "train, last epoch [%]",
        "train [s]",
        "params",
        "latency p50 [ms]",
        "latency p99 [ms]",
    ]
    return ["## Per point and row", "", results_files.markdown_table(header, body)]
