"""Live classification of one trial as a command (`python -m experiments.stream`): the model
(a checkpoint, or a quick one-seed model of a preset, trained once and checkpointed), the trial
(an archive, or the first test-day trial of the model's dataset), the live printout and
results/stream.json. The streaming itself is `fabricjax.inference.live`.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np

from fabricjax import catalog, sim
from fabricjax.inference import confidence, live
from fabricjax.reporting import results_files
from fabricjax.store import archive, dataset_index, splits
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents
from fabricjax.studies.machinery.quick_model import quick_model


def format_step(r: live.StepResult, label: int, meta: dict | None = None) -> str:
    """One line of the live printout: running prediction, its calibrated confidence, the posterior
    accumulated over the windows so far (and whether the sequential rule has decided), latency;
    classes named by the trial's `meta` (its label map, else the catalog's)."""
    if r.probs is None:
        return f"step {r.step:5d}  {r.time_s:6.2f} s  filling window  {r.latency_ms:6.2f} ms"
    k, j = int(np.argmax(r.probs)), int(np.argmax(r.posterior))
    mark = "correct" if k == label else "wrong"
    post = (
        f"posterior {live.class_name(j, meta)} {r.posterior[j]:.3f} ({r.windows} "
        f"windows){'  decided' if r.decided else ''}"
    )
    return (
        f"step {r.step:5d}  {r.time_s:6.2f} s  {live.class_name(k, meta):<28s} p={r.probs[k]:.2f}  {mark:<7s} "
        f"{r.latency_ms:6.2f} ms  {post}"
    )


def first_test_trial(folder, workdir=None) -> str:
    """Path of the first test-day trial of a dataset folder (a class the model knows)."""
    index = dataset_index.load_index(folder, workdir)
    roles = splits.assign_roles([e.meta for e in index.entries])
    for e, role in zip(index.entries, roles):
        if role == "test" and e.meta["label"] < catalog.N_CLASSES:
            return str(index.path(e))
    raise archive.ArchiveError(index.root, "<folder>", "no test-day trial of a known class")


def _model_and_trial(checkpoint_dir, archive_path, preset: str, overrides, where: Location):
    """(graphdef, params, config, temperature, checkpoint folder, trial archive): `checkpoint_dir`'s
    model, else a quick model of `preset`; `archive_path`, else its dataset's first test-day trial."""
    if checkpoint_dir is not None:
        graphdef, params, config, temperature = live.restore_model(checkpoint_dir)
    else:
        graphdef, params, config, checkpoint_dir = quick_model(
            preset, overrides, workdir=where.workdir, data_dir=where.data_dir
        )
        temperature = confidence.load_temperature(checkpoint_dir, 0) or 1.0
    if archive_path is None:
        folder = where.data_dir or sim.ensure_dataset(
            config.preset, where.workdir, streams=("audio", "proprio"), progress=False
        )
        archive_path = first_test_trial(folder, where.workdir)
    return graphdef, params, config, temperature, checkpoint_dir, archive_path


def _outcome(summary: Mapping[str, Any], realtime: bool) -> tuple[str, str]:
    """The replay's outcome in two lines: the sequential decision, then the first correct one, the
    accuracy over decided steps and the latencies."""
    first, step, d = summary["time_to_first_correct_s"], summary["first_correct_step"], summary["decision"]
    decision = f"sequential decision (posterior {confidence.DECISION_THRESHOLD:g}): " + (
        "none before the trial ended"
        if d is None
        else f"{d['fabric']} ({'correct' if d['correct'] else 'wrong'}) at {d['time_s']:.2f} s (step "
        f"{d['step']}, {d['windows']} windows, posterior {d['posterior']:.3f})"
    )
    first_correct = (
        f"first correct decision: {'never' if first is None else f'{first:.2f} s (step {step})'}; "
        f"accuracy over {summary['decided_steps']} decided steps "
        f"{100 * (summary['accuracy_over_decided_steps'] or 0):.1f} %; "
        f"per-step latency p50 {summary['latency_p50_ms']:.2f} ms, p99 {summary['latency_p99_ms']:.2f} ms"
        + (f"; {summary['late_steps']} of {summary['steps']} results came after their 20 ms slot" if realtime else "")
    )
    return decision, first_correct


def run(
    *,
    archive_path=None,
    checkpoint_dir=None,
    preset: str = "default",
    overrides: Mapping[str, Any] | None = None,
    realtime: bool = True,
    print_every: int = 0,
    out: Callable[[str], None] = print,
    view: bool = False,
    view_save=None,
    where: Location = Location(),
) -> dict:
    """Classify one trial live and write results/stream.json; returns its document.

    The model is `checkpoint_dir`'s (any `train_and_evaluate` checkpoint of a streamable config),
    else a quick one-seed model of `preset` with `overrides` (trained once, then restored from its
    checkpoint).
    The trial is `archive_path`, else the first test-day trial of the model's dataset.
    With `view` (a Rerun viewer) or `view_save` (a .rrd file) each step's sensor data and result
    are logged as they come (`fabricjax.inference.view`); the logging runs between the timed updates, so
    the latencies are the model's, but in real time it can make steps late.
    """
    watch = view or view_save is not None
    if watch:
        from fabricjax.inference import view as trial_view

        if view_save is None:
            trial_view.require_display("--view_save")
    graphdef, params, config, temperature, checkpoint_dir, archive_path = _model_and_trial(
        checkpoint_dir, archive_path, preset, overrides, where
    )
    trial = archive.read_archive(archive_path, images=watch)
    streamer = live.Streamer(graphdef, params, config, temperature, layout=archive.layout(trial.meta))
    label = int(trial.meta["label"])
    if watch:
        rec = trial_view.open_recording(view_save)
        viewer = trial_view.TrialView(rec, label, trial.meta)
    out(
        f"{archive_path}: {live.class_name(label, trial.meta)} (class {label}), {trial.n_steps} steps; model "
        f"{checkpoint_dir}, "
        f"N={streamer.n} steps ({streamer.n / archive.STEP_RATE:.2f} s), {'+'.join(config.modalities)}, "
        f"temperature {temperature:.3f}{'' if temperature != 1.0 else ' (none fitted: python -m experiments.decide)'}"
    )

    def show(r: live.StepResult) -> None:
        if print_every and (r.step % print_every == 0 or r.step == trial.n_steps - 1):
            out(format_step(r, label, trial.meta))
        if watch:
            viewer.log_step(trial_view.archive_step(trial, r.step))
            viewer.log_prediction(r)

    summary = live.replay(streamer, trial, realtime=realtime, on_step=show)
    if watch:
        rec.flush()
    for line in _outcome(summary, realtime):
        out(line)
    doc = {
        **documents.header(
            "stream",
            module=__name__,
            command=where.command,
            archive=str(archive_path),
            checkpoint=str(checkpoint_dir),
            config=config.to_json(),
        ),
        **summary,
    }
    return results_files.write(where.results_dir(), doc, None)
