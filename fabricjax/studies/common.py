"""What every study shares: per-preset training configs, the dataset, multi-seed rows, reporting.

A study is a list of rows (one `Config` each) trained on sequences loaded ONCE for the union of
the rows' modalities; each row selects its own inputs (`train.select` takes the config's
modalities) and trains all seeds in one vmapped program (`train.train_and_evaluate`).

Where the data comes from: `data_dir` (a folder of real recordings, see WORKSPACE.md) if given,
else the simulated dataset of the preset, written on first use by `sim.ensure_dataset` (camera
frames are rendered only when some row needs images or optical flow).
"""

from __future__ import annotations

import dataclasses
import hashlib
import shlex
import sys
import time
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from absl import logging

from fabricjax import data, report, sim, stats, train, workspace
from fabricjax.config import Config
from fabricjax.errors import UserError

# Training settings per preset (configs are code). The model and optimiser fields not named here
# keep `Config`'s defaults, which follow the paper.
#   smoke    a tiny model for tests (XLA compilation dominates): the numbers mean nothing.
#   default  the README's main command (16-row ablation x 5 seeds on the paper-scale dataset, ~5900
#            training sequences; measured time in results/ablation.md). Narrower than the paper's
#            model, small CNNs. The recipe was chosen by the Minsound row's validation accuracy
#            (5 seeds) among recipes costing at most ~55 s per audio row on a 2-core CPU:
#              batch 32, 2 epochs, constant LR 2e-3      val 68.1 %   (37 s)
#              batch 32, 2 epochs, cosine,  LR 2e-3      val 71.9 %   (48 s)
#              batch 32, 2 epochs, cosine,  LR 4e-3      val 78.0 %   (54 s)
#              batch 16, 1 epoch,  cosine               val 62.7 %   (37 s)
#              batch  8, 1 epoch,  cosine               val 68.0 %   (39 s)
#              batch 16, 2 epochs, cosine               val 82.2 %   (55 s)   <- chosen
#              batch 32, 3 epochs, cosine               val 85.7 %   (76 s, over the cost bound)
#            (times measured while other jobs shared the cores). Image rows read 30x40 frames
#            (the paper's 60x80 in the paper preset): the per-sequence rotation is a gather that
#            XLA:CPU runs at ~230 ms per 5-seed step at 60x80 against ~50 ms at 30x40.
#   paper    `Config`'s defaults at the paper's sequence length (N=200): a GPU job.
PRESET_TRAINING: dict[str, dict[str, Any]] = {
    "smoke": dict(
        width=16, n_heads=4, n_layers=1, ffn=32, audio_hidden=(32, 16), proprio_hidden=(16, 16),
        cnn_features=(4, 8), epochs=2, batch_size=16,
    ),
    "default": dict(
        width=32, n_heads=4, n_layers=2, ffn=64, audio_hidden=(64, 32), proprio_hidden=(32, 32),
        cnn_features=(4, 8), epochs=2, batch_size=16, learning_rate=2e-3, lr_schedule="cosine", image_size=(30, 40),
    ),
    "paper": dict(),
}


def study_config(preset: str, **overrides) -> Config:
    """The preset's training config with `overrides` (flag values) on top."""
    return Config(preset=preset, **{**PRESET_TRAINING[preset], **overrides})


def seed_list(n_seeds: int) -> tuple[int, ...]:
    if n_seeds < 1:
        raise UserError(f"need at least one seed, got {n_seeds}")
    return tuple(range(n_seeds))


def select_rows(rows: Sequence, names: Sequence[str] | None, name=lambda r: r.name) -> list:
    """The rows named in `names` (all when None), in the table's order; unknown names raise."""
    if not names:
        return list(rows)
    known = [name(r) for r in rows]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise UserError(f"unknown rows {unknown}; choose from {known}")
    return [r for r in rows if name(r) in names]


@dataclasses.dataclass
class Dataset:
    """Sequences of every split, and what it took to get them (reported apart from training)."""

    sets: dict[str, data.SequenceSet]
    folder: Path
    source: str  # "recorded" | "simulated"
    generate_s: float  # simulating missing archives (0 for recorded data or a finished dataset)
    load_s: float  # features (cached after the first run) and sequences


# The splits a study that evaluates on the lab test day needs (no cafe or holdout features computed).
TRAIN_VAL_TEST = ("train", "val", "test")


