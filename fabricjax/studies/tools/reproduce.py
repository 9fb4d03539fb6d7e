"""Every table and figure of the paper on one preset, in order, and one report: REPORT.md.

    python -m experiments.reproduce                      # default preset, into workspace/results/
    python -m experiments.reproduce --results=results    # regenerates the report published in the repository

The plan (`PLAN`, data): the modality ablation (5 seeds), the linear probe of every ablation
row's inputs (no seeds: deterministic, and cheap), the day shift of every input (what the fabric,
the day and the trial explain, beside the probe's training-day and new-day accuracy; no seeds),
the PSD bandwidth (5), cafe noise (10, as the paper), property perception (5, saving its
checkpoints) and the latent t-SNE from the property study's checkpoint of its Minsound + proprioception + Minsight row,
then the
decision study (calibration, when to stop rubbing, unknown fabrics) on the ablation's checkpoints
of the row the paper calls best and of Minsound alone (`DECIDE_ROWS`; no training), and last what Minsight's
camera sees of a stroke (`camera_frames`: the simulator's frames, no data, no training). The dataset is simulated once
(or read from
`data_dir`), features and compiled programs are cached, checkpoints resume, so every study after
the first pays only for its training.

A study is skipped when it is up to date: the manifest `reproduce.json` in the results folder
records, per study, a key over what decides its numbers (`step_key`: the study and its seeds and
rows, the preset, the config overrides, the `documents.fingerprints` of the code, the simulator's
estimates and the data and, for a study that reads another's results (`UPSTREAM`: the latents the
property study's checkpoint, the day shift the probe's accuracies, the decision study the
ablation's checkpoints), that study's key) and its outputs exist. Change any of those and that
study (and what depends on it) runs again. The manifest is rewritten after every study, so an
interrupted run picks up where it stopped.

Staleness: each manifest entry also records what its key was computed from (its step, preset,
overrides and fingerprints) and the commit it ran at, so `stale` recomputes every study's key
under today's fingerprints without running anything: a study whose key moved is stale, since
that commit, and its numbers are not today's code's, estimates' or data's. `check` (`python -m
experiments.reproduce --check`) lists the stale studies of a results folder with their files;
REPORT.md and README's results block, when `run` writes them, say "stale since <commit>" beside
each study of the manifest that this call did not bring up to date (one outside `--studies`).

The report embeds each study's own Markdown (its table beside the paper's, its findings
checklist, its Wilcoxon tests), links its figures, sets the probe beside the ablation row by row
(from both studies' JSON, `probe.beside_ablation`), and adds a summary of every checklist, the
machine, the library versions, the code's fingerprint, each study's wall time and the exact
command that reruns that study alone. On recorded data (`data_dir`) the report, like its studies,
names the data and compares rows with each other: no paper in its titles or summary.

On recorded data the plan follows what the data has (`fit_plan`): a study's rows that need a
stream the data lacks are left out, a study none of whose rows it can feed is skipped, and the
studies of the paper's protocol (`PROTOCOL`: cafe noise needs cafe-split trials, the property study
held-out fabrics, the latents the property study, the decision study the ablation) are skipped when the data has no such
trials, and the studies of the simulator itself (`SIMULATOR_ONLY`: the camera frames) always,
each with one line saying why.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
import shlex
import time
from importlib import metadata
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import fabricjax
from fabricjax import presets
from fabricjax.config import format_override
from fabricjax.errors import UserError
from fabricjax.reporting import stats
from fabricjax.store import archive, dataset_index, provenance, splits, workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.common import documents, findings
from fabricjax.studies.common.plan import rates as training_rates
from fabricjax.studies.common.rows import split_by_inputs
from fabricjax.studies.extra import camera_frames, day_shift, decide, probe, sensitivity
from fabricjax.studies.paper import ablation, bandwidth, latents, noise, properties

STUDIES = {
    "ablation": ablation,
    "probe": probe,
    "day_shift": day_shift,
    "bandwidth": bandwidth,
    "noise": noise,
    "properties": properties,
    "latents": latents,
    "decide": decide,
    "camera_frames": camera_frames,
}
UPSTREAM = {
    "latents": "properties",
    "day_shift": "probe",
    "decide": "ablation",
}  # a study -> the study whose results it reads
UNSEEDED = ("probe", "day_shift", "camera_frames")  # deterministic studies of no paper table: no seeds, no claims
SIMULATOR_ONLY = ("camera_frames",)  # studies of the simulator itself: skipped on recorded data
LATENT_ROW = properties.ROWS[
    -1
].name  # the paper's figure: its "Minsound + Minsight" model, which also reads proprioception
# the decision study's models: the ablation row the paper calls best (its highest mean) and Minsound alone
DECIDE_ROWS = (max(ablation.PAPER_ROWS, key=lambda r: r.paper["mean"]).name, "internal")
CHECKPOINT_STUDIES = (
    "latents",
    "decide",
)  # studies of another study's checkpoints: run by --checkpoint, no seeds or rows flags
MANIFEST = "reproduce.json"
REPORT = "REPORT.md"
HEADLINE = "headline.json"  # README's results block, as data (tracked, unlike the studies' JSON)
# README's results block lies between these lines; `run` rewrites it in the README.md beside the results folder
README_BEGIN = (
    "<!-- results: written by `python -m experiments.reproduce` from results/headline.json; edits are overwritten -->"
)
README_END = "<!-- end of results -->"


@dataclasses.dataclass(frozen=True)
class Step:
    """One study of the plan: its name (a key of `STUDIES`), seed count and rows (None: all)."""

    study: str
    seeds: int | None = (
        None  # None for `UNSEEDED` (deterministic) and the studies of another's checkpoints (latents, decide)
    )
    rows: tuple[str, ...] | None = None


PLAN = (
    Step("ablation", 5),
    Step("probe"),
    Step("day_shift"),
    Step("bandwidth", 5),
    Step("noise", 10),
    Step("properties", 5),
    Step("latents"),
    Step("decide", rows=DECIDE_ROWS),
    Step("camera_frames"),
)
# The studies that need trials of the paper's protocol: the split they read, and what it is
PROTOCOL = {
    "noise": ("cafe", "trials of the cafe condition (split cafe)"),
    "properties": ("holdout", "held-out fabrics (split holdout)"),
}

# The manifest the repository publishes (results/reproduce.json): its recorded wall times are the
# estimate for a run of the same preset before this folder has its own.
PUBLISHED_MANIFEST = provenance.repository_root() / "results" / MANIFEST


def title(study: str, recorded: bool = False) -> str:
    """How the report names `study`: its title, and on simulated data what of the paper it reproduces."""
    module = STUDIES[study]
    return module.TITLE if recorded else f"{module.TITLE} ({module.PAPER})"


def step_key(
    step: Step, preset: str, overrides: Mapping[str, Any], prints: Mapping[str, str | None], upstream: str = ""
) -> str:
    """What decides a study's results, as one key: the step, preset, overrides, the fingerprints
    of the code, the simulator's estimates and the data (`prints`: `documents.fingerprints`; the
    data's is recorded data's contents, None on the preset's simulated data, which the other two
    decide) and the upstream study's key."""
    parts = {
        "step": dataclasses.asdict(step),
        "preset": preset,
        "overrides": dict(sorted(overrides.items())),
        "fingerprints": dict(prints),
        "upstream": upstream,
    }
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _as_json(value: Any) -> Any:
    """`value` as the manifest holds it once written (tuples as lists, what JSON lacks as its str,
    as `step_key` hashes it), so that this call's manifest equals the next call's reading of it."""
    return json.loads(json.dumps(value, default=str))


