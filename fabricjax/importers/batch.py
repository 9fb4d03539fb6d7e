"""Import every trial a manifest lists (`fabricjax.importers.manifest_file`) into one folder of trial
archives, in one process pool with one progress bar, as one transaction.

Every problem that can be found before importing (a row's fields, a recording listed twice, two
rows naming one archive, a missing trial folder or file, a label outside the label map, what DIR
already holds) is listed, one line each, and nothing is written. The trials are then imported into
a hidden staging folder in DIR; a trial that fails is reported as the same one-line error with one
worker or many, after every trial was tried, and then nothing reaches DIR. Only a complete import
is moved into DIR under `archive.trial_filename`.

A rerun resumes: an archive already in DIR is kept when it reads back whole (every member's CRC-32
checked) and was imported from the same recording with the same label, label map, split, day,
trial, condition and properties; a damaged one is imported again. Anything else is refused unless
`overwrite`, which replaces the dataset in DIR: its archives become exactly the manifest's. So an
archive of another recording under a row's name, a changed label map (a class added or renamed),
and archives no row produces (another dataset, or rows since deleted or relabelled) are errors
without it. Staging folders and `.partial` files a killed run left in DIR are removed at the next
run (one import per DIR at a time); a killed import's worker processes end with it.

A complete import ends by writing DIR's index (`dataset_index.build_index`: each archive's meta,
size and sha256, hashed as the import left it) where `workspace.index_file` keeps it for the
workspace `workdir`, under `<workspace>/indexes/` and never inside DIR, so that
`python -m experiments.verify DIR` re-hashes every archive against what was imported, and the first
study reading DIR finds it indexed.

The label map is written into every archive of a rig's recordings (meta.label_map), so the classes
and the classifier's size come from the data, and nothing from our fabric catalog is stamped on
them. A rig's trials without a split or a day would never be used, so that is an error.

A camera's session reference is never made up: the rig file's or mapping's [camera] table names
it, and for the hand's folders `reference` does (a file relative to each trial folder, or
`pre_contact` with `reference_frames` for each trial's first frames: `fabricjax.importers.hand_folder`);
a camera without one is an error before anything is read or written.

Per trial the existing importers do the work (`rig_folder.import_rig_folder`,
`hand_folder.import_folder`, `ros_bag.import_bag`); manifest columns no importer of the run reads
(the property columns of the hand's folders and bags, whose levels come from the fabric catalog)
and joint columns that are not used are reported, never dropped silently.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any, Callable

from tqdm import tqdm

from fabricjax import parallel
from fabricjax.errors import UserError
from fabricjax.importers import hand_folder, manifest_file, mapping_file, rig_folder, ros_bag
from fabricjax.importers.alignment import ReferenceSource, parse_reference, session_of
from fabricjax.importers.manifest_file import COLUMNS, HAND_COLUMNS, ManifestError, Row
from fabricjax.store import archive, dataset_index, lock, provenance, workspace
from fabricjax.store.atomic import atomic_open

STAGING = (".import-", ".partial")  # prefix and suffix of the staging folder in DIR
IMPORT_LOCK = ".import.lock"  # in DIR: a second import into it at the same time is refused (`fabricjax.store.lock`)


class ImportProblems(UserError):
    """Every problem of an import, one line each (a single problem is its one line)."""

    def __init__(self, problems: list[str]):
        self.problems = problems
        super().__init__("\n".join(problems))


@dataclasses.dataclass(frozen=True)
class Job:
    kind: str  # "rig" | "folder" | "bag"
    row: Row
    target: str  # archive path
    meta_fields: dict[str, Any]  # rig: make_meta's trial fields; folder / bag: the importers' trial dict
    split: str | None
    rig: rig_folder.Rig | None
    mapping: dict[str, Any] | None
    manifest: str  # the manifest that lists the trial, for errors
    reference: ReferenceSource | None = None  # the camera's session reference; None: no camera


def _import_one(job: Job) -> None:
    """One trial, by the importer for its kind, written atomically to its staging path (a worker's
    job); a trial that cannot be imported leaves its one-line error beside it (`<target>.error`),
    so every trial is tried and every error reported, with one worker or many. An archive the
    writer refuses is named by the manifest's line and the recording, never by the staging path,
    which the user neither chose nor can find once the import has stopped."""
    try:
        if job.kind == "rig":
            result = rig_folder.import_rig_folder(job.row.path, job.rig, job.meta_fields, session=job.row.session)
        else:
            trial = {**job.meta_fields, **({"session": job.row.session} if job.row.session else {})}
            result = (
                hand_folder.import_folder(job.row.path, trial, reference=job.reference)
                if job.kind == "folder"
                else ros_bag.import_bag(job.row.path, job.mapping, trial)
            )
            if job.split is not None:
                result.meta["split"] = job.split
        try:
            archive.write_archive(job.target, result)
        except archive.ArchiveError as e:
            raise ManifestError(
                job.manifest, job.row.line, e.field, f"{e.problem}, in the archive made from {job.row.path}"
            ) from None
    except UserError as e:
        with atomic_open(job.target + ".error", "w") as f:
            f.write(str(e))


def plan(
    rows: list[Row],
    out: Path,
    *,
    rig: rig_folder.Rig | None,
    mapping: dict[str, Any] | None,
    label_map: dict[str, int] | None,
    splits: list[str | None],
    manifest,
    problems: list[str],
    reference: ReferenceSource | None = None,
) -> list[Job]:
    """One job per row, with its archive's name; two rows giving one name or listing one recording,
    a label outside the label map and a missing recording or file are problems. `reference`: the
    hand's folders' session reference (`--reference`)."""
    kind = "rig" if rig is not None else "bag" if mapping is not None else "folder"
    if kind == "rig":
        reference = rig.reference
    elif kind == "bag":
        reference = parse_reference(mapping["camera"], "mapping", topic=True)
    jobs, names, paths = [], {}, {}
    for r, split in zip(rows, splits):
        if r.path in paths:
            problems.append(
                str(
                    ManifestError(
                        manifest,
                        r.line,
                        "path",
                        f"the recording {r.path} is listed again (line {paths[r.path]}): "
                        "one recording is one trial, in one split, under one label",
                    )
                )
            )
            continue
        paths[r.path] = r.line
        try:
            if kind == "rig":
                if r.label not in label_map:
                    raise ManifestError(
                        manifest,
                        r.line,
                        "label",
                        f"{r.label!r} is not in the label map (its names: {', '.join(sorted(label_map))})",
                    )
                cls = label_map[r.label]
                fields = dict(
                    label=cls,
                    label_name=r.label,
                    label_map=label_map,
                    properties=r.properties,
                    day=r.day,
                    trial=r.trial,
                    condition=r.condition,
                    **({"split": split} if split else {}),
                )
                rig_folder.check_layout(r.path, rig)
            else:
                fid = manifest_file.integer(r.label, manifest, r.line, "label")
                if r.day is None:
                    raise ManifestError(manifest, r.line, "day", "missing: the hand's importers need a day")
                # the hand's protocol: a trial is lab unless the row says cafe (as `import_folder`'s flag)
                fields = {"fabric_id": fid, "day": r.day, "trial": r.trial, "condition": r.condition or "lab"}
                if kind == "folder":
                    hand_folder.check_layout(r.path, reference)
                elif not r.path.exists():
                    raise ManifestError(manifest, r.line, "path", f"no such bag: {r.path}")
        except UserError as e:
            problems.append(str(e))
            continue
        name = archive.trial_filename(fields)
        if name in names:
            problems.append(
                str(
                    ManifestError(
                        manifest,
                        r.line,
                        "trial",
                        f"gives the archive {name}, as line {names[name]} does (make label, day, trial unique)",
                    )
                )
            )
            continue
        names[name] = r.line
        jobs.append(Job(kind, r, str(out / name), fields, split, rig, mapping, str(manifest), reference))
    return jobs


def _difference(meta: dict[str, Any], job: Job) -> str | None:
    """How an existing archive differs from what the job would import (None: the same trial)."""
    if meta["source"].get("path") != str(job.row.path):
        return f"was imported from {meta['source'].get('path')}, not from {job.row.path} as line {job.row.line} says"
    if meta.get("label_map") != job.meta_fields.get("label_map"):
        return (
            f"its label map {meta.get('label_map')} differs from the manifest's "
            f"{job.meta_fields.get('label_map')} (classes added or renamed)"
        )
    wanted_reference = None if job.reference is None else job.reference.describe()
    if meta["source"].get("reference") != wanted_reference:
        if "reference" not in meta["source"]:
            return "it holds no camera reference (imported before archives carried one)"
        return (
            f"its camera reference was read from {meta['source']['reference']}, not from {wanted_reference} as "
            f"the import now names it"
        )
    wanted = {**{k: v for k, v in job.meta_fields.items() if k != "label_map"}, "split": job.split}
    changed = [
        f"{key} {meta.get(key)!r} where line {job.row.line} says {want!r}"
        for key, want in wanted.items()
        if meta.get(key) != want
    ]
    if job.reference is not None and (
        session := session_of({**job.meta_fields, "session": job.row.session})
    ) != meta.get("reference", {}).get("session"):
        changed.append(
            f"session {meta.get('reference', {}).get('session')!r} where line {job.row.line} says {session!r}"
        )
    return f"it has {', '.join(changed)}" if changed else None


def check_out(
    out: Path, jobs: list[Job], overwrite: bool, manifest, problems: list[str], say: Callable[[str], None]
) -> tuple[list[Job], list[Path]]:
    """The jobs to run, and the archives in `out` that --overwrite removes (no row produces them);
    what `out` already holds that a plain rerun may not keep is a problem."""
    if out.exists() and not out.is_dir():
        problems.append(f"{out}: --out: not a folder")
        return jobs, []
    names = {Path(j.target).name for j in jobs}
    foreign = sorted(p for p in out.glob("*.npz") if p.name not in names) if out.is_dir() else []
    if overwrite:
        return jobs, foreign
    if foreign:
        shown = ", ".join(p.name for p in foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
        problems.append(
            f"{out}: --out: holds {len(foreign)} archive{'s' * (len(foreign) != 1)} no row of {manifest} "
            f"produces ({shown}): "
            "another dataset, or rows since removed or relabelled; choose another --out, or pass --overwrite "
            "to replace the dataset in it"
        )
    todo = []
    for j in jobs:
        target = Path(j.target)
        if not target.exists():
            todo.append(j)
            continue
        try:
            meta = archive.read_archive(target).meta  # every member read back against its CRC-32
        except archive.ArchiveError as e:
            say(f"note: {target}: damaged ({e.field}: {e.problem}): imported again")
            todo.append(j)
            continue
        if (difference := _difference(meta, j)) is not None:
            problems.append(f"{target}: exists, but {difference}; pass --overwrite to replace the dataset")
    return todo, []


def _writable(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UserError(f"{out}: --out: cannot write there: {e.strerror or e}") from None


def _staging(out: Path) -> Path:
    """A new staging folder in `out`, after removing what a killed run left there (the import's
    lock is held: no other import is using them)."""
    try:
        for stray in out.glob(f"{STAGING[0]}*{STAGING[1]}"):
            shutil.rmtree(stray)
        for stray in out.glob(".*.partial"):  # `atomic_open`'s temporaries
            stray.unlink()
        return Path(tempfile.mkdtemp(prefix=STAGING[0], suffix=STAGING[1], dir=out))
    except OSError as e:
        raise UserError(f"{out}: --out: cannot write there: {e.strerror or e}") from None


def run(
    manifest: str | Path,
    out: str | Path,
    *,
    rig: str | Path | None = None,
    mapping: str | Path | None = None,
    labels: str | Path | None = None,
    split: str | None = None,
    overwrite: bool = False,
    workers: int | None = None,
    progress: bool = True,
    say: Callable[[str], None] = print,
    reference: str | None = None,
    reference_frames: int | None = None,
    workdir: str | Path | None = None,
) -> dict[str, Any]:
    """Import every row of `manifest` into `out` as one transaction, then index `out` in the
    workspace `workdir` (module docstring); returns a summary. `reference`, `reference_frames`: the
    hand's folders' session reference (--reference)."""
    t0 = time.perf_counter()
    if rig is not None and mapping is not None:
        raise UserError("give --rig (trial folders of another rig) or --map (ROS 2 bags), not both")
    if (rig is not None or mapping is not None) and (reference is not None or reference_frames is not None):
        raise UserError(
            f"--reference names the session reference of the hand's trial folders; "
            f"{'a rig file' if rig is not None else 'a mapping'} "
            f"names its camera's own ([camera] {'reference' if rig is not None else 'reference_topic or reference'})"
        )
    folder_reference = None
    if rig is None and mapping is None:  # the hand's folders have a camera: the command line names its reference
        folder_reference = parse_reference(
            {"reference": reference, "reference_frames": reference_frames}, manifest, flags=True
        )
    rows, header, problems = manifest_file.read_manifest(manifest)
    splits = manifest_file.splits(rows, split, manifest, problems)
    loaded_rig = rig_folder.load_rig(rig) if rig is not None else None
    used = (
        (COLUMNS if loaded_rig.camera else tuple(c for c in COLUMNS if c != "session"))
        if loaded_rig is not None
        else HAND_COLUMNS
    )
    ignored = [h for h in header if h not in used]
    if ignored:
        say(f"note: {manifest}: columns not used: {', '.join(ignored)} (used: {', '.join(used)})")
    if loaded_rig is not None and not any(splits) and any(r.day is None for r in rows):
        r = next(r for r in rows if r.day is None)
        problems.append(
            str(
                ManifestError(
                    manifest,
                    r.line,
                    "split",
                    "no split and no day: the trial would belong to no split "
                    "(give a split column, --split=fraction:TRAIN,VAL,TEST or trial:SPLIT=FIRST-LAST,..., or "
                    "days with --split=day)",
                )
            )
        )
    label_map = None
    if loaded_rig is not None:
        label_map = manifest_file.label_map(rows, labels)
    elif labels:
        raise UserError(
            "--labels names classes of a rig's recordings (--rig); the hand's folders and bags are labelled "
            "by fabric id"
        )
    loaded_map = mapping_file.load_mapping(mapping) if mapping is not None else None
    out = Path(out)
    jobs = plan(
        rows,
        out,
        rig=loaded_rig,
        mapping=loaded_map,
        label_map=label_map,
        splits=splits,
        manifest=manifest,
        problems=problems,
        reference=folder_reference,
    )
    todo, stale = check_out(out, jobs, overwrite, manifest, problems, say)
    if problems:
        raise ImportProblems(
            problems + ([f"{out}: nothing was written ({len(problems)} problems above)"] if len(problems) > 1 else [])
        )
    _writable(out)
    # one import at a time
    with lock.hold(out / IMPORT_LOCK, f"the import into {out}", f"importing {len(todo)} trials", transient=True):
        staging = _staging(out)
        try:
            staged = [dataclasses.replace(j, target=str(staging / Path(j.target).name)) for j in todo]
            n = max(1, min(workers or os.cpu_count() or 1, len(todo)))
            with tqdm(total=len(todo), desc=f"import ({n} processes)", unit="trial", disable=not progress) as bar:
                parallel.run_jobs(_import_one, staged, n, bar.update)
            failed = [Path(j.target + ".error").read_text() for j in staged if Path(j.target + ".error").exists()]
            if failed:
                raise ImportProblems(
                    failed + ([f"{out}: nothing was written ({len(failed)} trials failed)"] if len(failed) > 1 else [])
                )
            for j, s in zip(todo, staged):  # the import is complete: into DIR, and what no row produces out of it
                os.replace(s.target, j.target)
            for p in stale:
                p.unlink()
            source = provenance.from_readme(Path(manifest).parent)
            if source is not None:
                provenance.write(out, source)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
        index_path = workspace.index_file(out, workdir)
        dataset_index.build_index(
            out, index_path
        )  # an earlier index's entries of the archives kept are not hashed again
    notes: dict[str, Counter] = defaultdict(Counter)
    steps = 0
    for j in jobs:
        meta, n_steps = archive.read_meta(j.target)
        steps += n_steps
        notes["columns"].update(meta.get("import", {}).get("ignored_columns", []))
        notes["incomplete"].update(["trials"] if not meta["complete"] else [])
        notes["joint_gaps"].update(["trials"] if meta.get("import", {}).get("joint_gaps") else [])
    if notes["columns"]:
        say(
            f"note: joint columns not named in the rig file, not imported: "
            f"{', '.join(f'{c} ({k} trials)' for c, k in sorted(notes['columns'].items()))}"
        )
    if notes["incomplete"]:
        say(
            f"note: {notes['incomplete']['trials']} trials are incomplete (complete: false; "
            f"meta.import.truncated names the cut-off files)"
        )
    if notes["joint_gaps"]:
        say(
            f"note: {notes['joint_gaps']['trials']} trials have holes in the joints, where steps hold the "
            f"last reading (meta.import.joint_gaps)"
        )
    per_split = Counter(s or "by day" for s in splits)
    n_classes = (
        len(set(label_map.values())) if label_map else None
    )  # classes, not names: a label file may give one class two names
    summary = {
        "trials": len(jobs),
        "imported": len(todo),
        "resumed": len(jobs) - len(todo),
        "removed": len(stale),
        "steps": steps,
        "splits": dict(per_split),
        "classes": n_classes,
        "seconds": time.perf_counter() - t0,
        "out": str(out),
        "index": str(index_path),
    }
    say(
        f"{out}: {len(todo)} trials imported, {len(jobs) - len(todo)} already there (resumed); {steps} steps; "
        f"splits {', '.join(f'{k} {v}' for k, v in sorted(per_split.items()))}"
        + (f"; {n_classes} classes" if label_map else "")
        + (f"; {len(stale)} archives no row produces removed (--overwrite)" if stale else "")
        + f" ({summary['seconds']:.1f} s)"
    )
    verify = "experiments.verify" + (f" --workdir={workdir}" if workdir is not None else "")
    say(f"{out}: indexed, each archive's sha256 in {workspace.shown(index_path)} ({verify} re-hashes against it)")
    return summary
