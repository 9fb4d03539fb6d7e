"""Training studies as data, and the one runner they all go through.

    STUDY = runner.Study("noise", rows=(RowSpec(...), ...), n_seeds=10, eval_splits=("cafe", "test"), ...)
    doc = runner.run_study(STUDY, n_seeds=10, preset="default")     # what `experiments.noise` calls

A `Study` is its rows (`rows.RowSpec`: a name, the `Config` fields the row sets, its label and
the paper's numbers for it), the splits it evaluates, and four functions: `document` (the
study's own part of the results JSON: its statistics), `checklist` (the paper's claims as
predicates over that document), `markdown` (its table) and `figures` (drawn from the document).
The last two read the results JSON alone, so `render` draws a study's pages again from it,
training and reading nothing else: what `experiments.reproduce` does when only the code that
presents numbers changed. `run_study` does the rest,
the same way for every study: it refuses a `--set` of a field a row sets, picks the rows, builds
their configs, trains them (`row_training.train_rows`: sequences loaded ONCE for the union of
the rows' inputs, each row's seeds in one vmapped program), checks the paper's claims (never on
recorded data) and writes results/<study>.md and .json (`results_files.write`).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

from fabricjax import presets
from fabricjax.config import Config
from fabricjax.errors import UserError
from fabricjax.reporting import results_files
from fabricjax.store import atomic
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents, loading, plan, row_training
from fabricjax.studies.machinery.rows import RowSpec, check_overrides, feedable_rows, select_rows
from fabricjax.studies.machinery.trained import TrainedRow, TrainingRun

if TYPE_CHECKING:
    from fabricjax.studies.machinery.findings import Finding


def seed_list(n_seeds: int) -> tuple[int, ...]:
    if n_seeds < 1:
        raise UserError(f"need at least one seed, got {n_seeds}")
    return tuple(range(n_seeds))


@dataclasses.dataclass(frozen=True)
class Study:
    """A training study as data: what `run_study` needs to train, check and write it.

    `document(trained, chosen)` returns the study's own part of the results JSON (rows,
    statistics, what its figures show); `checklist(doc)` the paper's claims about the table as
    `findings.Finding`s (skipped on recorded data); `markdown(doc)` the table people read;
    `figures(doc, results)` the figures drawn from the JSON into the `results` folder.
    `recorded_settings`: `Config` fields every row sets on recorded data only (the property
    study's holdouts are the data's own holdout split).
    `recorded_fusions`: other `Config.fusion_norm`s each chosen row is also trained under on
    recorded data, as the row `<fusion>:<name>` (`fusion_twin`), so that the study can say which
    fusion the data needs: a cue steady within a sequence, which the paper's rescale erases, is
    what another rig may carry."""

    name: str
    rows: tuple[RowSpec, ...]
    n_seeds: int
    eval_splits: tuple[str, ...]
    split_names: tuple[str, ...]
    document: Callable[[TrainingRun, Sequence[RowSpec]], dict[str, Any]]
    checklist: Callable[[dict[str, Any]], list[Finding]]
    markdown: Callable[[dict[str, Any]], str]
    module: str  # the module that defines the study: its import closure is the code of its results
    figures: Callable[[dict[str, Any], Path], list[Path | None]] = lambda doc, results: []
    choose_rows: str = "choose them with --rows"  # how to pick what a row sets instead of --set
    checkpoints: bool = True  # save each row as it trains (`train.SAVE_EVERY_EPOCHS`): a killed run resumes mid-row
    summary: Callable[[TrainedRow], str] = row_training.summary_by_test
    check: Callable[[loading.Dataset], None] | None = None
    recorded_settings: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    recorded_fusions: tuple[str, ...] = ()
    # named sets of rows that --rows takes as one word (besides `ALL_ROWS`), and the rows trained
    # when --rows is not given (None: every row)
    groups: Mapping[str, tuple[str, ...]] = dataclasses.field(default_factory=dict)
    default_rows: tuple[str, ...] | None = None

    def row(self, name: str) -> RowSpec:
        return next(r for r in self.rows if r.name == name)

    @property
    def row_names(self) -> list[str]:
        return [r.name for r in self.rows]

    def select(self, names: Sequence[str] | None) -> list[RowSpec]:
        """The rows `names` stand for (`rows.select_rows`; None: the study's default rows)."""
        return select_rows(self.rows, names, self.groups, self.default_rows)

    def run(self, **kwargs) -> dict[str, Any]:
        """`run_study(self, **kwargs)`."""
        return run_study(self, **kwargs)


def fusion_twin(name: str, fusion_norm: str) -> str:
    """The name of row `name` trained under `fusion_norm` (a study's `recorded_fusions`)."""
    return f"{fusion_norm}:{name}"


def _with_fusion_twins(study: Study, rows: list[tuple[str, Config]]) -> list[tuple[str, Config]]:
    """`rows` and, for each, its twin under every `study.recorded_fusions` it is not already
    under, unless that twin is among `rows` itself; a twin the study declares as a row of its own
    trains with that row's settings (our variant's image rows read frames unrotated)."""
    names = {n for n, _ in rows}
    declared = {r.name: r.settings for r in study.rows}

    def twin(name: str, config: Config, fusion: str) -> Config:
        return dataclasses.replace(config, **declared.get(fusion_twin(name, fusion), {"fusion_norm": fusion}))

    twins = [
        (fusion_twin(n, f), twin(n, c, f))
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

    chosen = study.select(rows)
    overrides = check_overrides(study.name, overrides, chosen, study.choose_rows)
    if where.data_dir:  # the preset's recipe for recorded data, beneath the command line's
        overrides = {**presets.get(preset).recorded_training, **overrides}
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
    trained = row_training.train_rows(
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
        body = study.document(trained, chosen)
        dtypes = (config.compute_dtype for _, config in row_configs)
        doc = {
            **documents.header(
                study.name,
                module=study.module,
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
        figures = study.figures(doc, where.results_dir())
        return results_files.write(where.results_dir(), doc, study.markdown, figures, samples(study, trained))


def render(study: Study, results: Path) -> dict[str, Any]:
    """Draw `study`'s Markdown and figures again from its results JSON in the `results` folder
    and rewrite both with the JSON (its numbers as they were); trains and reads nothing else."""
    doc = json.loads((results / f"{study.name}.json").read_text())
    with atomic.together():
        return results_files.write(results, doc, study.markdown, study.figures(doc, results))


def samples(study: Study, trained: TrainingRun) -> dict[str, Any]:
    """The per-sample records of a training study (`results_files.SAMPLES`): every trained row's
    predictions on the study's evaluated splits, and what each evaluated sequence is."""
    sets = trained.dataset.sets
    return {
        "rows": {name: row.samples(study.eval_splits) for name, row in trained.rows.items()},
        "sequences": {s: documents.samples_doc(sets[s]) for s in study.eval_splits},
    }
