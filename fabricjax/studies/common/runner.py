"""Training studies as data, and the one runner they all go through.

    STUDY = runner.Study("noise", rows=(runner.StudyRow(...), ...), n_seeds=10, eval_splits=("cafe", "test"), ...)
    doc = runner.run_study(STUDY, n_seeds=10, preset="default")     # what `experiments.noise` calls

A `Study` is its rows (`StudyRow`: a name, the `Config` fields the row sets, its label and the
paper's numbers for it), the splits it evaluates, and three functions: `document` (the study's
own part of the results JSON: its statistics and figures), `checklist` (the paper's claims as
predicates over that document) and `markdown` (its table). `run_study` does the rest, the same
way for every study: it refuses a `--set` of a field a row sets, picks the rows, builds their
configs, trains them (`train_rows`: sequences loaded ONCE for the union of the rows' inputs,
each row's seeds in one vmapped program), checks the paper's claims (never on recorded data)
and writes results/<study>.md and .json (`documents.write`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import re
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence, TypeVar

import numpy as np
from absl import logging

from fabricjax import presets, source
from fabricjax.config import CAMERA_MODALITIES, Config
from fabricjax.errors import UserError
from fabricjax.reporting import stats
from fabricjax.sequences import data
from fabricjax.store import archive, atomic, dataset_index, lock, workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.common import documents, loading, plan, recipe
from fabricjax.studies.common.trained import TrainedRow, TrainingRun
from fabricjax.training import checkpoint, train
from fabricjax.training.placement import place_ahead

if TYPE_CHECKING:
    from fabricjax.studies.common.findings import Finding

T = TypeVar("T")


def seed_list(n_seeds: int) -> tuple[int, ...]:
    if n_seeds < 1:
        raise UserError(f"need at least one seed, got {n_seeds}")
    return tuple(range(n_seeds))


@dataclasses.dataclass(frozen=True)
class StudyRow:
    """A row of a study's table: `name` (what --rows, logs and checkpoints call it), the `Config`
    fields it sets on top of the preset and the overrides (`settings`), how tables label it, and
    the paper's numbers for it (None where the paper has no such row)."""

    name: str
    settings: Mapping[str, Any]
    label: str
    paper: Mapping[str, Any] | None = None

    @property
    def modalities(self) -> tuple[str, ...]:
        return tuple(self.settings["modalities"])

    def config(self, preset: str, overrides: Mapping[str, Any], last: Mapping[str, Any] | None = None) -> Config:
        """The config the row trains with: the preset, `overrides`, the row's own fields, then
        `last` (a study's `recorded_settings`)."""
        return Config.from_preset(preset, **{**overrides, **self.settings, **(last or {})})


ALL_ROWS = "all"  # the word --rows takes for every row of a study's table
# A label's parts: what stands before a ':' ("TCN:"), its '+'-joined inputs, and what follows them ("(our
# step-LayerNorm fusion)", ", frames − session reference").
_LABEL_PARTS = re.compile(r"(?P<before>[^:]*:)?(?P<inputs>[^(,−]*)(?P<after>.*)")


def label_key(label: str) -> tuple[str, frozenset[str], str]:
    """A label as `select_rows` matches it. A user types "minsound+palm mic" for the row the tables
    print as "Minsound + palm mic", and the noise study prints "Minsound + proprioception + palm mic"
    for the inputs the ablation prints as "Minsound + palm mic + proprioception", so case, the spaces
    around '+' and the order of the inputs do not count; what stands before or after the inputs does
    (the ablation's "TCN: " and "(our step-LayerNorm fusion)" rows read the same inputs as another)."""
    parts = _LABEL_PARTS.fullmatch(" ".join(label.casefold().split()))
    before, inputs, after = (parts[k] or "" for k in ("before", "inputs", "after"))
    return before.removesuffix(":").strip(), frozenset(x.strip() for x in inputs.split("+")), after.strip()