def _upstream(study: str, keys: Mapping[str, str], manifest: Mapping[str, Any]) -> str:
    """The key of the study whose results `study` reads: this call's (`keys`), else the
    manifest's; "" for a study that reads none, or one never run."""
    up = UPSTREAM.get(study)
    return keys.get(up, manifest.get(up, {}).get("key", "")) if up else ""


def _data_fingerprint(data_dir, workdir) -> str | None:
    """The "data" of `documents.fingerprints` for a run on `data_dir` (None: the preset's simulated data)."""
    return dataset_index.load_index(data_dir, workdir).content_hash if data_dir else None


FINGERPRINT_WORDS = {
    "code": "the code",
    "estimates": "the simulator's estimates",
    "data": "the data",
}  # `documents.fingerprints`' keys


def stale(manifest: Mapping[str, Any], prints: Mapping[str, str | None]) -> dict[str, str]:
    """{study: "stale since <commit>: <what> changed"} for each study of `manifest` whose key,
    recomputed from what its entry recorded (step, preset, overrides) under today's fingerprints
    (`prints`) and the manifest's key of its upstream study (whose results it read: rerun since,
    they are not the ones it read), differs from the key it ran under; in `STUDIES` order. An entry
    that records no fingerprints is stale: nothing says what it was computed from."""
    out: dict[str, str] = {}
    for study in (s for s in STUDIES if s in manifest):
        entry = manifest[study]
        since = f"stale since {entry.get('commit', entry['finished'])}"
        if "fingerprints" not in entry:
            out[study] = f"{since}: it records no fingerprints of what it was computed from"
            continue
        if (
            step_key(Step(**entry["step"]), entry["preset"], entry["overrides"], prints, _upstream(study, {}, manifest))
            != entry["key"]
        ):
            moved = [words for k, words in FINGERPRINT_WORDS.items() if entry["fingerprints"].get(k) != prints[k]]
            moved = moved or (
                [f"the {UPSTREAM[study]} study it reads"] if study in UPSTREAM else ["how its key is computed"]
            )
            out[study] = f"{since}: {' and '.join(moved)} changed"
    return out


