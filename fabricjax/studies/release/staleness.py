"""Which results are not today's: the key over what decides a study's numbers, and the studies
and files whose key or fingerprints moved.

A study of `experiments.reproduce` is up to date when the manifest (`reproduce_plan.MANIFEST`)
records, for it, the key `step_key` gives today (the study and its seeds and rows, the preset,
the config overrides, the `results_files.fingerprints` of the code that computes it (its
module's import closure, `today`), of the simulator and its estimates, and of the data and, for
a study that reads another's results (`reproduce_plan.UPSTREAM`: the latents the property
study's checkpoint, the day shift the probe's accuracies, the decision study the ablation's
checkpoints), that study's key) and its outputs exist. Change any of those
and that study (and what depends on it) runs again.

Each manifest entry also records what its key was computed from (its step, preset, overrides
and fingerprints) and the commit it ran at, so `stale` recomputes every study's key under
today's fingerprints without running anything: a study whose key moved is stale, since that
commit, and its numbers are not today's code's, simulator's or data's. Every other results file
(a study run alone, a sweep, a benchmark) is stale when the fingerprints its results JSON
records differ from today's of the module its header names (`other_stale`). `check`
(`python -m experiments.reproduce --check`) lists both, with their files; REPORT.md and
README's results block say "stale since <commit>" beside each stale study.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from fabricjax import source
from fabricjax.errors import UserError
from fabricjax.reporting import results_files
from fabricjax.store import dataset_index, workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents
from fabricjax.studies.release.reproduce_plan import (
    HEADLINE,
    MANIFEST,
    REPORT,
    STUDIES,
    UPSTREAM,
    Step,
    chosen,
    command,
    outputs,
    read_json,
)

KINDS = results_files.FINGERPRINT_KINDS


def step_key(
    step: Step, preset: str, overrides: Mapping[str, Any], prints: Mapping[str, str | None], upstream: str = ""
) -> str:
    """What decides a study's results, as one key: the step, preset, overrides, the fingerprints
    of the code, the simulator and the data (`prints`: `today`; the data's is recorded data's
    contents, None on the preset's simulated data, which the simulator's decides) and the upstream
    study's key."""
    parts = {
        "step": dataclasses.asdict(step),
        "preset": preset,
        "overrides": dict(sorted(overrides.items())),
        "fingerprints": dict(prints),
        "upstream": upstream,
    }
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:16]


def today(study: str, data: str | None) -> dict[str, str | None]:
    """The fingerprints of what decides `study`'s numbers today (`results_files.fingerprints` of
    its module), on recorded data of contents `data` (None: the preset's simulated data)."""
    return results_files.fingerprints(STUDIES[study].__name__, data)


def upstream_key(study: str, keys: Mapping[str, str], manifest: Mapping[str, Any]) -> str:
    """The key of the study whose results `study` reads: this call's (`keys`), else the
    manifest's; "" for a study that reads none, or one never run."""
    up = UPSTREAM.get(study)
    return keys.get(up, manifest.get(up, {}).get("key", "")) if up else ""


def data_fingerprint(data_dir, workdir) -> str | None:
    """The "data" of `results_files.fingerprints` for a run on `data_dir` (None: the preset's simulated data)."""
    return dataset_index.load_index(data_dir, workdir).content_hash if data_dir else None


def stale(manifest: Mapping[str, Any], data: str | None) -> dict[str, str]:
    """{study: "stale since <commit>: <what> changed"} for each study of `manifest` whose key,
    recomputed from what its entry recorded (step, preset, overrides) under today's fingerprints
    of its code and of the data (`today`, `data`: recorded data's contents, None for simulated
    data) and the manifest's key of its upstream study (whose results it read: rerun since, they
    are not the ones it read), differs from the key it ran under; in `STUDIES` order. An entry
    that records no fingerprints is stale: nothing says what it was computed from."""
    out: dict[str, str] = {}
    for study in (s for s in STUDIES if s in manifest):
        entry = manifest[study]
        since = f"stale since {entry.get('commit', entry['finished'])}"
        if "fingerprints" not in entry:
            out[study] = f"{since}: it records no fingerprints of what it was computed from"
            continue
        prints = today(study, data)
        if (
            step_key(
                Step(**entry["step"]), entry["preset"], entry["overrides"], prints, upstream_key(study, {}, manifest)
            )
            != entry["key"]
        ):
            moved = _moved(entry["fingerprints"], prints)
            moved = moved or (
                [f"the {UPSTREAM[study]} study it reads"] if study in UPSTREAM else ["how its key is computed"]
            )
            out[study] = f"{since}: {' and '.join(moved)} changed"
    return out


