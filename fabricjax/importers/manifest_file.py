"""A manifest: the CSV that lists the trials of one import, one row per trial, with a header row
(docs/data.md, "Recordings from another rig"), and what names its classes and splits.

    path        the trial: a folder (of the rig file's layout with --rig, else of the hand's:
                internal.wav, external.wav, joints.csv, camera) or a ROS 2 bag (with --map)
                relative to the manifest's folder
    label       the trial's class by name (with --rig; e.g. "felt"), or the hand's fabric id
    split       optional: train | val | test | cafe | holdout
    day, trial, condition     optional (condition: lab | cafe; a rig's trial without one has
                none, the hand's folders and bags are lab, as import_folder's; trial: default the
                row's index among its label's rows)
    session     optional: the session whose camera reference the trial shares
                (meta.reference.session; default: the trial's day and condition, without days the
                trial's own name); not read for a rig without a camera
    stretchiness, roughness, thickness     optional property levels (ints), only where known

The label map (name -> class) is a CSV with columns name, class (`read_label_map`) or, without
one, the manifest's label names in sorted order as classes 0..K-1 (`label_map`). Splits are the
manifest's `split` column, or a rule (`parse_split_rule`): `fraction:TRAIN,VAL,TEST` (per class, in
trial order: the first fraction of its trials train, then val, then test),
`trial:train=0-3,val=4,test=5-6` (by trial index, inclusive ranges, the same in every class;
every trial's index must be in one) or `day` (by day, as the preset's days: the hand's protocol).

A row's problems are collected, one line each, so that an import lists them all before it writes
anything (`fabricjax.importers.batch`).
"""

from __future__ import annotations

import csv
import dataclasses
from collections import defaultdict
from pathlib import Path

from fabricjax.errors import UserError
from fabricjax.store import archive

COLUMNS = ("path", "label", "split", "day", "trial", "condition", "session", *archive.PROPERTY_NAMES)
HAND_COLUMNS = COLUMNS[:7]  # the hand's folders and bags: property levels come from the fabric catalog


@dataclasses.dataclass(frozen=True)
class Row:
    line: int  # in the manifest, for errors
    path: Path
    label: str
    split: str | None
    day: int | None
    trial: int | None
    condition: str | None  # None: the manifest gives none
    properties: dict[str, int]
    session: str | None = None  # the session whose camera reference the trial shares


class ManifestError(UserError):
    def __init__(self, path, line: int | str, field: str, problem: str):
        super().__init__(f"{path}: line {line}: {field}: {problem}")


def integer(text: str, manifest, line: int, field: str) -> int | None:
    """A manifest cell as a count (a day, trial, fabric id, class or property level: an integer the
    archive holds, from 0 to `archive.MAX_INT`), checked here so that a bad cell is named by its line
    rather than by the archive it would have made; an empty cell is None."""
    if text.strip() == "":
        return None
    try:
        value = int(text)
    except ValueError:
        raise ManifestError(manifest, line, field, f"{text!r} is not an integer") from None
    if not 0 <= value <= archive.MAX_INT:
        raise ManifestError(manifest, line, field, f"must be an integer from 0 to {archive.MAX_INT}, got {text!r}")
    return value


def _utf8_lines(path: Path, what: str):
    """The text of a UTF-8 file (with or without a byte-order mark); another encoding is a one-line error."""
    try:
        return path.read_text(encoding="utf-8-sig").splitlines(keepends=True)
    except UnicodeDecodeError as e:
        raise ManifestError(
            path,
            "-",
            "<file>",
            f"not UTF-8 text (byte {e.object[e.start]:#04x} at offset {e.start}): save the {what} as UTF-8",
        ) from None


def read_manifest(manifest: str | Path) -> tuple[list[Row], list[str], list[str]]:
    """The rows (a row without a trial index numbered among its label's rows), the manifest's
    columns, and the problems of its rows (one line each; such a row is left out)."""
    manifest = Path(manifest)
    if not manifest.is_file():
        raise ManifestError(manifest, "-", "<file>", "no such manifest")
    reader = csv.DictReader(_utf8_lines(manifest, "manifest"))
    header = [h.strip() for h in reader.fieldnames or []]
    for col in ("path", "label"):
        if col not in header:
            raise ManifestError(manifest, 1, col, "column missing")
    rows, problems = [], []
    for line, raw in enumerate(reader, start=2):
        try:
            rows.append(_row(manifest, line, {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}))
        except ManifestError as e:
            problems.append(str(e))
    if not rows and not problems:
        raise ManifestError(manifest, 2, "<rows>", "the manifest lists no trials")
    counters: dict[str, int] = defaultdict(int)
    numbered = [
        dataclasses.replace(r, trial=r.trial if r.trial is not None else _next(counters, r.label)) for r in rows
    ]
    return numbered, header, problems


def _next(counters: dict[str, int], label: str) -> int:
    counters[label] += 1
    return counters[label] - 1


def _row(manifest: Path, line: int, r: dict[str, str]) -> Row:
    if not r["path"] or not r["label"]:
        raise ManifestError(manifest, line, "path" if not r["path"] else "label", "empty")
    split = r.get("split") or None
    if split is not None and split not in archive.SPLITS:
        raise ManifestError(manifest, line, "split", f"must be one of {archive.SPLITS}, got {split!r}")
    condition = r.get("condition") or None
    if condition is not None and condition not in archive.CONDITIONS:
        raise ManifestError(manifest, line, "condition", f"must be one of {archive.CONDITIONS}, got {condition!r}")
    props = {p: v for p in archive.PROPERTY_NAMES if (v := integer(r.get(p, ""), manifest, line, p)) is not None}
    return Row(
        line,
        (manifest.parent / r["path"]).resolve(),
        r["label"],
        split,
        integer(r.get("day", ""), manifest, line, "day"),
        integer(r.get("trial", ""), manifest, line, "trial"),
        condition,
        props,
        r.get("session") or None,
    )