def other_stale(out: Path, manifest: Mapping[str, Any], prints: Mapping[str, str | None]) -> dict[str, str]:
    """{file: "stale since <commit>: ..."} for every other results file under `out` (each `.md` that
    is not a study of the manifest or REPORT.md: a study run alone, a sweep, a benchmark, a folder
    of recorded data) whose header records no fingerprints, or another code or estimates
    fingerprint than today's (`prints`); recorded data's fingerprint is not compared (its folder is
    not known here)."""
    own = {out / REPORT, *(out / f"{s}.md" for s in manifest if s in STUDIES)}
    found = {}
    for path in sorted(out.rglob("*.md")):
        if path in own:
            continue
        head = path.read_text(errors="replace").split("\n## ", 1)[0]
        commit = re.search(r"^- code: commit (\w+)", head, re.M)
        since = f"stale since commit {commit.group(1)}" if commit else "stale"
        recorded = re.search(r"^- fingerprints: (.*)$", head, re.M)
        if recorded is None:
            found[workspace.shown(path)] = f"{since}: it records no fingerprints of what it was computed from"
            continue
        saved = dict(re.findall(r"(code|simulator estimates) `(\w+)`", recorded.group(1)))
        moved = [
            FINGERPRINT_WORDS[k]
            for k, named in (("code", "code"), ("estimates", "simulator estimates"))
            if named in saved and saved[named] != prints.get(k)
        ]
        if moved:
            found[workspace.shown(path)] = f"{since}: {' and '.join(moved)} changed"
    return found


def refuse_unknown(studies: Sequence[str]) -> None:
    """A one-line error naming the studies of `studies` that are not of `STUDIES`, and those that are
    (before anything runs or is read, so a misspelt name is never a silent no-op)."""
    unknown = [s for s in studies if s not in STUDIES]
    if unknown:
        raise UserError(f"--studies: unknown studies {unknown}; choose from {', '.join(STUDIES)}")


def chosen(studies: Sequence[str] | None) -> tuple[Step, ...]:
    """The steps of `PLAN` of the studies named in `studies` (None: all), in the plan's order."""
    refuse_unknown(studies or ())
    return tuple(s for s in PLAN if studies is None or s.study in studies)