def select_rows(
    rows: Sequence[StudyRow],
    names: Sequence[str] | None,
    groups: Mapping[str, Sequence[str]] | None = None,
    default: Sequence[str] | None = None,
) -> list[StudyRow]:
    """The rows named in `names`, in the table's order; None: the rows named in `default` (every
    row where it is None). Each of `names` is a row's name (what logs and checkpoints call it),
    its label (what the tables print, such as "Minsound + palm mic", matched by `label_key`), a key
    of `groups` (a named set of rows, e.g. the ablation's "paper") or `ALL_ROWS`, in any case; one
    that is none of these, or no name at all (`--rows=`), is a one-line error listing the choices."""
    groups = {ALL_ROWS: [r.name for r in rows], **{k.casefold(): list(v) for k, v in (groups or {}).items()}}
    if names is None:
        names = list(default) if default is not None else groups[ALL_ROWS]

    def row(name: str) -> StudyRow | None:
        return next((r for r in rows if r.name.casefold() == name.casefold()), None) or next(
            (r for r in rows if label_key(r.label) == label_key(name)), None
        )

    wanted = [n for name in names for n in groups.get(name.strip().casefold(), [name])]
    found = {n: row(n) for n in wanted}
    unknown = [n for n, r in found.items() if r is None]
    if unknown or not wanted:
        choices = ", ".join(r.name if r.label == r.name else f"{r.name} ({r.label})" for r in rows)
        said = f"unknown rows {unknown}" if unknown else "no rows given"
        raise UserError(
            f"{said}; choose a row's name or its label, in any case, or a group ({', '.join(groups)}): {choices}"
        )
    chosen = {r.name for r in found.values()}
    return [r for r in rows if r.name in chosen]


def check_overrides(study: str, overrides: Mapping | None, rows: Sequence[StudyRow], instead: str) -> dict:
    """`overrides` as a dict, after checking that none of them is a `Config` field that one of the
    study's `rows` sets itself: the row would silently replace the override, or the override
    would silently turn the row into another one. Such an override is a one-line error naming the
    field, the rows that set it and, `instead`, how to choose that dimension."""
    overrides = dict(overrides or {})
    setters: dict[str, list[str]] = {}
    for row in rows:
        for field in row.settings:
            setters.setdefault(field, []).append(row.name)
    clash = sorted(set(overrides) & set(setters))
    if clash:
        said = "; ".join(f"{field} per row itself ({_which_rows(setters[field], len(rows))})" for field in clash)
        raise UserError(f"the {study} study sets {said}; {instead}")
    return overrides


def load_chosen_rows(
    study: str,
    all_rows: Sequence[StudyRow],
    names: Sequence[str] | None,
    preset: str,
    overrides: Mapping | None,
    where: Location,
    split_names: Sequence[str],
) -> tuple[list[StudyRow], list[Config], list[loading.Dataset], list[str]]:
    """What a study without training (the probe, the day shift) reads: the chosen rows of
    `all_rows` (all for None), their configs, each row's sequences on `split_names` (rows that
    agree on `loading.SEQUENCE_FIELDS` share one load: the same object), and the splits that hold
    any. Rows that read frames against their session's reference are left out, with a warning,
    when the data has none and the rows were not asked for by name."""
    overrides = check_overrides(study, overrides, all_rows, "choose them with --rows")
    chosen = select_rows(all_rows, names)
    if where.data_dir and not names:  # recorded data: the rows it can feed, the others left out in one line
        chosen = feedable_rows(study, chosen, where)
    configs = [r.config(preset, overrides) for r in chosen]
    loads: dict[tuple, loading.Dataset] = {}
    for key in dict.fromkeys(loading.sequence_key(c) for c in configs):
        group = [c for c in configs if loading.sequence_key(c) == key]
        # another reading of the frames decides only the image's sequences: an earlier load that
        # differs in nothing else gives the rest, and only what it lacks is loaded
        base = next((d for k, d in loads.items() if _apart_from_reading(k, key)), None)
        if base is not None:
            have = set(next(iter(base.sets.values())).inputs)
            lacking = [(c, tuple(m for m in c.modalities if m == "image" or m not in have)) for c in group]
            group = [dataclasses.replace(c, modalities=ms) for c, ms in lacking if ms]
        try:
            ds = (
                loading.load_for_rows(group, data_dir=where.data_dir, workdir=where.workdir, split_names=split_names)
                if group
                else base
            )
        except archive.ArchiveError as e:
            if e.field != "reference" or names:
                raise
            logging.warning("%s: rows that read frames against their session's reference left out: %s", study, e)
            continue
        if base is not None and ds is not base:
            ds = dataclasses.replace(
                base,
                sets={
                    s: dataclasses.replace(x, inputs={**x.inputs, **ds.sets[s].inputs}) for s, x in base.sets.items()
                },
            )
        loads[key] = ds
    kept = [(r, c) for r, c in zip(chosen, configs) if loading.sequence_key(c) in loads]
    datasets = [loads[loading.sequence_key(c)] for _, c in kept]
    return [r for r, _ in kept], [c for _, c in kept], datasets, [s for s in split_names if len(datasets[0].sets[s])]


