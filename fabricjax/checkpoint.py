"""Orbax checkpoints of the stacked (all-seed) training state, tagged with the config as JSON.

A checkpoint step is the number of finished epochs. The config and seeds are saved next to the
state, so restoring under a different config fails loudly instead of silently mixing runs. Orbax
has no restore of one index along an axis: one seed is the stacked restore, sliced.
"""

from __future__ import annotations

import os
from typing import Any

import jax
import orbax.checkpoint as ocp

from fabricjax.config import Config
from fabricjax.errors import UserError


# The layout of the saved training state; bumped whenever it changes (2: the optimiser state holds
# the cosine decay's own step counter), so a checkpoint of another layout is refused by name
# instead of failing inside orbax, and a study's checkpoint folder (tagged with it) starts afresh.
STATE_VERSION = 2


class CheckpointMismatch(UserError):
    """A checkpoint directory holds a run made with another config or other seeds."""


def manager(directory: str | os.PathLike, max_to_keep: int = 2) -> ocp.CheckpointManager:
    return ocp.CheckpointManager(
        os.path.abspath(directory), options=ocp.CheckpointManagerOptions(max_to_keep=max_to_keep)
    )


def meta(config: Config, seeds, shapes: dict[str, tuple[int, ...]]) -> dict[str, Any]:
    """What identifies a run: its config, its seeds, the per-step input shapes and the state's layout."""
    return {
        "config": config.to_json(), "seeds": [int(s) for s in seeds], "shapes": {k: list(v) for k, v in shapes.items()},
        "state_version": STATE_VERSION,
    }


def save(mngr: ocp.CheckpointManager, step: int, state, run_meta: dict[str, Any]) -> None:
    """Save and wait: callers treat a returned save as durable (e.g. before a kill)."""
    mngr.save(step, args=ocp.args.Composite(state=ocp.args.StandardSave(state), meta=ocp.args.JsonSave(run_meta)))
    mngr.wait_until_finished()


def read_meta(mngr: ocp.CheckpointManager, step: int | None = None) -> dict[str, Any]:
    step = mngr.latest_step() if step is None else step
    return mngr.restore(step, args=ocp.args.Composite(meta=ocp.args.JsonRestore()))["meta"]


def check_meta(directory, saved: dict[str, Any], expected: dict[str, Any]) -> None:
    """Raise `CheckpointMismatch` naming the directory and every field that differs."""
    cfg = expected["config"]
    saved_cfg = saved.get("config", {})
    diff = sorted(k for k in set(cfg) | set(saved_cfg) if _norm(cfg.get(k)) != _norm(saved_cfg.get(k)))
    diff += [k for k in RUN_FIELDS if _norm(saved.get(k, 1 if k == "state_version" else None)) != _norm(expected[k])]
    if diff:
        details = "; ".join(
            f"{k}: saved {_field(saved, k)!r}, requested {_field(expected, k)!r}" for k in diff
        )
        raise CheckpointMismatch(f"checkpoint in {directory} was made with a different run: {details}")


RUN_FIELDS = ("seeds", "shapes", "state_version")  # beside the config's fields (a checkpoint without state_version has layout 1)


def _field(m: dict[str, Any], k: str):
    return m.get(k, 1 if k == "state_version" else None) if k in RUN_FIELDS else m.get("config", {}).get(k)


def _norm(v):
    """JSON turns tuples into lists; compare modulo that."""
    if isinstance(v, (list, tuple)):
        return [_norm(x) for x in v]
    if isinstance(v, dict):
        return {k: _norm(x) for k, x in v.items()}
    return v


def restore(mngr: ocp.CheckpointManager, abstract_state, expected_meta: dict[str, Any], step: int | None = None):
    """(stacked state, step) of the latest (or given) step, after checking the run's identity."""
    step = mngr.latest_step() if step is None else step
    if step is None:
        raise FileNotFoundError(f"no checkpoint in {mngr.directory}")
    check_meta(mngr.directory, read_meta(mngr, step), expected_meta)
    out = mngr.restore(step, args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract_state)))
    return out["state"], step


def select_seed(state, index: int):
    """One seed's slice of a stacked state."""
    return jax.tree.map(lambda x: x[index], state)

