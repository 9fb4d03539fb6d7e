"""A study's results file: where the numbers come from (`header`), per-row and per-sample
records, written as results/<study>.md and .json atomically (`write_outputs`)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from fabricjax import data, findings, report, stats, workspace
from fabricjax.studies.loading import Dataset
from fabricjax.studies.runner import Row


def results_path(results=None) -> Path:
    return workspace.results_dir(results)


def write_outputs(results, name: str, markdown: str, doc: dict[str, Any]) -> tuple[Path, Path]:
    """results/<name>.md and .json, atomically."""
    out = results_path(results)
    return report.write_text(out / f"{name}.md", markdown), report.write_json(out / f"{name}.json", doc)


def header(study: str, *, command: str | None, preset: str, seeds: Sequence[int], dataset: Dataset, train_s: float) -> dict[str, Any]:
    """The first fields of every training study's JSON: what ran (`command`: the command line,
    None when called from Python), on which data and machine, and how long training took."""
    return {
        "study": study,
        "command": command,
        "preset": preset,
        "seeds": list(seeds),
        "machine": report.machine(),
        "dataset": dataset_doc(dataset),
        "train_s": train_s,
    }


def header_markdown(doc: dict[str, Any]) -> str:
    """Where the numbers come from: command, preset, data, machine, time."""
    d = doc["dataset"]
    seeds = doc["seeds"]
    return "\n".join([
        command_markdown(doc["command"]),
        data_markdown(doc["preset"], d),
        f"- seeds: {len(seeds)} ({seeds[0]}-{seeds[-1]}), mean ± SD (sample SD) over seeds",
        machine_markdown(doc["machine"]),
        f"- time: training {doc['train_s']:.0f} s in all (per row below, compilation included); {data_time_markdown(d)}",
        "",
    ])


def data_time_markdown(d: dict[str, Any]) -> str:
    """The data's share of a study's time (`dataset_doc`): recorded data is read, never simulated."""
    load = f"features and sequences {d['load_s']:.0f} s"
    if d["source"] == "recorded":
        return f"data apart from that: {load} (recorded data, read as it is)"
    return f"data apart from that: simulation {d['generate_s']:.0f} s, {load}"


def data_markdown(preset: str, d: dict[str, Any]) -> str:
    """The preset and the dataset (`dataset_doc`) a study read."""
    if d["source"] == "recorded":
        return (f"- preset: {preset}; recorded data `{d['folder']}` ({len(d['classes'])} classes, chance "
                f"{100 / len(d['classes']):.1f} %); trials {d['trials']}; sequences {d['sequences']}")
    return f"- preset: {preset}; {d['source']} dataset `{d['folder']}`; sequences {d['sequences']}"


def machine_markdown(m: dict[str, Any]) -> str:
    """The machine (`report.machine`) a study ran on."""
    return (f"- machine: {m['cpu']} ({', '.join(m.get('vector_units') or ['vector units not recorded'])}), {m['cores']} cores, "
            f"JAX {m['jax']} on {m['jax_backend']} ({len(m['devices'])} devices)")


def command_markdown(command: str | None) -> str:
    return f"- command: `{command}`" if command else "- command: none (called from Python)"


def row_doc(row: Row, splits: Sequence[str]) -> dict[str, Any]:
    """A row's config, wall time and, per seed, accuracies and per-sample predictions of every head."""
    ev = row.results.metrics["eval"]
    return {
        "config": row.config.to_json(),
        "seeds": list(row.results.seeds),
        "wall_s": row.seconds,
        "best_epoch": np.asarray(row.results.metrics["best_epoch"]).tolist(),
        "epochs": {t: [[None if np.isnan(x) else float(x) for x in s] for s in v] for t, v in row.results.metrics["epochs"].items()},
        "accuracy": {s: {h: np.asarray(a, np.float64).tolist() for h, a in ev[s]["accuracy"].items()} for s in ("val", *splits)},
        "predictions": {s: {h: np.asarray(p).tolist() for h, p in ev[s]["predictions"].items()} for s in splits},
    }


def samples_doc(ss: data.SequenceSet) -> dict[str, Any]:
    """What each evaluated sequence is: labels and where it comes from (the predictions' columns)."""
    return {
        "labels": {k: v.tolist() for k, v in ss.labels.items()},
        **{k: ss.info[k].tolist() for k in ("fabric_id", "trial_key", "start")},
    }


def dataset_doc(ds: Dataset) -> dict[str, Any]:
    return {
        "folder": str(ds.folder),
        "source": ds.source,
        "generate_s": ds.generate_s,
        "load_s": ds.load_s,
        "sequences": {k: len(v) for k, v in ds.sets.items()},
        "trials": {k: c["trials"] for k, c in ds.split_counts().items()},
        "classes": list(ds.classes),
    }


def recorded(doc: dict[str, Any]) -> bool:
    """The results are of recorded data (`--data_dir`): compared row with row, never with the
    paper's numbers or the simulator's."""
    return doc["dataset"]["source"] == "recorded"


def title(doc: dict[str, Any], study: str, paper: str | None = None) -> str:
    """A study's heading: on recorded data it names the data, not what of the paper (`paper`, e.g.
    "Table ablation_table"; None: nothing of the paper's) it reproduces."""
    if recorded(doc):
        return f"# {study} on recorded data"
    return f"# {study} (the paper's {paper})" if paper else f"# {study}"


BEST_GAP = "Row − best row [pp]"  # the column recorded-data tables have instead of the paper's
RECORDED_NOTE = "Rows are compared with each other on the same recorded data and test trials."


def claims_markdown(doc: dict[str, Any], claims: str = "the paper's claims about this table") -> list[str]:
    """A table's closing section: the paper's `claims` checked (`doc["findings"]`), or on recorded
    data, which has no paper to check, the note that its rows are compared with each other."""
    if recorded(doc):
        return [RECORDED_NOTE, ""]
    return [f"## Findings checklist ({claims})", "", findings.markdown(doc["findings"])]


def best_gaps(means: Sequence[float]) -> list[str]:
    """Each row's mean [%] minus the best row's: how rows on recorded data are compared."""
    best = max(means)
    return [f"{m - best:+.2f}" for m in means]


def wilcoxon_doc(w: stats.WilcoxonResult) -> dict[str, Any]:
    return {**dataclasses.asdict(w), "describe": w.describe()}