def split_by_inputs(rows: Sequence[StudyRow], have: set[str]) -> tuple[list[StudyRow], list[str]]:
    """(the rows whose inputs are all in `have`, the inputs some row needs that `have` lacks)."""
    return [r for r in rows if set(r.modalities) <= have], sorted({m for r in rows for m in r.modalities} - have)


def feedable_rows(study: str, rows: Sequence[StudyRow], where: Location) -> list[StudyRow]:
    """The rows of `rows` whose inputs the recorded data in `where.data_dir` has, saying in one
    line which it leaves out and why; none fed is a one-line error."""
    lay = archive.layout(dataset_index.load_index(where.data_dir, where.workdir).entries[0].meta)
    fed, lacking = split_by_inputs(rows, set(lay.modalities()))
    left = [r.name for r in rows if r not in fed]
    if not fed:
        raise UserError(f"{study}: none of its rows can be fed by {where.data_dir}: it has {lay.describe()}")
    if left:
        logging.warning(
            "%s: %d of its %d rows left out (%s): they need %s, which the data lacks",
            study,
            len(left),
            len(rows),
            ", ".join(left),
            ", ".join(lacking),
        )
    return fed


def _apart_from_reading(a: tuple, b: tuple) -> bool:
    """Two `loading.sequence_key`s that differ in `image_reference` alone."""
    reading = loading.SEQUENCE_FIELDS.index("image_reference")
    return a != b and a[:reading] + a[reading + 1 :] == b[:reading] + b[reading + 1 :]


def _which_rows(names: Sequence[str], n_rows: int) -> str:
    return f"every one of its {n_rows} rows" if len(names) == n_rows else f"rows {', '.join(names)}"


CAMERA_INPUTS = CAMERA_MODALITIES
ROW_KINDS = (*CAMERA_INPUTS, "other")


def row_kind(config: Config) -> str:
    """What a row's training time mostly depends on: its costliest input (a camera row trains
    several times longer than an audio row), else "other"."""
    return next((m for m in CAMERA_INPUTS if m in config.modalities), "other")


def in_training_order(items: Sequence[T], config: Callable[[T], Config]) -> list[T]:
    """`items` (rows, each with its `config(item)`) in the order they train: grouped by their
    camera input (`row_kind`), in the given order within a group. A study's rows share the inputs
    placed on the devices (`placement.place_sets`) within a memory budget, so a camera's frames are placed
    once for its group, instead of again each time a row of the other camera has pushed them out."""
    return sorted(items, key=lambda item: ROW_KINDS.index(row_kind(config(item))))


class Progress:
    """Logs 'row i/n' with the elapsed time and an ETA. Each row has a kind (`row_kind`) and an
    amount of work (default 1; the sweep's rows: their epochs); a row left is expected to take
    its work times the seconds per unit of work of the rows of its kind done so far (of every row
    done while none of its kind is), so a camera row run first does not inflate the estimate for
    the audio rows after it. The rates are this run's own: nothing measured elsewhere."""

    def __init__(
        self, study: str, n_rows: int, kinds: Sequence[str] | None = None, work: Sequence[float] | None = None
    ):
        self.kinds = list(kinds) if kinds is not None else ["other"] * n_rows
        self.work = list(work) if work is not None else [1.0] * n_rows
        if not len(self.kinds) == len(self.work) == n_rows:
            raise ValueError(f"{n_rows} rows but {len(self.kinds)} kinds and {len(self.work)} amounts of work")
        self.study, self.n, self.done, self.t0 = study, n_rows, 0, time.perf_counter()
        self.seconds: list[float] = []

    def start(self, name: str) -> None:
        logging.info("%s: row %d/%d %s ...", self.study, self.done + 1, self.n, name)

    def eta(self) -> float:
        """Seconds left, from the rows done (`finish`)."""
        done = range(self.done)

        def rate(rows) -> float:
            return sum(self.seconds[i] for i in rows) / max(sum(self.work[i] for i in rows), 1e-9)

        by_kind = {k: rate([i for i in done if self.kinds[i] == k]) for k in set(self.kinds[: self.done])}
        overall = rate(done)
        return sum(self.work[i] * by_kind.get(self.kinds[i], overall) for i in range(self.done, self.n))

    def exclude(self, seconds: float) -> None:
        """Leave `seconds` spent on something else (loading a later part's data) out of the
        elapsed time."""
        self.t0 += seconds

    def finish(self, name: str, seconds: float, summary: str) -> None:
        self.done += 1
        self.seconds.append(seconds)
        elapsed = time.perf_counter() - self.t0
        logging.info(
            "%s: row %d/%d %s done in %.1f s: %s (elapsed %s, ETA %s)",
            self.study,
            self.done,
            self.n,
            name,
            seconds,
            summary,
            _hms(elapsed),
            _hms(self.eta()),
        )