def check(where: Location, say: Callable[[str], None] = print, studies: Sequence[str] | None = None) -> dict[str, str]:
    """Say which studies of the manifest in `where`'s results folder are stale (`stale`, under the
    fingerprints of today's code, estimates and `where.data_dir`'s data), each with its files
    there, and which files gather them, and which other results files there are stale
    (`other_stale`); runs nothing, writes nothing. `studies` (None: all) narrows the check to
    those studies of the manifest, without the other files. Returns the stale ones as
    {study or file: note}."""
    asked = [s.study for s in chosen(studies)]
    out = where.results_dir()
    manifest = _read_json(out / MANIFEST)
    if manifest is None:
        raise UserError(f"{workspace.shown(out / MANIFEST)}: no manifest of experiments.reproduce to check")
    prints = documents.fingerprints(_data_fingerprint(where.data_dir, where.workdir))
    notes = {study: note for study, note in stale(manifest, prints).items() if study in asked}
    checked = [s for s in asked if s in manifest]
    lines = [
        f"reproduce --check: {len(notes)} of the {len(checked)} studies of {workspace.shown(out / MANIFEST)} are stale "
        f"({documents.fingerprints_markdown(prints)[2:]} today)"
    ]
    for study, note in notes.items():
        files = ", ".join(workspace.shown(p) for p in _outputs(study, out) if p.exists())
        lines.append(f"  {study:<11} {note}: {files or 'no files'}")
    if notes:
        first = manifest[
            next(iter(notes))
        ]  # the flags of the run that wrote it: a step named reproduce is the whole plan's command
        rerun = command(
            Step("reproduce"),
            first["preset"],
            first.get("overrides", {}),
            workspace.shown(out),
            data_dir=where.data_dir,
            workdir=where.workdir,
        )
        lines.append(
            f"  {workspace.shown(out / REPORT)} and {workspace.shown(out / HEADLINE)} (README's results "
            f"block) gather them; "
            f"`{rerun}` reruns what is stale and rewrites both"
        )
    others = other_stale(out, manifest, prints) if studies is None else {}
    if others:
        lines.append(
            f"other results files in {workspace.shown(out)}, each rewritten by rerunning the command its header names:"
        )
        lines += [f"  {path}: {note}" for path, note in others.items()]
    say("\n".join(lines))
    return {**notes, **others}


def command(
    step: Step,
    preset: str,
    overrides: Mapping[str, Any],
    results: Path,
    checkpoint: str | None = None,
    data_dir=None,
    workdir=None,
) -> str:
    """The command that reruns `step` alone, as a user would type it (`checkpoint`: the
    checkpoint folders, comma-separated, of a study of another's checkpoints)."""
    args = [f"python -m experiments.{step.study}"]
    if step.study in CHECKPOINT_STUDIES:
        args.append(f"--checkpoint={checkpoint}")
    else:
        args += (
            [f"--seeds={step.seeds}"] * bool(step.seeds)
            + [f"--preset={preset}"]
            + ([f"--rows={','.join(step.rows)}"] if step.rows else [])
        )
        args += [shlex.quote(f"--set={format_override(k, v)}") for k, v in sorted(overrides.items())]
    args += (
        [f"--data_dir={data_dir}"] * bool(data_dir)
        + [f"--workdir={workdir}"] * bool(workdir)
        + [f"--results={results}"]
    )
    return " ".join(args)


def estimate_s(step: Step, preset: str, *manifests: Mapping[str, Any]) -> float | None:
    """Expected wall time of `step`: the first of `manifests` that recorded this study on `preset`,
    scaled by seeds and rows (None where none did)."""
    entry = next((m[step.study] for m in manifests if m.get(step.study, {}).get("preset") == preset), None)
    if entry is None:
        return None
    scale = (
        (step.seeds or 1)
        / (entry["seeds"] or 1)
        * (len(step.rows) if step.rows else _n_rows(step.study))
        / entry["rows"]
    )
    return entry["wall_s"] * scale


def _n_rows(study: str) -> int:
    """Rows a study trains without --rows (1 for the latents, which have none)."""
    module = STUDIES[study]
    default = getattr(getattr(module, "STUDY", None), "default_rows", None)
    return len(default if default is not None else getattr(module, "ROWS", (None,)))


def _minutes(seconds: float | None) -> str:
    return "unknown" if seconds is None else f"{seconds / 60:.1f} min"


