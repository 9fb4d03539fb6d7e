"""A study's rows as it declares them and as a command chooses them.

`RowSpec` is one row of a study's table; `select_rows` finds the rows `--rows` names (by name,
by label or by group), `check_overrides` refuses a `--set` of a field a row sets itself, and
`feedable_rows` keeps the rows whose inputs recorded data has.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any, Mapping, Sequence

from absl import logging

from fabricjax.config import Config
from fabricjax.errors import UserError
from fabricjax.store import archive, dataset_index
from fabricjax.store.workspace import Location


@dataclasses.dataclass(frozen=True)
class RowSpec:
    """A row of a study's table as the study declares it, before anything is trained.

    `name` is what --rows, logs and checkpoints call it, `settings` the `Config` fields it sets on
    top of the preset and the overrides, `label` how tables name it, `paper` the paper's numbers
    for it (None where the paper has no such row)."""

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
    rows: Sequence[RowSpec],
    names: Sequence[str] | None,
    groups: Mapping[str, Sequence[str]] | None = None,
    default: Sequence[str] | None = None,
) -> list[RowSpec]:
    """The rows named in `names`, in the table's order; None: the rows named in `default` (every
    row where it is None). Each of `names` is a row's name (what logs and checkpoints call it),
    its label (what the tables print, such as "Minsound + palm mic", matched by `label_key`), a key
    of `groups` (a named set of rows, e.g. the ablation's "paper") or `ALL_ROWS`, in any case; one
    that is none of these, or no name at all (`--rows=`), is a one-line error listing the choices."""
    groups = {ALL_ROWS: [r.name for r in rows], **{k.casefold(): list(v) for k, v in (groups or {}).items()}}
    if names is None:
        names = list(default) if default is not None else groups[ALL_ROWS]

    def row(name: str) -> RowSpec | None:
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


def check_overrides(study: str, overrides: Mapping | None, rows: Sequence[RowSpec], instead: str) -> dict:
    """`overrides` as a dict, after checking that none of them is a `Config` field that one of the
    study's chosen `rows` sets itself: the row would silently replace the override, or the override
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


def split_by_inputs(rows: Sequence[RowSpec], have: set[str]) -> tuple[list[RowSpec], list[str]]:
    """(the rows whose inputs are all in `have`, the inputs some row needs that `have` lacks)."""
    return [r for r in rows if set(r.modalities) <= have], sorted({m for r in rows for m in r.modalities} - have)


def feedable_rows(study: str, rows: Sequence[RowSpec], where: Location) -> list[RowSpec]:
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


def _which_rows(names: Sequence[str], n_rows: int) -> str:
    return f"every one of its {n_rows} rows" if len(names) == n_rows else f"rows {', '.join(names)}"