def _hms(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}m{s:02d}s"


def train_row(
    name: str,
    config: Config,
    sets: Mapping[str, data.SequenceSet],
    seeds: Sequence[int],
    eval_splits: Sequence[str],
    checkpoint_dir=None,
    log_dir=None,
) -> TrainedRow:
    """Train all seeds of one row on its part of `sets` (`data.narrow`) and evaluate the
    best-validation models on `eval_splits`; with `checkpoint_dir` the models are saved there,
    with `log_dir` (`workspace.logs_dir`) the training curves are written there as it trains."""
    row_sets = data.narrow({s: sets[s] for s in ("train", "val", *eval_splits)}, config)
    t0 = time.perf_counter()
    results = train.train_and_evaluate(config, row_sets, seeds, workdir=checkpoint_dir, log_dir=log_dir)
    return TrainedRow(name, config, results, time.perf_counter() - t0, Path(checkpoint_dir) if checkpoint_dir else None)


def train_fitted(
    study: str,
    name: str,
    config: Config,
    sets: Mapping[str, data.SequenceSet],
    seeds: Sequence[int],
    eval_splits: Sequence[str],
    workdir=None,
    checkpoints: bool = False,
) -> TrainedRow:
    """`train_row` of every point of `config`'s recipe grid (`recipe.points`), the point the
    validation split prefers kept (`recipe.choose`); its time is the whole grid's. A config
    without a grid is one point, reported as is."""
    configs = recipe.points(config)
    grid = []
    for point in configs:
        sub = name if len(configs) == 1 else f"{name}/{recipe.point_name(point)}"
        grid.append(
            train_row(
                name,
                point,
                sets,
                seeds,
                eval_splits,
                checkpoint_dir=checkpoint_dir(study, name, point, seeds, sets["train"].dataset, workdir)
                if checkpoints
                else None,
                log_dir=workspace.logs_dir(study, sub, workdir),
            )
        )
    chosen = recipe.choose(grid)
    return dataclasses.replace(
        chosen, seconds=sum(r.seconds for r in grid), recipe=recipe.document(config, grid, chosen)
    )


def checkpoint_dir(
    study: str, row: str, config: Config, seeds: Sequence[int], dataset: Mapping[str, str], workdir=None
) -> Path:
    """A checkpoint directory per (row, config, seeds, data, code): reruns resume; other settings,
    other data (`dataset`: `DatasetIndex.identity`, by content) or other code (`source.training`)
    start afresh instead of reusing what was trained on something else."""
    key = f"{config.dumps()}{list(seeds)}{checkpoint.STATE_VERSION}{dataset.get('content')}{source.training()}"
    return workspace.checkpoints_dir(f"{study}/{row}-{hashlib.sha1(key.encode()).hexdigest()[:8]}", workdir)


