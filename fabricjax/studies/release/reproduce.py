"""Every table and figure of the paper on one preset, in order, and one report: REPORT.md.

    python -m experiments.reproduce                      # default preset, into workspace/results/
    python -m experiments.reproduce --results=results    # regenerates the report published in the repository

`run` goes through the plan (`reproduce_plan.PLAN`, fitted to recorded data by
`reproduce_plan.fit_plan`), skips each study that is up to date (`staleness.step_key`), draws
again from its results JSON each up-to-date study whose pages were drawn by other code that
presents numbers (`source.views`; `runner.render`: the training studies; the others have no
such path and run again) and runs the others, rewriting the manifest after every study so that
an interrupted run picks up where it stopped; then it writes REPORT.md (`reproduce_report`) and
README's results block (`reproduce_readme`).
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from fabricjax import presets, source
from fabricjax.errors import UserError
from fabricjax.reporting import results_files
from fabricjax.store import workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents, runner
from fabricjax.studies.machinery.plan import rates as training_rates
from fabricjax.studies.diagnostics import decide
from fabricjax.studies.paper import ablation, latents
from fabricjax.studies.release.reproduce_plan import (
    HEADLINE,
    LATENT_ROW,
    MANIFEST,
    PLAN,
    PUBLISHED_MANIFEST,
    REPORT,
    STUDIES,
    Step,
    command,
    estimate_s,
    fit_plan,
    minutes,
    n_rows,
    outputs,
    read_json,
    refuse_unknown,
)
from fabricjax.studies.release.reproduce_readme import headline, readme_block, write_readme_block
from fabricjax.studies.release.reproduce_report import write_report
from fabricjax.studies.release.staleness import data_fingerprint, step_key, today, upstream_key


def run(
    *,
    preset: str = "default",
    plan: Sequence[Step] = PLAN,
    overrides: Mapping[str, Any] | None = None,
    force: bool = False,
    where: Location = Location(command="python -m experiments.reproduce"),
    say: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Run every study of `plan` that is not up to date (all with `force`), then write REPORT.md
    from every study's results; returns the manifest. `where.command` is the command REPORT.md
    names for the whole run."""
    workdir, data_dir = where.workdir, where.data_dir
    presets.get(preset)  # an unknown preset is a one-line error before anything runs
    refuse_unknown([s.study for s in plan])
    overrides = dict(overrides or {})
    if data_dir:
        plan = fit_plan(plan, preset, data_dir, workdir, say)
    out = where.results_dir()
    manifest_path = out / MANIFEST
    manifest = read_json(manifest_path) or {}
    data = data_fingerprint(data_dir, workdir)
    prints = {step.study: today(step.study, data) for step in plan}

    keys: dict[str, str] = {}
    for step in plan:  # a study that reads another's results has that study's key in its own
        keys[step.study] = step_key(
            step, preset, overrides, prints[step.study], upstream_key(step.study, keys, manifest)
        )
    rendering = source.views()[: results_files.FINGERPRINT_DIGITS]
    redrawn = [s for s in plan if manifest.get(s.study, {}).get("rendering") != rendering]
    todo = [
        s
        for s in plan
        if force
        or manifest.get(s.study, {}).get("key") != keys[s.study]
        or not all(p.exists() for p in outputs(s.study, out))
        or (s in redrawn and _drawn_again(s.study) is None)
    ]
    redraw = [s for s in redrawn if s not in todo]

    say("\n".join(_plan_lines(plan, todo, redraw, manifest, preset, out, where)))

    t_all = time.perf_counter()
    for step in redraw:  # only the code that presents numbers changed: nothing trained, simulated or read
        runner.render(_drawn_again(step.study), out)
        manifest[step.study]["rendering"] = rendering
        results_files.write_json(manifest_path, manifest)
        say(f"reproduce: {step.study} drawn again from {step.study}.json")
    for step in todo:
        say(f"reproduce: {step.study} ...")
        manifest[step.study] = _run_step(
            step, preset, overrides, out, where, keys[step.study], prints[step.study], rendering
        )
        results_files.write_json(manifest_path, manifest)
        say(f"reproduce: {step.study} done in {minutes(manifest[step.study]['wall_s'])}")
    write_report(out / REPORT, manifest, preset, data, where.command, time.perf_counter() - t_all, len(todo))
    say(f"reproduce: wrote {out / REPORT}")
    head = headline(out, manifest, preset, where.command, data)
    if head is not None:
        results_files.write_json(out / HEADLINE, head)
        readme = out.parent / "README.md"
        if write_readme_block(readme, readme_block(head, out.name)):
            say(f"reproduce: wrote the results block of {readme}")
    return {s.study: manifest[s.study] for s in plan}