def _read_json(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _outputs(study: str, out: Path) -> list[Path]:
    """The study's Markdown and JSON, and every figure its JSON names (a row subset may draw none)."""
    doc = _read_json(out / f"{study}.json") or {}
    return [out / f"{study}.md", out / f"{study}.json", *[out / f for f in doc.get("figures", [])]]


def _decide_checkpoints(out: Path, rows: Sequence[str]) -> tuple[list[str], list[str]]:
    """(checkpoint folders, row labels) of the ablation's rows among `rows` that it kept models of:
    the labels its tables print (`display_name`), which the decision study's figure titles show."""
    doc = _read_json(out / "ablation.json")
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
    doc = _read_json(out / "properties.json")
    if not doc or not doc.get("rows"):
        raise UserError(
            f"{out / 'properties.json'}: field 'rows': the latents need the property study's checkpoint; run it first"
        )
    rows = {r["name"]: r["checkpoint"] for r in doc["rows"]}
    return rows.get(LATENT_ROW, doc["rows"][-1]["checkpoint"])


def fit_plan(plan: Sequence[Step], preset: str, data_dir, workdir, say: Callable[[str], None]) -> list[Step]:
    """`plan` as recorded data in `data_dir` can run it (module docstring), saying what is left out."""
    index = dataset_index.load_index(data_dir, workdir)
    lay = archive.layout(index.entries[0].meta)
    have = set(lay.modalities())
    roles = set(splits.assign_roles([e.meta for e in index.entries], presets.get(preset).dataset.splits))
    out: list[Step] = []
    for step in plan:
        if step.study in SIMULATOR_ONLY:
            say(f"  {step.study:<11} skip  (it draws the simulator's frames, not the data's)")
            continue
        if step.study == "latents" and not any(s.study == "properties" for s in out):
            say("  latents     skip  (it reads the property study's checkpoint, which this data does not train)")
            continue
        if step.study == "decide":
            ablated = next((s for s in out if s.study == "ablation"), None)
            fit = tuple(
                r for r in step.rows or () if ablated is not None and (ablated.rows is None or r in ablated.rows)
            )
            if not fit:
                say(
                    "  decide      skip  (it reads the ablation's checkpoints of its rows, which this data "
                    "does not train)"
                )
                continue
            out.append(dataclasses.replace(step, rows=fit))
            continue
        if step.study in PROTOCOL and PROTOCOL[step.study][0] not in roles:
            say(
                f"  {step.study:<11} skip  (the paper's protocol: it needs {PROTOCOL[step.study][1]}, and "
                f"the data has none)"
            )
            continue
        rows = getattr(STUDIES[step.study], "ROWS", None)
        if rows is None:
            out.append(step)
            continue
        named = [r for r in rows if step.rows is None or r.name in step.rows]
        fed, lacking = split_by_inputs(named, have)
        fit = tuple(r.name for r in fed)
        if not fit:
            say(
                f"  {step.study:<11} skip  (its rows need {', '.join(lacking)}, which the data lacks: it has "
                f"{lay.describe()})"
            )
            continue
        if len(fit) < len(named):
            say(
                f"  {step.study:<11} {len(named) - len(fit)} of its {len(named)} rows left out (they need "
                f"{', '.join(lacking)}, which the data lacks)"
            )
        out.append(step if len(fit) == len(named) else dataclasses.replace(step, rows=fit))
    return out


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
    manifest = _read_json(manifest_path) or {}
    prints = documents.fingerprints(_data_fingerprint(data_dir, workdir))

    keys: dict[str, str] = {}
    for step in plan:  # a study that reads another's results has that study's key in its own
        keys[step.study] = step_key(step, preset, overrides, prints, _upstream(step.study, keys, manifest))
    todo = [
        s
        for s in plan
        if force
        or manifest.get(s.study, {}).get("key") != keys[s.study]
        or not all(p.exists() for p in _outputs(s.study, out))
    ]

    lines = [f"reproduce: preset {preset}, results in {out}"]
    published = _read_json(PUBLISHED_MANIFEST) or {}
    for step in plan:
        if step in todo:
            lines.append(f"  {step.study:<11} run   ~{_minutes(estimate_s(step, preset, manifest, published))}")
        else:
            lines.append(
                f"  {step.study:<11} skip  (up to date: ran {manifest[step.study]['finished']}, "
                f"{_minutes(manifest[step.study]['wall_s'])})"
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
            f"  estimated time: {_minutes(known)}{data_note} (scaled from an earlier run's wall times; other "
            f"machines differ)"
        )
    say("\n".join(lines))

    t_all = time.perf_counter()
    for step in todo:
        say(f"reproduce: {step.study} ...")
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
        manifest[step.study] = {
            "key": keys[step.study],
            "wall_s": wall,
            "command": cmd,
            "finished": documents.utc_now(),
            "commit": documents.git_commit(),
            # what the key was computed from: `stale` recomputes it under later fingerprints
            "step": _as_json(dataclasses.asdict(step)),
            "overrides": _as_json(overrides),
            "fingerprints": prints,
            # what an estimate of a later run scales from: the study's, and each training row's (`plan.rates`)
            "preset": preset,
            "seeds": step.seeds,
            "rows": len(step.rows) if step.rows else _n_rows(step.study),
            **(
                {"rates": training_rates(doc), "machine": documents.machine_line(doc["machine"])}
                if doc and step.seeds
                else {}
            ),
        }
        documents.write_json(manifest_path, manifest)
        say(f"reproduce: {step.study} done in {_minutes(wall)}")
    write_report(out / REPORT, manifest, preset, prints, where.command, time.perf_counter() - t_all, len(todo))
    say(f"reproduce: wrote {out / REPORT}")
    head = headline(out, manifest, preset, where.command, prints)
    if head is not None:
        documents.write_json(out / HEADLINE, head)
        readme = out.parent / "README.md"
        if write_readme_block(readme, readme_block(head, out.name)):
            say(f"reproduce: wrote the results block of {readme}")
    return {s.study: manifest[s.study] for s in plan}


def versions() -> dict[str, str]:
    out = {}
    for name in (
        "jax",
        "jaxlib",
        "flax",
        "optax",
        "orbax-checkpoint",
        "numpy",
        "scipy",
        "opencv-contrib-python-headless",
        "scikit-learn",
    ):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _demote(markdown: str) -> str:
    """A study's Markdown inside the report: its title dropped, its sections one level down."""
    lines = markdown.splitlines()
    if lines and lines[0].startswith("# "):
        lines = lines[1:]
    return "\n".join("#" + line if line.startswith("#") else line for line in lines).strip() + "\n"


def write_report(
    path: Path,
    manifest: Mapping[str, Any],
    preset: str,
    prints: Mapping[str, str | None],
    command_line: str,
    run_s: float,
    n_run: int,
) -> Path:
    """REPORT.md over every study the manifest holds (this call's and earlier calls'), in `STUDIES`
    order, each stale one (`stale` under today's fingerprints, `prints`) saying so."""
    out = path.parent
    studies = [s for s in STUDIES if s in manifest]
    notes = stale(manifest, prints)
    docs = {s: _read_json(out / f"{s}.json") for s in studies}
    first = next((d for d in docs.values() if d), None)
    m = first["machine"] if first else documents.machine()
    # recorded data (`--data_dir`): its studies compare rows with each other, so no paper in titles or summary
    recorded = first is not None and documents.recorded(first)
    total = sum(e["wall_s"] for e in manifest.values())
    summary = []
    for study in studies:
        doc = docs[study] or {}
        if study in UNSEEDED:  # not a table of the paper: no claims to check, no seeds
            seeds, claims = "– (deterministic)", "– (not in the paper)"
        elif study == "decide":  # not in the paper: the ablation's models, each its best seed
            seeds, claims = "1 per model (best of the ablation's)", "– (not in the paper)"
        else:
            held, evaluated = findings.count([findings.Finding.from_json(f) for f in doc.get("findings", [])])
            seeds = len(doc["seeds"]) if study != "latents" and doc.get("seeds") else "1 (best of the property study's)"
            claims = f"{held} of {evaluated}" if not presets.install_check(preset) else "not counted (install check)"
        finished = manifest[study]["finished"] + (f"; **{notes[study]}**" if study in notes else "")
        summary.append(
            [
                f"[{title(study, recorded)}](#{_anchor(title(study, recorded))})",
                seeds,
                *([] if recorded else [claims]),
                _minutes(manifest[study]["wall_s"]),
                finished,
            ]
        )
    if recorded:
        heading = documents.title(first, f"Report: every study on the {preset} preset")
        data_note, numbers = "feature extraction, done once, is", documents.RECORDED_NOTE
    else:
        heading = f"# Reproduction report: every table and figure of the paper on the {preset} preset"
        if presets.install_check(preset):
            heading += f"\n\n> {presets.INSTALL_CHECK_NOTE}"
        data_note = "data simulation and feature extraction, done once, are"
        numbers = (
            "The simulator is the same for every study and was never tuned to a table: differences from the paper "
            "are findings."
        )
    lines = [
        heading,
        "",
        f"- command: `{command_line}` ({n_run} of {len(studies)} studies run by this call, in {_minutes(run_s)}; "
        "the others were up to date and kept)",
        f"- machine: {m['cpu']}, {m['cores']} cores, {m['platform']}, Python {m['python']}, JAX on "
        f"{m['jax_backend']} ({len(m['devices'])} devices)",
        f"- versions: {', '.join(f'{k} {v}' for k, v in versions().items())}",
        f"- code: fabricjax {fabricjax.__version__}, {documents.git_commit()}",
        documents.fingerprints_markdown(prints)
        + " (today's; `python -m experiments.reproduce --check` lists the studies they do not match)",
        f"- wall time of the studies: {_minutes(total)} in all (each below; {data_note} in the first study's)",
        "",
        f"Every number below comes from the study's results file in this folder, written by the run named "
        f"beside it. {numbers}",
        "",
        "## Summary",
        "",
        documents.markdown_table(
            ["Study", "Seeds", *([] if recorded else ["Paper's claims reproduced"]), "Wall time", "Finished"], summary
        ),
        "",
    ]
    if not recorded:
        lines += ["## What the simulator's estimates decide", "", sensitivity.report_block(out), ""]
    for study in studies:
        e = manifest[study]
        md = out / f"{study}.md"
        lines += [
            f"## {title(study, recorded)}",
            "",
            f"Wall time {_minutes(e['wall_s'])}, finished {e['finished']}. Rerun alone: `{e['command']}`",
            "",
            *(
                [
                    f"> **{notes[study][0].upper() + notes[study][1:]}**: these are not today's numbers; "
                    f"`python -m experiments.reproduce` reruns it.",
                    "",
                ]
                if study in notes
                else []
            ),
            _demote(md.read_text()) if md.exists() else f"({md.name} is missing)\n",
        ]
        figures = (docs[study] or {}).get("figures", [])
        lines += [
            f"![{f}]({f})\n"
            for f in figures
            if (out / f).exists() and f"({f})" not in (md.read_text() if md.exists() else "")
        ]
        if study == "probe" and docs["probe"] and docs.get("ablation"):
            lines += [
                "### The probe beside the model, row by row",
                "",
                probe.beside_ablation(docs["probe"], docs["ablation"]),
            ]
    return documents.write_text(path, "\n".join(lines))


def _anchor(title: str) -> str:
    """GitHub's anchor for a heading: lower case, spaces to hyphens, punctuation dropped."""
    return "".join(c for c in title.lower().replace(" ", "-") if c.isalnum() or c in "-_")


def headline(
    out: Path, manifest: Mapping[str, Any], preset: str, command_line: str | None, prints: Mapping[str, str | None]
) -> dict[str, Any] | None:
    """README's results block as data, from the same results files as REPORT.md: the ablation's
    rows (the paper's rows on simulated data, every row on recorded data) beside the paper and
    the linear probe of the same inputs, each seeded study's checklist count, the stale studies
    (`stale` under today's fingerprints, `prints`) by title, and the run's command, date, machine
    and wall time. None when the folder holds no ablation."""
    docs = {s: _read_json(out / f"{s}.json") for s in STUDIES if s in manifest}
    abl = docs.get("ablation")
    if not abl:
        return None
    recorded = documents.recorded(abl)
    probe_rows = (docs.get("probe") or {}).get("rows", [])
    rows = []
    for r in abl["rows"]:
        if not recorded and r.get("fusion_norm", "sequence_minmax") != "sequence_minmax":
            continue  # our fusion variants: in REPORT.md, not the headline
        p = probe.row_for(r["modalities"], probe_rows, r.get("config", {}).get("image_reference"))
        probe_test = None if p is None or p["accuracy"].get("test") is None else 100 * p["accuracy"]["test"]
        rows.append(
            {
                "inputs": r["display_name"],
                "ours": stats.format_mean_sd(r["accuracy"]["test"]["fabric"])
                + findings.collapse_note(r["predictions"]["test"]["fabric"]),
                "paper": None if recorded else f"{r['paper_mean']:.2f} ± {r['paper_sd']:.2f}",
                "probe": None
                if probe_test is None
                else f"{probe_test:.2f}" + findings.collapse_note(p.get("predictions", {}).get("test", [])),
            }
        )
    claims = {}
    for study, doc in docs.items():
        if doc and study not in UNSEEDED and study != "decide" and doc.get("findings") and not recorded:
            held, evaluated = findings.count([findings.Finding.from_json(f) for f in doc["findings"]])
            claims[title(study)] = (
                "not counted (install check)" if presets.install_check(preset) else f"{held} of {evaluated}"
            )
    m = abl["machine"]
    return {
        "command": command_line,
        "preset": preset,
        "recorded": recorded,
        "date": documents.utc_now(),
        "code": documents.git_commit(),
        "machine": documents.machine_line(m),
        "wall_s": sum(e["wall_s"] for s, e in manifest.items() if s in STUDIES),
        "seeds": len(abl["seeds"]),
        "rows": rows,
        "claims": claims,
        "stale": {title(s, recorded): note for s, note in stale(manifest, prints).items()},
        "other_stale": len(other_stale(out, manifest, prints)),
    }


def readme_block(head: Mapping[str, Any], results: str = "results") -> str:
    """README's results block (between `README_BEGIN` and `README_END`, both included) rendered
    from `headline`'s data; `results`: the results folder, relative to the README."""
    command_line = f"`{head['command']}`" if head["command"] else "a call from Python"
    lines = [
        README_BEGIN,
        f"From {command_line} on the {head['preset']} preset, {head['date']}, on {head['machine']} ({head['code']}); "
        f"its studies took {_minutes(head['wall_s'])}. Every table, figure, test and time: "
        f"[{results}/{REPORT}]({results}/{REPORT}).",
        "",
    ]
    paper = not head["recorded"]
    header = [
        "Inputs",
        f"Ours, test [%] ({head['seeds']} seeds)",
        *(["Paper [%]"] if paper else []),
        "Linear probe, test [%]",
    ]
    body = [[r["inputs"], r["ours"], *([r["paper"]] if paper else []), r["probe"] or "–"] for r in head["rows"]]
    lines.append(documents.markdown_table(header, body))
    if head["claims"]:
        lines.append("The paper's claims reproduced: " + "; ".join(f"{k} {v}" for k, v in head["claims"].items()) + ".")
        lines.append("")
    if head.get("stale"):  # a headline written before it recorded stale studies has none
        lines.append(
            "**Stale**, not today's numbers: "
            + "; ".join(f"{k} ({v})" for k, v in head["stale"].items())
            + " (`python -m experiments.reproduce --check` lists their files)."
        )
        lines.append("")
    if head.get("other_stale"):
        lines.append(
            f"{head['other_stale']} other results files in `{results}/` (studies run alone, sweeps, "
            f"benchmarks) predate today's "
            "code or estimates: `python -m experiments.reproduce --check --results=results` names each."
        )
        lines.append("")
    lines.append(README_END)
    return "\n".join(lines)


def write_readme_block(readme: Path, block: str) -> bool:
    """Replace the results block of `readme` with `block`; False (nothing written) when the file
    does not exist or has no block: only a README that asks for one is ever written."""
    return documents.replace_block(readme, README_BEGIN, README_END, block)