def _test_summary(row: TrainedRow) -> str:
    return f"test {stats.format_mean_sd(row.accuracy('test'))} %"


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
    summary: Callable[[TrainedRow], str] = _test_summary,
    check: Callable[[loading.Dataset], None] | None = None,
    progress: Progress | None = None,
    data_names: bool = False,
) -> TrainingRun:
    """Load the data every row needs once, then train each (name, config) row's seeds, in
    `in_training_order` (the rows come back in the order given).

    `eval_splits`: the splits every row is evaluated on (beside val); `split_names`: the splits
    loaded. `checkpoints`: keep each row's models (`checkpoint_dir`). `label` names a row in the
    progress log, `summary` says how it did there. `check` looks at the loaded data before any
    training (raise `UserError` for data the study cannot use). `progress`: a log shared with
    other calls (a study that loads its rows in several parts), else one for these rows.
    `data_names`: on recorded data, name each row in the log by its name and the data's own names
    for its inputs (the rig's microphones and joints), not by `label`."""
    configs = [c for _, c in rows]
    checkpoints_folder = workspace.checkpoints_dir(study, workdir)
    with (
        lock.hold(
            lock.lock_file(checkpoints_folder, workdir),
            f"the {study} study's checkpoints ({workspace.shown(checkpoints_folder)})",
            f"training {len(rows)} rows",
        ),
        loading.reading(configs[0].preset, data_dir, workdir),
    ):
        ds = loading.load_for_rows(configs, data_dir=data_dir, workdir=workdir, split_names=split_names)
        if check is not None:
            check(ds)
        rows = [(name, ds.fit(config)) for name, config in rows]  # the data's classes, step window and epochs
        if ds.recorded:  # what training will take, now that the data's size is known
            stages = plan.training(rows, len(seeds), len(ds.sets["train"]))
            print(
                plan.markdown(
                    f"{rows[0][1].preset} on recorded data", stages, len(rows), len(seeds), plan.free_disk(workdir)
                ),
                flush=True,
            )
        if data_names and ds.recorded:
            names, inputs = next(iter(ds.sets.values())).names, {n: c.modalities for n, c in rows}
            label = lambda name: f"{name} ({data.inputs_name(inputs[name], names)})"  # noqa: E731
        order = in_training_order(rows, lambda row: row[1])
        if progress is None:
            progress = Progress(study, len(rows), [row_kind(c) for _, c in order])
        else:  # started before this load
            progress.exclude(ds.generate_s + ds.load_s)
        trained, laid_out = {}, set()
        for name, config in order:
            camera = row_kind(config)
            # the group's camera input, once (`in_training_order`)
            if camera in CAMERA_INPUTS and camera not in laid_out:
                t0 = time.perf_counter()
                alone = dataclasses.replace(config, modalities=(camera,))
                # timed as the data's cost; each row's run finds these arrays kept (`placement.place_sets`)
                place_ahead(alone, data.narrow({s: ds.sets[s] for s in ("train", "val", *eval_splits)}, alone))
                ds.layout_s += time.perf_counter() - t0
                laid_out.add(camera)
            progress.start(label(name))
            trained[name] = row = train_fitted(study, name, config, ds.sets, seeds, eval_splits, workdir, checkpoints)
            progress.finish(label(name), row.seconds, summary(row))
        return TrainingRun(ds, {name: trained[name] for name, _ in rows})


def paired_tests(
    a: TrainedRow, b: TrainedRow, split: str, labels: np.ndarray, head: str = "fabric"
) -> dict[str, stats.WilcoxonResult]:
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
            b.accuracy(split, head),
            a.accuracy(split, head),
            pairing=f"per seed: {split} accuracy of the same seed, {n} seeds",
        ),
        "per_sample": stats.wilcoxon(
            correct(b),
            correct(a),
            pairing=f"per {split} sequence: correctness (0/1) on the same sequence and seed, pooled over {n} seeds",
        ),
    }


@dataclasses.dataclass(frozen=True)
class Study:
    """A training study as data: what `run_study` needs to train, check and write it.

    `document(trained, chosen, results)` returns the study's own part of the results JSON (rows,
    statistics, samples) and the figures it drew into the `results` folder; `checklist(doc)` the
    paper's claims about the table as `findings.Finding`s (skipped on recorded data);
    `markdown(doc)` the table people read. `recorded_settings`: `Config` fields every row sets on
    recorded data only (the property study's holdouts are the data's own holdout split).
    `recorded_fusions`: other `Config.fusion_norm`s each chosen row is also trained under on
    recorded data, as the row `<fusion>:<name>` (`fusion_twin`), so that the study can say which
    fusion the data needs: a cue steady within a sequence, which the paper's rescale erases, is
    what another rig may carry."""

    name: str
    rows: tuple[StudyRow, ...]
    n_seeds: int
    eval_splits: tuple[str, ...]
    split_names: tuple[str, ...]
    document: Callable[[TrainingRun, Sequence[StudyRow], Path], tuple[dict[str, Any], list[Path | None]]]
    checklist: Callable[[dict[str, Any]], list[Finding]]
    markdown: Callable[[dict[str, Any]], str]
    choose_rows: str = "choose them with --rows"  # how to pick what a row sets instead of --set
    checkpoints: bool = True  # save each row as it trains (`train.SAVE_EVERY_EPOCHS`): a killed run resumes mid-row
    summary: Callable[[TrainedRow], str] = _test_summary
    check: Callable[[loading.Dataset], None] | None = None
    recorded_settings: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    recorded_fusions: tuple[str, ...] = ()
    # named sets of rows that --rows takes as one word (besides `ALL_ROWS`), and the rows trained
    # when --rows is not given (None: every row)
    groups: Mapping[str, tuple[str, ...]] = dataclasses.field(default_factory=dict)
    default_rows: tuple[str, ...] | None = None

    def row(self, name: str) -> StudyRow:
        return next(r for r in self.rows if r.name == name)

    @property
    def row_names(self) -> list[str]:
        return [r.name for r in self.rows]

    def select(self, names: Sequence[str] | None) -> list[StudyRow]:
        """The rows `names` stand for (`select_rows`; None: the study's default rows)."""
        return select_rows(self.rows, names, self.groups, self.default_rows)

    def run(self, **kwargs) -> dict[str, Any]:
        """`run_study(self, **kwargs)`."""
        return run_study(self, **kwargs)


