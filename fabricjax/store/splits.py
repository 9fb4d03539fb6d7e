"""Splits and the dataset a preset simulates, as data.

The paper's protocol: training trials on days 1 and 2 (six per fabric per day, lab noise), test
trials on day 3 (two per fabric), a separate cafe-noise test set (two per fabric, here day 4),
property holdouts (fabrics 1 and 10 never trained on in the property experiment, new fabrics
21-23 only ever tested). A validation split is carved from the training days by holding out
whole trials (the last `val_trials_per_day` of each fabric and day), so no trial leaks.

Roles are derived from an archive's meta alone (`role_of`), so real recordings drop in: a trial
whose meta names its split (`split`, set by the user at import: a manifest column or a rule, see
`experiments.import_manifest`) has that role; otherwise put the training days' trials under days
1-2, test under day 3 and cafe-noise trials with condition "cafe".

What each preset simulates (`DatasetSpec`) is part of its definition in `presets.py`.
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from typing import Any, Iterable

from fabricjax import catalog
from fabricjax.store import archive


@dataclasses.dataclass(frozen=True)
class Splits:
    train_days: tuple[int, ...] = (1, 2)
    test_days: tuple[int, ...] = (3,)
    cafe_days: tuple[int, ...] = (4,)
    val_trials_per_day: int = 1


@dataclasses.dataclass(frozen=True)
class TrialSpec:
    fabric_id: int
    day: int
    trial: int
    condition: str  # "lab" | "cafe"


@dataclasses.dataclass(frozen=True, kw_only=True)
class DatasetSpec:
    """Which trials a dataset holds and how they are recorded: per fabric, `train_trials_per_day`
    lab trials on each training day, `cafe_trials` on each cafe day and `test_trials` on each test
    day, each `cycles_per_trial` rubbing cycles long, Minsight frames at `image_size`."""

    fabrics: tuple[int, ...]
    train_trials_per_day: int
    test_trials: int
    cafe_trials: int
    cycles_per_trial: int
    image_size: tuple[int, int]
    splits: Splits = Splits()

    def trials(self) -> list[TrialSpec]:
        """Every trial this dataset holds; new fabrics 21-23 have test trials only."""
        s = self.splits
        out = []
        for fid in self.fabrics:
            if fid not in catalog.NEW_FABRICS:
                for day in s.train_days:
                    out += [TrialSpec(fid, day, t, "lab") for t in range(self.train_trials_per_day)]
                for day in s.cafe_days:
                    out += [TrialSpec(fid, day, t, "cafe") for t in range(self.cafe_trials)]
            for day in s.test_days:
                out += [TrialSpec(fid, day, t, "lab") for t in range(self.test_trials)]
        return out


def role_of(meta: dict[str, Any], val_trials: Iterable[tuple[int, int, int]], splits: Splits = Splits()) -> str | None:
    """The split a trial belongs to, from its meta (None: not used by any split)."""
    if meta.get("split") is not None:
        return meta["split"]
    if meta["condition"] == "cafe":
        return "cafe"
    day = meta["day"]
    if day in splits.test_days:
        return "test"
    if day in splits.train_days:
        return "val" if (archive.fabric_or_class(meta), day, meta["trial"]) in set(val_trials) else "train"
    return None


def validation_trials(metas: Iterable[dict[str, Any]], splits: Splits = Splits()) -> set[tuple[int, int, int]]:
    """The last `val_trials_per_day` trial indices of each (fabric, training day) with >1 trial."""
    by_key: dict[tuple[int, int], list[int]] = defaultdict(list)
    for m in metas:
        if m.get("split") is None and m["condition"] != "cafe" and m["day"] in splits.train_days:
            by_key[(archive.fabric_or_class(m), m["day"])].append(m["trial"])
    out = set()
    for (fid, day), trials in by_key.items():
        trials = sorted(trials)
        k = min(splits.val_trials_per_day, len(trials) - 1)
        out |= {(fid, day, t) for t in trials[len(trials) - k :]} if k > 0 else set()
    return out


def assign_roles(metas: list[dict[str, Any]], splits: Splits = Splits()) -> list[str | None]:
    val = validation_trials(metas, splits)
    return [role_of(m, val, splits) for m in metas]


def dataset_roles(dataset: DatasetSpec) -> list[tuple[dict[str, Any], str | None]]:
    """Each trial of `dataset` as the meta fields its archive will carry (fabric_id, day, trial,
    condition) with the role `assign_roles` gives it: what a plan counts before the data exists."""
    metas = [dataclasses.asdict(t) for t in dataset.trials()]
    return list(zip(metas, assign_roles(metas, dataset.splits)))
