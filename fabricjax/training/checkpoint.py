"""Orbax checkpoints of the stacked (all-seed) training state, tagged with the config as JSON.

A checkpoint step is the number of finished epochs. The config and seeds are saved next to the
state, so restoring under a different config fails loudly instead of silently mixing runs. Orbax
has no restore of one index along an axis: one seed is the stacked restore, sliced.

The meta also says what the model was trained for (`trained_for`: its heads, classes, inputs and
the fabrics it never saw), so that a command reading a checkpoint can refuse one made for another
job (`require`) in one line. A restore places every array on this process's devices (`on_devices`),
whatever the device and process count of the run that saved it. Reading opens a checkpoint folder
without creating anything (`open_existing`): a path holding no checkpoint is a one-line error.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any, Mapping, Sequence

import jax
import numpy as np
import orbax.checkpoint as ocp
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from fabricjax.config import RESULT_NEUTRAL_FIELDS, Config
from fabricjax.errors import UserError
from fabricjax.model import head_sizes
from fabricjax.store import disk

# The layout of the saved training state; bumped whenever it changes (2: the optimiser state holds
# the cosine decay's own step counter; 3: Adam's moments are one flat vector; 4: each seed's early-stopping epoch), so a
# checkpoint of
# another layout is refused by name instead of failing inside orbax, and a study's checkpoint
# folder (tagged with it) starts afresh.
STATE_VERSION = 4


class CheckpointMismatch(UserError):
    """A checkpoint directory holds a run made with another config or other seeds."""


class NoCheckpoint(UserError, FileNotFoundError):
    """A path given as a checkpoint holds none."""


class WrongCheckpoint(UserError):
    """A checkpoint made for another job than the one a command does with it."""


def manager(directory: str | os.PathLike, max_to_keep: int = 2) -> ocp.CheckpointManager:
    """The checkpoints of a training run in `directory` (created), to save and resume."""
    return ocp.CheckpointManager(
        os.path.abspath(directory), options=ocp.CheckpointManagerOptions(max_to_keep=max_to_keep)
    )


def open_existing(directory: str | os.PathLike) -> ocp.CheckpointManager:
    """The checkpoints in `directory`, only read; a path holding none (absent, a file, an empty or
    other folder such as the parent of checkpoint folders) is a `NoCheckpoint` naming the path and,
    for a parent, the checkpoint folders inside it. Nothing is created."""
    path = os.path.abspath(directory)
    if not os.path.isdir(path):
        raise NoCheckpoint(
            f"no checkpoint at {path}: {'no such folder' if not os.path.exists(path) else 'not a folder'}"
        )
    # create=False and no save: nothing is written (orbax's read_only mode says as much in two warnings)
    mngr = ocp.CheckpointManager(path, options=ocp.CheckpointManagerOptions(create=False))
    if mngr.latest_step() is None:
        inside = sorted(str(p) for p in Path(path).glob("*/") if p.is_dir() and _holds_steps(p))
        hint = (
            f"; checkpoint folders inside it: {', '.join(inside)}"
            if inside
            else " (a checkpoint folder holds numbered step folders)"
        )
        raise NoCheckpoint(f"no checkpoint in {path}{hint}")
    return mngr


def _holds_steps(folder: Path) -> bool:
    return any(p.is_dir() and p.name.isdigit() and (p / "meta").exists() for p in folder.iterdir())


def meta(
    config: Config,
    seeds,
    shapes: dict[str, tuple[int, ...]],
    classes: Sequence[str] | None = None,
    dataset: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """What identifies a run (its config, its seeds, the per-step input shapes, the state's layout
    and the data it trains on: `dataset`, `DatasetIndex.identity`) and what it was trained for
    (`trained_for`, with the data's class names `classes`)."""
    return {
        "config": config.to_json(),
        "seeds": [int(s) for s in seeds],
        "shapes": {k: list(v) for k, v in shapes.items()},
        "state_version": STATE_VERSION,
        "trained_for": trained_for(config, classes),
        "dataset": dict(dataset or {}),
    }


def trained_for(config: Config, classes: Sequence[str] | None = None) -> dict[str, Any]:
    """What a model is for: its heads, its fabric classes (count and names, the data's label map),
    its inputs, its dataset preset and the fabrics excluded from its training (never seen)."""
    return {
        "heads": list(head_sizes(config)),
        "n_classes": config.n_classes if config.fabric_head else None,
        "classes": None if classes is None or not config.fabric_head else list(classes),
        "inputs": list(config.modalities),
        "preset": config.preset,
        "unseen_fabrics": sorted(config.exclude_fabrics),
    }


def describe(for_: Mapping[str, Any]) -> str:
    """`trained_for` in words, for an error message."""
    heads = "+".join(for_["heads"]) or "no"
    classes = f" ({for_['n_classes']} classes)" if for_.get("n_classes") else ""
    unseen = ", ".join(map(str, for_["unseen_fabrics"])) or "none"
    return (
        f"heads {heads}{classes}, inputs {'+'.join(for_['inputs'])}, preset {for_['preset']}, fabrics never "
        f"seen: {unseen}"
    )


def require(directory, for_: Mapping[str, Any], job: str, expected: str, ok: bool) -> None:
    """Raise `WrongCheckpoint` unless `ok`: `job` needs `expected`, and the checkpoint in
    `directory` holds a model trained for `for_`."""
    if not ok:
        raise WrongCheckpoint(
            f"{job} needs {expected}; the checkpoint in {directory} holds a model with {describe(for_)}"
        )


def save(mngr: ocp.CheckpointManager, step: int, state, run_meta: dict[str, Any]) -> None:
    """Save and wait: callers treat a returned save as durable (e.g. before a kill).

    The state is copied to the host first: orbax saves a device array from each device's shard,
    and compiles a slicing program per array shape and device to do so, which costs a run's first
    save far more than the host copy does. A restore places
    the arrays on the devices whichever way they were saved (`restore`). A save that would not fit
    on the disk is a `disk.DiskFull` before orbax starts (orbax's own threads would print a
    traceback each); one that fills the disk all the same leaves no unfinished step behind."""
    state = jax.device_get(state)
    where, what = Path(mngr.directory), f"the checkpoint of epoch {step}"
    needed = sum(np.asarray(x).nbytes for x in jax.tree.leaves(state))
    disk.require(where, needed, what, margin=SAVE_MARGIN)
    try:
        with disk.writing(where, what, needed):
            mngr.save(
                step, args=ocp.args.Composite(state=ocp.args.StandardSave(state), meta=ocp.args.JsonSave(run_meta))
            )
            mngr.wait_until_finished()
    except disk.DiskFull:
        for unfinished in where.glob(f"{step}.orbax-checkpoint-tmp*"):
            shutil.rmtree(unfinished, ignore_errors=True)
        raise


# Free space a save asks for beyond the arrays' bytes: orbax's metadata and the file system's blocks.
SAVE_MARGIN = 1.25


def read_meta(mngr: ocp.CheckpointManager, step: int | None = None) -> dict[str, Any]:
    step = mngr.latest_step() if step is None else step
    return mngr.restore(step, args=ocp.args.Composite(meta=ocp.args.JsonRestore()))["meta"]


def check_meta(directory, saved: dict[str, Any], expected: dict[str, Any]) -> None:
    """Raise `CheckpointMismatch` naming the directory and every field that differs; a run on other
    data (`require_data`) first, naming both datasets."""
    if expected.get("dataset"):
        require_data(directory, saved.get("dataset"), expected["dataset"], CheckpointMismatch)
    cfg = expected["config"]
    saved_cfg = saved.get("config", {})
    diff = sorted(
        k
        for k in (set(cfg) | set(saved_cfg)) - set(RESULT_NEUTRAL_FIELDS)
        if _norm(cfg.get(k)) != _norm(saved_cfg.get(k))
    )
    diff += [k for k in RUN_FIELDS if _norm(saved.get(k, 1 if k == "state_version" else None)) != _norm(expected[k])]
    if diff:
        details = "; ".join(f"{k}: saved {_field(saved, k)!r}, requested {_field(expected, k)!r}" for k in diff)
        raise CheckpointMismatch(f"checkpoint in {directory} was made with a different run: {details}")


def require_data(
    directory, trained_on: Mapping[str, str] | None, reads: Mapping[str, str], error: type[UserError] = WrongCheckpoint
) -> None:
    """Raise `error` unless the checkpoint in `directory`, trained on `trained_on`, was trained on
    the data this run `reads` (both `DatasetIndex.identity`): equal contents, wherever they lie. A
    checkpoint that does not name its data is refused too: its data cannot be told."""
    if not trained_on:
        raise error(
            f"the checkpoint in {directory} does not record the data it was trained on, so it cannot be used "
            f"with {reads['folder']}: retrain it"
        )
    if trained_on.get("content") != reads.get("content"):
        raise error(
            f"the checkpoint in {directory} was trained on {trained_on.get('folder')} (contents "
            f"{trained_on.get('content')}), "
            f"not on {reads['folder']} (contents {reads['content']}) that this run reads"
        )


RUN_FIELDS = (
    "seeds",
    "shapes",
    "state_version",
)  # beside the config's fields (a checkpoint without state_version has layout 1)


def _field(m: dict[str, Any], k: str):
    return m.get(k, 1 if k == "state_version" else None) if k in RUN_FIELDS else m.get("config", {}).get(k)


def _norm(v):
    """JSON turns tuples into lists; compare modulo that."""
    if isinstance(v, (list, tuple)):
        return [_norm(x) for x in v]
    if isinstance(v, dict):
        return {k: _norm(x) for k, x in v.items()}
    return v


def on_devices(abstract_state):
    """`abstract_state` (arrays' shapes and dtypes) placed whole on every device of this run
    (replicated), whatever devices and processes the saved arrays were on: orbax then reshards on
    restore instead of refusing another topology."""
    everywhere = NamedSharding(Mesh(np.asarray(jax.devices()), ("all",)), PartitionSpec())
    return jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=everywhere), abstract_state)


def restore(mngr: ocp.CheckpointManager, abstract_state, expected_meta: dict[str, Any], step: int | None = None):
    """(stacked state, step) of the latest (or given) step, after checking the run's identity;
    arrays come back with `abstract_state`'s shardings (`on_devices` for any of this run's devices)."""
    step = mngr.latest_step() if step is None else step
    if step is None:
        raise NoCheckpoint(f"no checkpoint in {mngr.directory}")
    check_meta(mngr.directory, read_meta(mngr, step), expected_meta)
    out = mngr.restore(step, args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract_state)))
    return out["state"], step


def select_seed(state, index: int):
    """One seed's slice of a stacked state."""
    return jax.tree.map(lambda x: x[index], state)