def fusion_twin(name: str, fusion_norm: str) -> str:
    """The name of row `name` trained under `fusion_norm` (a study's `recorded_fusions`)."""
    return f"{fusion_norm}:{name}"


def _with_fusion_twins(study: Study, rows: list[tuple[str, Config]]) -> list[tuple[str, Config]]:
    """`rows` and, for each, its twin under every `study.recorded_fusions` it is not already
    under, unless that twin is among `rows` itself."""
    names = {n for n, _ in rows}
    twins = [
        (fusion_twin(n, f), dataclasses.replace(c, fusion_norm=f))
        for n, c in rows
        for f in study.recorded_fusions
        if c.fusion_norm != f and fusion_twin(n, f) not in names
    ]
    return rows + twins


def run_study(
    study: Study,
    *,
    n_seeds: int | None = None,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: Mapping[str, Any] | None = None,
    where: Location = Location(),
    plan_only: bool = False,
) -> dict[str, Any]:
    """Train the chosen `rows` of `study` (all by default) with `n_seeds` seeds (the study's count
    by default), check the paper's claims and write results/<study>.md and .json; returns the JSON.
    The plan (`plan.stages`) is printed first; `plan_only` stops there, writing it as results/plan.md."""

    overrides = check_overrides(study.name, overrides, study.rows, study.choose_rows)
    if where.data_dir:  # the preset's recipe for recorded data, beneath the command line's
        overrides = {**presets.get(preset).recorded_training, **overrides}
    chosen = study.select(rows)
    if where.data_dir and not rows:  # recorded data: the rows it can feed, the others left out in one line
        chosen = feedable_rows(study.name, chosen, where)
    seeds = seed_list(study.n_seeds if n_seeds is None else n_seeds)
    own = dict(study.recorded_settings) if where.data_dir else {}
    row_configs = [(r.name, r.config(preset, overrides, own)) for r in chosen]
    if where.data_dir:
        row_configs = _with_fusion_twins(study, row_configs)
    labels = {r.name: r.label for r in study.rows}
    if not where.data_dir:  # what the run will take, before it starts (hours at the paper's scale)
        stages = plan.stages(preset, row_configs, len(seeds), where.workdir)
        print(plan.markdown(preset, stages, len(row_configs), len(seeds), plan.free_disk(where.workdir)), flush=True)
        if plan_only:
            return plan.write(where, study.name, preset, stages, len(row_configs), len(seeds))
    elif plan_only:
        raise UserError("--plan estimates what simulated data needs; recorded data (--data_dir) is there already")
    trained = train_rows(
        study.name,
        row_configs,
        seeds,
        eval_splits=study.eval_splits,
        split_names=study.split_names,
        data_dir=where.data_dir,
        workdir=where.workdir,
        checkpoints=study.checkpoints,
        label=lambda name: labels.get(name, name),
        summary=study.summary,
        check=study.check,
        data_names=True,
    )
    with atomic.together():  # the figures, Markdown and JSON of this run, or none of them
        body, figures = study.document(trained, chosen, where.results_dir())
        dtypes = (config.compute_dtype for _, config in row_configs)
        doc = {
            **documents.header(
                study.name,
                command=where.command,
                preset=preset,
                seeds=seeds,
                dataset=trained.dataset,
                compute_dtypes=dtypes,
                train_s=trained.train_s,
            ),
            **body,
        }
        # the checklist holds the paper's claims: recorded data is not the paper's
        doc["findings"] = [] if trained.dataset.recorded else [f.to_json() for f in study.checklist(doc)]
        return documents.write(where.results_dir(), doc, study.markdown, figures)
