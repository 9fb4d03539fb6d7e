"""What accuracy costs in time: touch time, training time and inference latency per configuration.

    python -m experiments.cost --seeds=5                  # default preset, <= 20 min on 2 CPU cores
    python -m experiments.cost --seq_lens=25,50 --backbones=attention --widths= --bandwidths= \
        --modality_sets=internal+external                 # any subset of the sweep by flag

Time means two things to a robot: how long the hand must rub before it can decide (touch time,
N steps / 50 Hz) and what the decision costs in compute (training, inference). The sweep is one
factor at a time around a base point, so it grows with the sum of the dimensions, not the product:

    N x backbone     every sequence length with every backbone, at the base width, bandwidth and
                     modality set: accuracy against touch time for both backbones
    width            each width alone (FFN = 2 x width, as in the paper's 64 / 128)
    bandwidth        each PSD bandwidth alone
    modalities       each modality set alone
    paper            the paper's configuration (N=200, attention, width 64, 15 kHz, internal +
                     palm microphone) with N capped at the preset's shortest trial; marked in
                     the table and the plot

On recorded data (`--data_dir`) there is no paper point (the paper's inputs need not exist on a
rig, and its numbers are not the data's): the points are compared with each other, and touch time
is N steps at the data's own step rate.

Everything not swept (the base width, layers, epochs, ...) is the preset's (`presets.py`) with
the `--set` overrides on top; the base N is the preset's (or `--set=seq_len=...`), the base
backbone and modality set are the first of their flags. Lengths longer than the shortest trial are skipped and reported.

Per point: test accuracy (mean ± SD over seeds; all seeds train in one vmapped program) beside
its test sequences' majority class (`findings.majority`), flagged where a seed collapsed, training
wall time of that program (compilation included, no checkpoints, so a rerun measures afresh),
inference latency of one test sequence (`predict_one` compiled ahead of time after warm-up, result on the host,
p50 / p99), parameter count. Sequences do not overlap, so a longer N also means fewer training
sequences (T // N per trial): the accuracy-versus-N curve shows both effects, as in the paper's
protocol.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Sequence

import numpy as np
from absl import logging

from fabricjax.config import Config
from fabricjax.reporting import plots, results_files, stats
from fabricjax.sequences import data
from fabricjax.store import atomic
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents, findings, inference_cost, loading, row_training, runner
from fabricjax.studies.machinery.progress import Progress

PAPER = dict(seq_len=200, backbone="attention", width=64, bandwidth_khz=15.0, modalities=("internal", "external"))
MODALITY_ABBREVIATIONS = {"internal": "int", "external": "ext", "proprio": "prop", "flow": "flow", "image": "img"}
X_AXES = (
    ("touch_s", "touch time to a decision [s] (N steps / step rate)"),
    ("latency_p50_ms", "inference latency of one sequence, p50 [ms]"),
)


@dataclasses.dataclass(frozen=True)
class Point:
    name: str
    group: str
    config: Config


def _with_width(config: Config, width: int) -> Config:
    return dataclasses.replace(config, width=width, ffn=2 * width)


def point_name(config: Config, base: Config) -> str:
    """A short plot label: backbone and N, then whatever differs from the base point."""
    name = f"{'att' if config.backbone == 'attention' else 'tcn'} N{config.seq_len}"
    if (config.width, config.ffn) != (base.width, base.ffn):
        name += f" w{config.width}/{config.ffn}"  # width / FFN: a width point's FFN is 2 x width
    if config.bandwidth_khz != base.bandwidth_khz:
        name += f" {config.bandwidth_khz:g}kHz"
    if config.modalities != base.modalities:
        name += " " + "+".join(MODALITY_ABBREVIATIONS[m] for m in config.modalities)
    return name


def sweep_points(
    base: Config,
    seq_lens: Sequence[int],
    backbones: Sequence[str],
    widths: Sequence[int],
    bandwidths: Sequence[float],
    modality_sets: Sequence[tuple[str, ...]],
    paper: bool = True,
    max_len: int | None = None,
) -> tuple[list[Point], str | None]:
    """The sweep's points (duplicates dropped, first occurrence kept) and the paper point's name."""
    candidates = [
        ("N x backbone", dataclasses.replace(base, seq_len=n, backbone=b)) for b in backbones for n in seq_lens
    ]
    candidates += [("width", _with_width(base, w)) for w in widths]
    candidates += [("bandwidth", dataclasses.replace(base, bandwidth_khz=bw)) for bw in bandwidths]
    candidates += [("modalities", dataclasses.replace(base, modalities=tuple(ms))) for ms in modality_sets]
    paper_config = None
    if paper:
        n = min(PAPER["seq_len"], max_len or PAPER["seq_len"])
        fields = {k: v for k, v in PAPER.items() if k not in ("seq_len", "width")}
        paper_config = _with_width(dataclasses.replace(base, seq_len=n, **fields), PAPER["width"])
        candidates.append(("paper", paper_config))
    points: dict[Config, Point] = {}
    for group, config in candidates:
        if max_len is not None and config.seq_len > max_len:
            logging.warning(
                "cost: skipping %s: N=%d exceeds the shortest trial (%d steps)", group, config.seq_len, max_len
            )
            continue
        points.setdefault(config, Point(point_name(config, base), group, config))
    paper_name = points[paper_config].name if paper_config is not None else None
    return list(points.values()), paper_name


def pareto_front(points: Sequence[dict], key: str) -> list[str]:
    """Names of the points no other point beats on both `key` (lower) and accuracy (higher)."""
    order = sorted(points, key=lambda p: (p[key], -p["accuracy_mean"]))
    front, best = [], -np.inf
    for p in order:
        if p["accuracy_mean"] > best:
            front.append(p["name"])
            best = p["accuracy_mean"]
    return front


def measure(point: Point, sets, seeds: Sequence[int], latency_repeats: int, step_rate: float) -> dict[str, Any]:
    """Train all seeds of one point and measure what it costs (touch time at `step_rate`); its
    test sequences' majority class (`findings.majority`: a point's N decides its sequences) and the
    class each seed collapsed to (`findings.collapsed`)."""
    row = row_training.train_row(point.name, point.config, row_training.place_row(point.config, sets, ["test"]), seeds)
    labels = sets["test"].labels["fabric"]
    acc = 100 * row.accuracy("test")
    mean, sd = stats.mean_sd(acc)
    c = point.config
    return {
        "name": point.name,
        "group": point.group,
        "seq_len": c.seq_len,
        "touch_s": c.seq_len / step_rate,
        "backbone": c.backbone,
        "width": c.width,
        "bandwidth_khz": c.bandwidth_khz,
        "modalities": list(c.modalities),
        "train_sequences": len(sets["train"]),
        "accuracy": acc.tolist(),
        "accuracy_mean": mean,
        "accuracy_sd": sd,
        "majority": findings.majority(labels),
        "collapsed": findings.collapsed(row.predictions("test"), labels),
        "train_s": row.seconds,
        **inference_cost.measure_inference(row, sets["test"], latency_repeats),
        "config": c.to_json(),
    }


def run(
    *,
    n_seeds: int = 5,
    preset: str = "default",
    seq_lens: Sequence[int] = (25, 50, 100, 200),
    backbones: Sequence[str] = ("attention", "tcn"),
    widths: Sequence[int] = (32, 128),
    bandwidths: Sequence[float] = (2.5, 24.0),
    modality_sets: Sequence[Sequence[str]] = (
        ("internal", "external"),
        ("internal",),
        ("internal", "external", "proprio"),
    ),
    paper: bool = True,
    overrides: dict[str, Any] | None = None,
    latency_repeats: int = 100,
    where: Location = Location(),
) -> dict[str, Any]:
    """Train every point of the sweep; write results/cost.{md,json} and cost_pareto.png; return the JSON."""
    if not backbones or not modality_sets:
        raise ValueError("need at least one backbone and one modality set (the base point's)")
    seeds = runner.seed_list(n_seeds)
    base = Config.from_preset(
        preset, **{"backbone": backbones[0], "modalities": tuple(modality_sets[0]), **(overrides or {})}
    )
    first = loading.load_dataset(
        base, data_dir=where.data_dir, workdir=where.workdir, split_names=loading.TRAIN_VAL_TEST
    )
    base = first.config_for(base)  # the data's classes and step window
    max_len, step_rate = inference_cost.steps_and_rate(first.folder, where.workdir)
    paper = paper and not first.recorded  # recorded data is compared with itself, not with the paper's configuration
    points, paper_name = sweep_points(
        base, seq_lens, backbones, widths, bandwidths, [tuple(m) for m in modality_sets], paper=paper, max_len=max_len
    )
    skipped = sorted(
        {n for n in seq_lens if n > max_len} | ({PAPER["seq_len"]} if paper and PAPER["seq_len"] > max_len else set())
    )
    union = loading.union_modalities([p.config for p in points])
    widest = max(p.config.bandwidth_khz for p in points)
    progress = Progress("cost", len(points))
    rows, sets, loaded_n = [], None, None
    t_all = time.perf_counter()
    for p in sorted(points, key=lambda p: p.config.seq_len):
        n = p.config.seq_len
        if n != loaded_n:  # every point of one N shares the sequences, loaded once at the widest band
            load = dataclasses.replace(base, seq_len=n, modalities=union, bandwidth_khz=widest)
            sets = loading.load_dataset(
                load, data_dir=where.data_dir, workdir=where.workdir, split_names=loading.TRAIN_VAL_TEST
            ).sets
            loaded_n = n
        progress.start(p.name)
        r = measure(p, sets, seeds, latency_repeats, step_rate)
        rows.append(r)
        progress.finish(
            p.name,
            r["train_s"],
            f"test {r['accuracy_mean']:.2f} ± {r['accuracy_sd']:.2f} %, p50 {r['latency_p50_ms']:.2f} ms",
        )
    order = {p.name: i for i, p in enumerate(points)}
    rows.sort(key=lambda r: order[r["name"]])
    fronts = {key: pareto_front(rows, key) for key, _ in X_AXES}
    doc = documents.header("cost", module=__name__, command=where.command, preset=preset, seeds=seeds, dataset=first)
    doc["dataset"].update(shortest_trial_steps=max_len, step_rate=step_rate)
    doc = {
        **doc,
        "base": base.to_json(),
        "paper_point": paper_name,
        "skipped_seq_lens": skipped,
        "pareto_front": fronts,
        "total_s": time.perf_counter() - t_all,
        "points": rows,
    }
    with atomic.together():  # the figure, Markdown and JSON of this run, or none of them
        figure = plots.plot_pareto(where.results_dir() / "cost_pareto.png", rows, X_AXES, highlight=paper_name)
        return results_files.write(where.results_dir(), doc, markdown, [figure])


def markdown(doc: dict[str, Any]) -> str:
    base, d = doc["base"], doc["dataset"]
    lines = [
        documents.title(doc, "What accuracy costs in time"),
        "",
        documents.header_markdown(
            doc, f"the sweep took {doc['total_s'] / 60:.1f} min; all seeds of a point train in one vmapped program"
        ).rstrip("\n"),
        f"- shortest trial {d['shortest_trial_steps']} steps"
        + (
            f"; N = {', '.join(map(str, doc['skipped_seq_lens']))} skipped as longer" if doc["skipped_seq_lens"] else ""
        ),
        f"- base point: {base['backbone']}, N={base['seq_len']}, width {base['width']}, {base['bandwidth_khz']:g} kHz, "
        f"{'+'.join(base['modalities'])}, {base['n_layers']} layers, {base['epochs']} epochs; one factor "
        f"varied at a time",
        f"- touch time: N steps at {d['step_rate']:g} Hz; train: wall time of the multi-seed program incl. "
        f"compilation; "
        "latency: `predict_one` compiled ahead of time on one test sequence after warm-up (p50 / p99 of "
        "repeated calls)",
        f"- Pareto front (marked T for touch time, L for latency): "
        f"{', '.join(doc['pareto_front']['touch_s'])} | {', '.join(doc['pareto_front']['latency_p50_ms'])}",
        f"- figure: `{doc['figures'][0]}`"
        + ("; **bold**: the paper's configuration on this preset" if doc["paper_point"] else ""),
        "",
        *([documents.RECORDED_NOTE, ""] if documents.recorded(doc) else []),
        "",
    ]
    header = [
        "point",
        "N",
        "touch [s]",
        "backbone",
        "width",
        "band [kHz]",
        "modalities",
        "params",
        "test acc [%]",
        "majority class, test [%]",
        "train [s]",
        "p50 [ms]",
        "p99 [ms]",
        "front",
    ]
    rows, names = [], documents.stream_names(doc)
    for r in doc["points"]:
        front = "".join(
            t for t, k in (("T", "touch_s"), ("L", "latency_p50_ms")) if r["name"] in doc["pareto_front"][k]
        )
        name = f"**{r['name']}**" if r["name"] == doc["paper_point"] else r["name"]
        rows.append(
            [
                name,
                r["seq_len"],
                f"{r['touch_s']:.2f}",
                r["backbone"],
                r["width"],
                f"{r['bandwidth_khz']:g}",
                data.inputs_name(r["modalities"], names) if names else "+".join(r["modalities"]),
                f"{r['params']:,}",
                f"{r['accuracy_mean']:.2f} ± {r['accuracy_sd']:.2f}{findings.collapse_text(r['collapsed'])}",
                findings.majority_cell(r["majority"]),
                f"{r['train_s']:.0f}",
                f"{r['latency_p50_ms']:.2f}",
                f"{r['latency_p99_ms']:.2f}",
                front,
            ]
        )
    return "\n".join(lines) + results_files.markdown_table(header, rows) + f"\n{findings.baseline_note()}\n"