def load_dataset(config: Config, *, data_dir=None, workdir=None, split_names: Sequence[str] = data.SPLITS) -> Dataset:
    """The splits a study evaluates as sequences of `config.modalities` (the union it needs), loaded once."""
    t0 = time.perf_counter()
    if data_dir:
        folder, source = workspace.dataset_dir(config.preset, workdir, data_dir), "recorded"
    else:
        streams = ("audio", "proprio") + (("images",) if {"image", "flow"} & set(config.modalities) else ())
        folder, source = sim.ensure_dataset(config.preset, workdir, streams=streams), "simulated"
    t1 = time.perf_counter()
    sets = data.load_sequences(config, folder, workdir=workdir, split_names=split_names)
    t2 = time.perf_counter()
    logging.info("dataset %s (%s): %s", folder, source, {k: len(v) for k, v in sets.items()})
    return Dataset(sets, Path(folder), source, t1 - t0, t2 - t1)


def union_modalities(configs: Sequence[Config]) -> tuple[str, ...]:
    return tuple(sorted({m for c in configs for m in c.modalities}))


def load_for_rows(configs: Sequence[Config], *, data_dir=None, workdir=None, split_names: Sequence[str] = data.SPLITS) -> Dataset:
    """The sequences of every modality any row uses, loaded once for all rows."""
    merged = dataclasses.replace(configs[0], modalities=union_modalities(configs))
    return load_dataset(merged, data_dir=data_dir, workdir=workdir, split_names=split_names)


# Training time of a row relative to a row without camera inputs, by the costliest camera input
# it uses: the default preset's measured per-row wall times in results/ablation.md (Minsight
# image rows 124-141 s, optical-flow rows 47-58 s, the others 30-64 s, mean 43 s: about 3.1 and
# 1.2 times).
CAMERA_COST = {"image": 3.1, "flow": 1.2}


def relative_cost(config: Config) -> float:
    """A row's expected training time in units of an audio / proprioception row (`CAMERA_COST`)."""
    return max([1.0] + [CAMERA_COST[m] for m in config.modalities if m in CAMERA_COST])


class Progress:
    """Logs 'row i/n' with the elapsed time and an ETA: the time per unit of relative cost of the
    rows done so far, times the relative cost of the rows left (equal costs unless given), so a
    camera row run first does not inflate the estimate for the audio rows after it."""

    def __init__(self, study: str, n_rows: int, costs: Sequence[float] | None = None):
        self.costs = list(costs) if costs is not None else [1.0] * n_rows
        if len(self.costs) != n_rows:
            raise ValueError(f"{n_rows} rows but {len(self.costs)} costs")
        self.study, self.n, self.done, self.t0 = study, n_rows, 0, time.perf_counter()

    def start(self, name: str) -> None:
        logging.info("%s: row %d/%d %s ...", self.study, self.done + 1, self.n, name)

    def eta(self, elapsed: float) -> float:
        """Seconds left, from `elapsed` seconds for the rows done."""
        return elapsed / sum(self.costs[: self.done]) * sum(self.costs[self.done :])

    def finish(self, name: str, seconds: float, summary: str) -> None:
        self.done += 1
        elapsed = time.perf_counter() - self.t0
        logging.info(
            "%s: row %d/%d %s done in %.1f s: %s (elapsed %s, ETA %s)",
            self.study, self.done, self.n, name, seconds, summary, _hms(elapsed), _hms(self.eta(elapsed)),
        )


def _hms(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}m{s:02d}s"


@dataclasses.dataclass
class Row:
    """One trained row: all seeds' metrics (leading seed axis) and its wall time."""

    name: str
    config: Config
    results: train.Results
    seconds: float

    def accuracy(self, split: str, head: str = "fabric") -> np.ndarray:
        return np.asarray(self.results.metrics["eval"][split]["accuracy"][head], np.float64)

    def predictions(self, split: str, head: str = "fabric") -> np.ndarray:
        return np.asarray(self.results.metrics["eval"][split]["predictions"][head])


