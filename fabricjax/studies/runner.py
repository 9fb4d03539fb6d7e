"""Training a study's rows: named configs -> one dataset load -> every row's seeds -> `Trained`.

    trained = runner.train_rows("noise", [(name, config), ...], seeds, eval_splits=["cafe", "test"])

A study is a list of rows (one `Config` each) trained on sequences loaded ONCE for the union of
the rows' modalities (`loading.load_for_rows`); each row takes its own inputs (`data.narrow`)
and trains all seeds in one vmapped program (`train.train_and_evaluate`). What a study keeps for
itself: its rows, its statistics and its table (`documents` builds the results file around them).
"""

from __future__ import annotations

import dataclasses
import hashlib
import time
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from absl import logging

from fabricjax import data, stats, train, workspace
from fabricjax.config import Config
from fabricjax.errors import UserError
from fabricjax.studies import loading


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


def check_overrides(study: str, overrides: Mapping | None, row_settings: Mapping[str, Mapping[str, Any]], how: str) -> dict:
    """`overrides` as a dict, after checking that none of them is a `Config` field that one of the
    study's rows sets itself (`row_settings`: row name -> the fields that row sets on top of the
    overrides): the row would silently replace the override, or the override would silently turn
    the row into another one. Such an override is a one-line error naming the field, the rows that
    set it and `how` to choose that dimension instead."""
    overrides = dict(overrides or {})
    setters: dict[str, list[str]] = {}
    for row, fields in row_settings.items():
        for field in fields:
            setters.setdefault(field, []).append(row)
    clash = sorted(set(overrides) & set(setters))
    if clash:
        said = "; ".join(f"{field} per row itself ({_which_rows(setters[field], len(row_settings))})" for field in clash)
        raise UserError(f"the {study} study sets {said}; {how}")
    return overrides


def _which_rows(names: Sequence[str], n_rows: int) -> str:
    return f"every one of its {n_rows} rows" if len(names) == n_rows else f"rows {', '.join(names)}"


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

    def exclude(self, seconds: float) -> None:
        """Leave `seconds` spent on something else (loading a later part's data) out of the
        elapsed time the ETA is estimated from."""
        self.t0 += seconds

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
    """One trained row: all seeds' metrics (leading seed axis), its wall time and, where the study
    keeps the models, its checkpoint directory."""

    name: str
    config: Config
    results: train.Results
    seconds: float
    checkpoint: Path | None = None

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
    """Train all seeds of one row on its part of `sets` (`data.narrow`) and evaluate the
    best-validation models on `eval_splits`; with `checkpoint_dir` the models are saved there,
    with `log_dir` (`workspace.logs_dir`) the training curves are written there as it trains."""
    mine = data.narrow({s: sets[s] for s in ("train", "val", *eval_splits)}, config)
    t0 = time.perf_counter()
    results = train.train_and_evaluate(config, mine, seeds, workdir=checkpoint_dir, log_dir=log_dir)
    return Row(name, config, results, time.perf_counter() - t0, Path(checkpoint_dir) if checkpoint_dir else None)


def checkpoint_dir(study: str, row: str, config: Config, seeds: Sequence[int], workdir=None) -> Path:
    """A checkpoint directory per (row, config, seeds): reruns resume, other settings start afresh."""
    tag = hashlib.sha1(f"{config.dumps()}{list(seeds)}".encode()).hexdigest()[:8]
    return workspace.checkpoints_dir(f"{study}/{row}-{tag}", workdir)


@dataclasses.dataclass
class Trained:
    """A study's trained rows, in the order given, and the dataset they were trained on."""

    dataset: loading.Dataset
    rows: dict[str, Row]

    @property
    def train_s(self) -> float:
        return sum(r.seconds for r in self.rows.values())


def train_rows(
    study: str,
    rows: Sequence[tuple[str, Config]],
    seeds: Sequence[int],
    *,
    eval_splits: Sequence[str],
    split_names: Sequence[str] = data.SPLITS,
    data_dir=None,
    workdir=None,
    checkpoints: bool = False,
    label: Callable[[str], str] = str,
    summary: Callable[[Row], str] = lambda row: f"test {stats.format_mean_sd(row.accuracy('test'))} %",
    check: Callable[[loading.Dataset], None] | None = None,
    progress: Progress | None = None,
) -> Trained:
    """Load the data every row needs once, then train each (name, config) row's seeds.

    `eval_splits`: the splits every row is evaluated on (beside val); `split_names`: the splits
    loaded. `checkpoints`: keep each row's models (`checkpoint_dir`). `label` names a row in the
    progress log, `summary` says how it did there. `check` looks at the loaded data before any
    training (raise `UserError` for data the study cannot use). `progress`: a log shared with
    other calls (a study that loads its rows in several parts), else one for these rows."""
    configs = [c for _, c in rows]
    ds = loading.load_for_rows(configs, data_dir=data_dir, workdir=workdir, split_names=split_names)
    if check is not None:
        check(ds)
    rows = [(name, dataclasses.replace(config, n_classes=ds.n_classes)) for name, config in rows]  # the data's classes
    configs = [c for _, c in rows]
    if progress is None:
        progress = Progress(study, len(rows), [relative_cost(c) for c in configs])
    else:  # started before this load
        progress.exclude(ds.generate_s + ds.load_s)
    trained = {}
    for name, config in rows:
        progress.start(label(name))
        trained[name] = row = train_row(
            name, config, ds.sets, seeds, eval_splits,
            checkpoint_dir=checkpoint_dir(study, name, config, seeds, workdir) if checkpoints else None,
            log_dir=workspace.logs_dir(study, name, workdir),
        )
        progress.finish(label(name), row.seconds, summary(row))
    return Trained(ds, trained)


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