def _plan_lines(
    plan: Sequence[Step], todo, redraw, manifest: Mapping[str, Any], preset: str, out: Path, where: Location
) -> list[str]:
    """What the run will do, study by study (run, draw or skip), and the time it expects."""
    workdir, data_dir = where.workdir, where.data_dir
    lines = [f"reproduce: preset {preset}, results in {out}"]
    published = read_json(PUBLISHED_MANIFEST) or {}
    for step in plan:
        if step in todo:
            lines.append(f"  {step.study:<11} run   ~{minutes(estimate_s(step, preset, manifest, published))}")
        elif step in redraw:
            lines.append(f"  {step.study:<11} draw  (up to date; its pages again from its results JSON)")
        else:
            lines.append(
                f"  {step.study:<11} skip  (up to date: ran {manifest[step.study]['finished']}, "
                f"{minutes(manifest[step.study]['wall_s'])})"
            )
    total = [estimate_s(s, preset, manifest, published) for s in todo]
    known = sum(t for t in total if t is not None)
    data_note = ""
    if todo and not data_dir and not (workspace.dataset_dir(preset, workdir) / workspace.INDEX_NAME).exists():
        data_note = ", plus simulating the dataset and its features once (README gives the time)"
    if None in total:
        unknown = ", ".join(s.study for s, t in zip(todo, total) if t is None)
        published_presets = sorted({e.get("preset") for e in published.values() if isinstance(e, dict)} - {None})
        lines.append(
            f"  estimated time: none for {unknown}: no earlier run of the {preset} preset in {out} recorded "
            f"its wall time, "
            f"and the repository publishes those of the {', '.join(published_presets) or 'no'} preset; this "
            f"run records "
            f"its own, so the next one has an estimate{data_note}"
        )
    else:
        lines.append(
            f"  estimated time: {minutes(known)}{data_note} (scaled from an earlier run's wall times; other "
            f"machines differ)"
        )
    return lines


def _run_step(
    step: Step,
    preset: str,
    overrides: Mapping[str, Any],
    out: Path,
    where: Location,
    key: str,
    prints: Mapping[str, str | None],
    rendering: str,
) -> dict[str, Any]:
    """Run one study of the plan as the command that reruns it alone would; returns its manifest
    entry: its key and what the key was computed from (`prints`: its fingerprints), its time,
    command and commit, and the code its pages were drawn with (`rendering`)."""
    workdir, data_dir = where.workdir, where.data_dir
    t0 = time.perf_counter()
    checkpoint = names = None
    if step.study == "latents":
        checkpoint = _latent_checkpoint(out)
    elif step.study == "decide":
        folders, names = _decide_checkpoints(out, step.rows)
        checkpoint = ",".join(folders)
    cmd = command(step, preset, overrides, out, checkpoint, data_dir, workdir)
    kwargs = dict(where=dataclasses.replace(where, results=out, command=cmd))
    doc = None
    if step.study == "latents":
        latents.run(checkpoint, **kwargs)
    elif step.study == "decide":
        decide.run(folders, names=names, **kwargs)
    else:
        seeds = {"n_seeds": step.seeds} if step.seeds else {}
        doc = STUDIES[step.study].run(**seeds, preset=preset, rows=step.rows, overrides=overrides, **kwargs)
    wall = time.perf_counter() - t0
    return {
        "key": key,
        "wall_s": wall,
        "command": cmd,
        "finished": results_files.utc_now(),
        "commit": results_files.git_commit(),
        # what the key was computed from: `stale` recomputes it under later fingerprints
        "step": _as_json(dataclasses.asdict(step)),
        "overrides": _as_json(overrides),
        "fingerprints": prints,
        "rendering": rendering,  # the code its pages were drawn with (`source.views`)
        # what an estimate of a later run scales from: the study's, and each training row's (`plan.rates`)
        "preset": preset,
        "seeds": step.seeds,
        "rows": len(step.rows) if step.rows else n_rows(step.study),
        **(
            {"rates": training_rates(doc), "machine": documents.machine_line(doc["machine"])}
            if doc and step.seeds
            else {}
        ),
    }


def _drawn_again(study: str) -> runner.Study | None:
    """`study` as a `runner.Study`, whose pages `runner.render` draws from its results JSON alone;
    None for a study without that path."""
    found = getattr(STUDIES[study], "STUDY", None)
    return found if isinstance(found, runner.Study) else None


def _as_json(value: Any) -> Any:
    """`value` as the manifest holds it once written (tuples as lists, what JSON lacks as its str,
    as `step_key` hashes it), so that this call's manifest equals the next call's reading of it."""
    return json.loads(json.dumps(value, default=str))


def _decide_checkpoints(out: Path, rows: Sequence[str]) -> tuple[list[str], list[str]]:
    """(checkpoint folders, row labels) of the ablation's rows among `rows` that it kept models of:
    the labels its tables print (`display_name`), which the decision study's figure titles show."""
    doc = read_json(out / "ablation.json")
    have = {r["name"]: r.get("checkpoint") for r in (doc or {}).get("rows", [])}
    labels = {r["name"]: r.get("display_name") or ablation.display_name(r["name"]) for r in (doc or {}).get("rows", [])}
    chosen = [r for r in rows if have.get(r)]
    if not chosen:
        raise UserError(
            f"{out / 'ablation.json'}: field 'rows': the decision study needs the ablation's checkpoints of "
            f"{list(rows)}; run it first"
        )
    return [have[r] for r in chosen], [labels[r] for r in chosen]


def _latent_checkpoint(out: Path) -> str:
    doc = read_json(out / "properties.json")
    if not doc or not doc.get("rows"):
        raise UserError(
            f"{out / 'properties.json'}: field 'rows': the latents need the property study's checkpoint; run it first"
        )
    rows = {r["name"]: r["checkpoint"] for r in doc["rows"]}
    return rows.get(LATENT_ROW, doc["rows"][-1]["checkpoint"])