def read_label_map(path: str | Path) -> dict[str, int]:
    """A label map file: CSV with columns name, class (classes 0..K-1, each named)."""
    path = Path(path)
    if not path.is_file():
        raise ManifestError(path, "-", "<file>", "no such label map")
    reader = csv.DictReader(_utf8_lines(path, "label map"))
    if not {"name", "class"} <= set(reader.fieldnames or []):
        raise ManifestError(path, 1, "name, class", "columns missing")
    out = {}
    for line, r in enumerate(reader, start=2):
        cls = integer(r["class"] or "", path, line, "class")
        if cls is None:
            raise ManifestError(path, line, "class", f"must be a class >= 0, got {r['class']!r}")
        out[(r["name"] or "").strip()] = cls
    if not out or set(out.values()) != set(range(max(out.values()) + 1)):
        raise ManifestError(path, "-", "class", f"classes must be 0..K-1, each named; got {sorted(set(out.values()))}")
    return out


def label_map(rows: list[Row], labels: str | Path | None) -> dict[str, int]:
    """The label map of `labels` (a file, `read_label_map`), or without one the rows' label names
    in sorted order as classes 0..K-1."""
    return read_label_map(labels) if labels else {name: k for k, name in enumerate(sorted({r.label for r in rows}))}


def parse_split_rule(rule: str | None) -> tuple[str, tuple[float, ...] | dict[int, str]] | None:
    """None (the manifest's column), ("day", ()), ("fraction", (train, val, test)) or ("trial",
    {trial index: split})."""
    if rule is None:
        return None
    if rule == "day":
        return ("day", ())
    kind, _, rest = rule.partition(":")
    if kind == "trial":
        return ("trial", _trial_ranges(rule, rest))
    try:
        fractions = tuple(float(x) for x in rest.split(","))
    except ValueError:
        fractions = ()
    if kind != "fraction" or len(fractions) != 3 or min(fractions) < 0 or abs(sum(fractions) - 1) > 1e-6:
        raise UserError(
            f"--split={rule}: expected day, fraction:TRAIN,VAL,TEST with fractions summing to 1 (e.g. "
            "fraction:0.7,0.15,0.15) or trial:SPLIT=FIRST-LAST,... (e.g. trial:train=0-3,val=4,test=5-6)"
        )
    return ("fraction", fractions)


def _trial_ranges(rule: str, rest: str) -> dict[int, str]:
    """`train=0-3,val=4,test=5-6` -> {0: "train", ..., 6: "test"}: inclusive ranges of trial
    indices, each index in one split."""
    usage = (
        f"--split={rule}: expected trial:SPLIT=FIRST-LAST,... with splits from {', '.join(archive.SPLITS)} "
        "and each trial index in one range, e.g. trial:train=0-3,val=4,test=5-6"
    )
    out: dict[int, str] = {}
    for item in rest.split(","):
        split, _, span = item.partition("=")
        first, _, last = span.partition("-")
        try:
            first, last = int(first), int(last or first)
        except ValueError:
            raise UserError(usage) from None
        indices = range(first, last + 1)
        if split not in archive.SPLITS or first < 0 or not indices or any(k in out for k in indices):
            raise UserError(usage)
        out.update(dict.fromkeys(indices, split))
    return out


def splits(rows: list[Row], rule: str | None, manifest, problems: list[str]) -> list[str | None]:
    """Each row's split: by the rule `rule` (`parse_split_rule`), or the manifest's column, which
    then every row gives or none; a row the rule or the column leaves without one is a problem."""
    parsed = parse_split_rule(rule)
    has_column = any(r.split for r in rows)
    if parsed is not None and has_column:
        raise UserError(f"{manifest}: has a split column and --split={rule} was given: choose one")
    if parsed is None and has_column:
        problems += [
            str(
                ManifestError(
                    manifest, r.line, "split", "empty, while other rows give one (give every row a split, or none)"
                )
            )
            for r in rows
            if not r.split
        ]
    if parsed and parsed[0] == "fraction":
        return by_fraction(rows, parsed[1])
    if parsed and parsed[0] == "trial":
        return by_trial(rows, parsed[1], manifest, rule, problems)
    return [r.split for r in rows]


def by_trial(rows: list[Row], splits: dict[int, str], manifest, rule: str, problems: list[str]) -> list[str | None]:
    """Each row's split by its trial index (the same indices in every class: stratified by class);
    a row whose index no range names is a problem, not a trial left out."""
    problems += [
        str(ManifestError(manifest, r.line, "trial", f"trial {r.trial} is in no range of --split={rule}"))
        for r in rows
        if r.trial not in splits
    ]
    return [splits.get(r.trial) for r in rows]


def by_fraction(rows: list[Row], fractions: tuple[float, float, float]) -> list[str]:
    """Per label, in (day, trial) order: the first `train` fraction train, then val, the rest test
    (stratified by class, deterministic)."""
    out = [""] * len(rows)
    groups: dict[str, list[int]] = defaultdict(list)
    for i, r in enumerate(rows):
        groups[r.label].append(i)
    for members in groups.values():
        members.sort(key=lambda i: (rows[i].day if rows[i].day is not None else -1, rows[i].trial))
        n = len(members)
        n_train = round(fractions[0] * n)
        n_val = round((fractions[0] + fractions[1]) * n) - n_train
        for k, i in enumerate(members):
            out[i] = "train" if k < n_train else "val" if k < n_train + n_val else "test"
    return out