def train_row(
    name: str,
    config: Config,
    sets: Mapping[str, data.SequenceSet],
    seeds: Sequence[int],
    eval_splits: Sequence[str],
    checkpoint_dir=None,
    log_dir=None,
) -> Row:
    """Train all seeds of one row and evaluate the best-validation models on `eval_splits`;
    with `log_dir` (`workspace.logs_dir`) its training curves are written there as it trains."""
    data_sets = {"train": sets["train"], "val": sets["val"], **{s: sets[s] for s in eval_splits}}
    t0 = time.perf_counter()
    results = train.train_and_evaluate(config, data_sets, seeds, workdir=checkpoint_dir, log_dir=log_dir)
    return Row(name, config, results, time.perf_counter() - t0)


def checkpoint_dir(study: str, row: str, config: Config, seeds: Sequence[int], workdir=None) -> Path:
    """A checkpoint directory per (row, config, seeds): reruns resume, other settings start afresh."""
    tag = hashlib.sha1(f"{config.dumps()}{list(seeds)}".encode()).hexdigest()[:8]
    return workspace.checkpoints_dir(f"{study}/{row}-{tag}", workdir)


def logs_dir(study: str, row: str, workdir=None) -> Path:
    """Where a row's training curves go (`workspace.logs_dir`): the row's latest run, whatever its settings."""
    return workspace.logs_dir(study, row, workdir)


def paired_tests(a: Row, b: Row, split: str, labels: np.ndarray, head: str = "fabric") -> dict[str, stats.WilcoxonResult]:
    """Wilcoxon signed-rank tests of row `b` against row `a` on `split`, under both pairings.

    per_seed: accuracy of b and a for the same seed (same key, same data); the exact test over n
    seeds cannot give p below 2 / 2^n.
    per_sample: correctness (0/1) of b and a on the same sequence and seed, pooled over seeds
    (many ties: normal approximation). Sequences of one trial and the seeds' shared data are not
    independent, so this p-value is optimistic; it is reported because it is what a per-sample
    comparison gives, not as the headline.
    """
    if b.results.seeds != a.results.seeds:
        raise ValueError(f"rows {a.name} and {b.name} were trained with different seeds")
    n = len(a.results.seeds)
    valid = np.asarray(labels) >= 0
    correct = lambda r: (r.predictions(split, head) == labels)[:, valid].astype(np.float64)  # noqa: E731
    return {
        "per_seed": stats.wilcoxon(
            b.accuracy(split, head), a.accuracy(split, head), pairing=f"per seed: {split} accuracy of the same seed, {n} seeds"
        ),
        "per_sample": stats.wilcoxon(
            correct(b), correct(a),
            pairing=f"per {split} sequence: correctness (0/1) on the same sequence and seed, pooled over {n} seeds",
        ),
    }


def results_path(results=None) -> Path:
    return workspace.results_dir(results)


def write_outputs(results, name: str, markdown: str, doc: dict[str, Any]) -> tuple[Path, Path]:
    """results/<name>.md and .json, atomically."""
    out = results_path(results)
    return report.write_text(out / f"{name}.md", markdown), report.write_json(out / f"{name}.json", doc)


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
    }


def wilcoxon_doc(w: stats.WilcoxonResult) -> dict[str, Any]:
    return {**dataclasses.asdict(w), "describe": w.describe()}


def header_markdown(doc: dict[str, Any]) -> str:
    """Where the numbers come from: command, preset, data, machine, time."""
    d, m = doc["dataset"], doc["machine"]
    seeds = doc["seeds"]
    return "\n".join([
        f"- command: `{doc['command']}`",
        f"- preset: {doc['preset']}; {d['source']} dataset `{d['folder']}`; sequences {d['sequences']}",
        f"- seeds: {len(seeds)} ({seeds[0]}-{seeds[-1]}), mean ± SD (sample SD) over seeds",
        f"- machine: {m['cpu']} ({', '.join(m.get('vector_units') or ['vector units not recorded'])}), {m['cores']} cores, JAX {m['jax']} on {m['jax_backend']} ({len(m['devices'])} devices)",
        f"- time: training {doc['train_s']:.0f} s in all (per row below, compilation included); "
        f"data apart from that: simulation {d['generate_s']:.0f} s, features and sequences {d['load_s']:.0f} s",
        "",
    ])


def command_line() -> str:
    """How this process was started, as a command to paste."""
    argv = list(sys.argv)
    if argv and argv[0].endswith(".py") and "experiments" in argv[0]:
        argv[0] = "-m experiments." + Path(argv[0]).stem
        return "python " + " ".join([argv[0]] + [shlex.quote(a) for a in argv[1:]])
    return " ".join(shlex.quote(a) for a in argv)