def _moved(
    recorded: Mapping[str, str | None], prints: Mapping[str, str | None], kinds: Sequence[str] = tuple(KINDS)
) -> list[str]:
    """How `FINGERPRINT_KINDS` names each of `kinds` whose fingerprint in `recorded` differs from `prints`'."""
    return [KINDS[k].changed for k in kinds if recorded.get(k) != prints[k]]


def other_stale(out: Path, manifest: Mapping[str, Any]) -> dict[str, str]:
    """{file: "stale since <commit>: ..."} for every other results file under `out` (each `.md`
    that is not a study of the manifest nor a REPORT.md, which gathers studies checked by their
    own files: a study run alone, a sweep, a benchmark, a folder of recorded data) whose results
    JSON beside it records no fingerprints or no module that computed it, or a code or simulator
    fingerprint other than today's of that module; recorded data's fingerprint is not compared
    (its folder is not known here), nor the simulator's of a file of recorded data (it records none)."""
    own = {out / f"{s}.md" for s in manifest if s in STUDIES}
    found = {}
    for path in sorted(out.rglob("*.md")):
        if path in own or path.name == REPORT:
            continue
        doc = read_json(path.with_suffix(".json")) or {}
        code = doc.get("code", "")  # "commit <hash>", and " + uncommitted changes" where there were any
        since = f"stale since {code.split(' + ')[0]}" if code.startswith("commit ") else "stale"
        recorded, module = doc.get("fingerprints"), doc.get("module")
        if recorded is None or module is None:
            found[workspace.shown(path)] = f"{since}: it records no fingerprints of the code that computed it"
            continue
        if not source.is_module(module):
            found[workspace.shown(path)] = f"{since}: the module that computed it, {module}, is gone"
            continue
        compared = [k for k in KINDS if k != "data" and recorded.get(k) is not None]
        moved = _moved(recorded, results_files.fingerprints(module, None), compared)
        if moved:
            found[workspace.shown(path)] = f"{since}: {' and '.join(moved)} changed"
    return found


def check(where: Location, say: Callable[[str], None] = print, studies: Sequence[str] | None = None) -> dict[str, str]:
    """Say which studies of the manifest in `where`'s results folder are stale (`stale`, under the
    fingerprints of today's code, simulator and `where.data_dir`'s data), each with its files
    there, and which files gather them, and which other results files there are stale
    (`other_stale`); runs nothing, writes nothing. `studies` (None: all) narrows the check to
    those studies of the manifest, without the other files. Returns the stale ones as
    {study or file: note}."""
    asked = [s.study for s in chosen(studies)]
    out = where.results_dir()
    manifest = read_json(out / MANIFEST)
    if manifest is None:
        raise UserError(f"{workspace.shown(out / MANIFEST)}: no manifest of experiments.reproduce to check")
    data = data_fingerprint(where.data_dir, where.workdir)
    notes = {study: note for study, note in stale(manifest, data).items() if study in asked}
    checked = [s for s in asked if s in manifest]
    lines = [
        f"reproduce --check: {len(notes)} of the {len(checked)} studies of {workspace.shown(out / MANIFEST)} are stale "
        f"({documents.fingerprints_markdown(results_files.data_fingerprints(data))[2:]} today, and each study's "
        "code its own)"
    ]
    for study, note in notes.items():
        files = ", ".join(workspace.shown(p) for p in outputs(study, out) if p.exists())
        lines.append(f"  {study:<11} {note}: {files or 'no files'}")
    if notes:
        # the flags of the run that wrote it: a step named reproduce is the whole plan's command
        first = manifest[next(iter(notes))]
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
    others = other_stale(out, manifest) if studies is None else {}
    if others:
        lines.append(
            f"other results files in {workspace.shown(out)}, each rewritten by rerunning the command its header names:"
        )
        lines += [f"  {path}: {note}" for path, note in others.items()]
    say("\n".join(lines))
    return {**notes, **others}
