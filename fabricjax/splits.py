"""Splits and dataset presets as data.

The paper's protocol: training trials on days 1 and 2 (six per fabric per day, lab noise), test
trials on day 3 (two per fabric), a separate cafe-noise test set (two per fabric, here day 4),
property holdouts (fabrics 1 and 10 never trained on in the property experiment, new fabrics
21-23 only ever tested). A validation split is carved from the training days by holding out
whole trials (the last `val_trials_per_day` of each fabric and day), so no trial leaks.

Roles are derived from an archive's meta alone (`role_of`), so real recordings drop in: put the
training days' trials under days 1-2, test under day 3 and cafe-noise trials with
condition "cafe".

Presets (`PRESETS`), chosen with `--preset`:
    smoke    seconds; 6 classes, 3 rubbing cycles per trial, N=20. For tests.
    default  the README's main command on a 2-core laptop CPU, at the paper's data scale: all 24
             fabrics, 6 training trials per day, 2 test and 2 cafe trials, 50 rubbing cycles per
             trial (~30 s, ~1500 steps), N=50 (1 s). Minsight frames are rendered at 60x80, the
             paper's image-row input size (it downsamples 308x410 to 60x80), so the camera rows
             keep the trial length within a laptop's time and disk: optical flow is computed on
             those frames (pooled 3x3 to 20x27) instead of at 308x410. (The default training
             settings read the image rows at 30x40, see studies/common.py.)
    paper    the paper's scale: 6 trials per day, 50 cycles (~30 s, ~1500 steps), N=200,
             Minsight at 308x410 (flow 102x137).
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from typing import Any, Iterable

from fabricjax import catalog

ROLES = ("train", "val", "test", "cafe")


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


@dataclasses.dataclass(frozen=True)
class Preset:
    name: str
    fabrics: tuple[int, ...]
    train_trials_per_day: int
    test_trials: int
    cafe_trials: int
    cycles_per_trial: int
    seq_len: int
    image_size: tuple[int, int]
    splits: Splits = Splits()

    def trials(self) -> list[TrialSpec]:
        """Every trial this preset's dataset holds; new fabrics 21-23 have test trials only."""
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


_ALL = tuple(f.id for f in catalog.FABRICS)
PRESETS: dict[str, Preset] = {
    "smoke": Preset("smoke", (0, 1, 4, 10, 12, 21), 2, 1, 1, 3, 20, (77, 103)),
    "default": Preset("default", _ALL, 6, 2, 2, 50, 50, (60, 80)),
    "paper": Preset("paper", _ALL, 6, 2, 2, 50, 200, (308, 410)),
}


def preset(name: str) -> Preset:
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}") from None


def role_of(meta: dict[str, Any], val_trials: Iterable[tuple[int, int, int]], splits: Splits = Splits()) -> str | None:
    """The split a trial belongs to, from its meta (None: not used by any split)."""
    if meta["condition"] == "cafe":
        return "cafe"
    day = meta["day"]
    if day in splits.test_days:
        return "test"
    if day in splits.train_days:
        return "val" if (meta["fabric_id"], day, meta["trial"]) in set(val_trials) else "train"
    return None


def validation_trials(metas: Iterable[dict[str, Any]], splits: Splits = Splits()) -> set[tuple[int, int, int]]:
    """The last `val_trials_per_day` trial indices of each (fabric, training day) with >1 trial."""
    by_key: dict[tuple[int, int], list[int]] = defaultdict(list)
    for m in metas:
        if m["condition"] == "lab" and m["day"] in splits.train_days:
            by_key[(m["fabric_id"], m["day"])].append(m["trial"])
    out = set()
    for (fid, day), trials in by_key.items():
        trials = sorted(trials)
        k = min(splits.val_trials_per_day, len(trials) - 1)
        out |= {(fid, day, t) for t in trials[len(trials) - k :]} if k > 0 else set()
    return out


def assign_roles(metas: list[dict[str, Any]], splits: Splits = Splits()) -> list[str | None]:
    val = validation_trials(metas, splits)
    return [role_of(m, val, splits) for m in metas]
