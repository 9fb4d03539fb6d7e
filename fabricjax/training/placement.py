"""Where a run's inputs live: on the devices, or on the host for training fed a block at a time.

`place_sets` is the one way a run's sets reach the devices: each set's arrays that its config uses
(`select`), in training's layout (`inputs.training_input`), evaluation sets padded to whole
minibatches, built on the host with NumPy (copies of a camera row's frames then compile nothing).
A run whose training inputs are larger than memory keeps its sets on the host (`reads_from_host`)
and `fabricjax.training.feed` places them a block at a time.

The rows of a study train on the same loaded arrays, so a placed input is kept for the next run on
the same array (`KEPT`, a `memo.ByArray`) within a memory budget (`budget`): a camera's frames,
which its rows share, are laid out for the first row that reads them, and the others find them
kept. A study places each row's sets once (`Placed`), for every point of its recipe grid.
"""

from __future__ import annotations

from typing import Any, Mapping, NamedTuple

import jax
import numpy as np
from jax.sharding import NamedSharding

from fabricjax import host_arrays, memo
from fabricjax.config import Config
from fabricjax.model import head_sizes
from fabricjax.sequences.inputs import feature_shapes, training_input
from fabricjax.training import sharding


def select(config: Config, ds) -> dict[str, dict[str, np.ndarray]]:
    """The arrays of `ds` this config uses, on the host: its modalities and its heads' labels
    (int32)."""
    inputs = ds["inputs"] if isinstance(ds, Mapping) else ds.inputs
    labels = ds["labels"] if isinstance(ds, Mapping) else ds.labels
    missing = [m for m in config.modalities if m not in inputs] + [h for h in head_sizes(config) if h not in labels]
    if missing:
        raise ValueError(f"data set lacks {missing} (has inputs {sorted(inputs)}, labels {sorted(labels)})")
    return {
        "inputs": {m: np.asarray(inputs[m]) for m in config.modalities},
        "labels": {h: np.asarray(labels[h], np.int32) for h in head_sizes(config)},
    }


def reads_from_host(config: Config, train_set) -> bool:
    """Whether a run of `config` on `train_set` is fed from the host (`fabricjax.training.feed`): "disk", or
    "auto" where the loaded inputs are memory-mapped files (`data.load_sequences` made them so:
    larger than memory)."""
    if config.input_source != "auto":
        return config.input_source == "disk"
    inputs = train_set["inputs"] if isinstance(train_set, Mapping) else train_set.inputs
    return any(isinstance(inputs[m], np.memmap) for m in config.modalities)


def buffer_bytes(placed: jax.Array) -> int:
    """Memory `placed` holds: each distinct buffer once (a replicated placement on CPU devices
    without a copy shares one, `host_arrays`)."""
    return sum({s.data.unsafe_buffer_pointer(): s.data.nbytes for s in placed.addressable_shards}.values())


# Inputs as runs read them (padded, in training's layout, on the devices), kept from one run to the
# next: the rows of a study share their arrays (`memo`), within `budget`.
KEPT = memo.ByArray(max_entries=12, size=lambda placed: buffer_bytes(placed[1]))


def budget(to: NamedSharding) -> int:
    """What kept inputs may hold, every device's copy counted: a quarter of the memory they live
    in, the host's for CPU devices, else a quarter of each accelerator's."""
    limits = [(d.memory_stats() or {}).get("bytes_limit") for d in to.addressable_devices]
    if None in limits:
        return memo.memory_budget(0.25)
    return min(limits) // 4 * len(limits)


def place_input(a: np.ndarray, modality: str, multiple: int | None, to: NamedSharding) -> tuple[str, jax.Array]:
    """(the input's name in training's layout, the array on `to`'s devices), padded to whole
    minibatches of `multiple` where one is given (evaluation sets); kept in `KEPT` for the next run
    on the same array."""

    def make():
        name, array = training_input(
            modality, a, None if multiple is None else host_arrays.whole_minibatches(len(a), multiple)
        )
        return name, sharding.put(array, to)

    # `a` itself, placed without a copy (`host_arrays`), is not kept: placing it again costs
    # nothing, and the kept value would keep `a` alive past its data set
    KEPT.max_bytes = budget(to)
    return KEPT.get(
        a, (modality, multiple, to), make, keep=lambda placed: not host_arrays.placed_in_place(placed[1], a)
    )


class Placed(NamedTuple):
    """A run's data as training reads it (`place_sets`)."""

    sets: dict[str, Any]  # {"train", "val", "eval": {name: set}}, each as `select` and `place_input` leave it
    sizes: dict[str, int]  # the sequences of every set but the training set, before padding to whole minibatches
    shapes: tuple[tuple[str, tuple[int, ...]], ...]  # (input, per-step shape) the model is built for, sorted
    from_host: bool  # the sets stay on the host, fed a block at a time (`reads_from_host`)
    training_set: Any  # the training set as given: its input statistics, classes and data identity

    @property
    def n_train(self) -> int:
        return int(jax.tree.leaves(self.sets["train"]["labels"])[0].shape[0])


def place_sets(config: Config, data_sets: Mapping[str, Any], to: NamedSharding | None = None) -> Placed:
    """`data_sets` ({"train", "val" and any evaluation sets}) as a run of `config` reads them, on
    `to`'s devices (default: every device of the training mesh holds them whole, like the state):
    each set's arrays that the config uses (`select`), in training's layout
    (`inputs.training_input`), evaluation sets padded to whole minibatches, large inputs kept for
    the next run on the same arrays (`place_input`). Every set is laid out, so that training and
    evaluation compile one image path (`FabricNet.image_features`), and once per run, not per
    chunk of its epochs. A run fed from the host (`reads_from_host`) gets its inputs as they are,
    on the host (`feed.HostFeed` pads them a block at a time), its labels padded alike."""
    to = to or sharding.replicated(sharding.training_mesh(config.batch_size))
    train_set = data_sets["train"]
    evals = {k: v for k, v in data_sets.items() if k not in ("train", "val")}
    sets = {k: select(config, v) for k, v in {"train": train_set, "val": data_sets["val"], **evals}.items()}
    sizes = {k: len(jax.tree.leaves(v["labels"])[0]) for k, v in sets.items() if k != "train"}
    shapes = tuple(sorted(feature_shapes(sets["train"]["inputs"]).items()))
    from_host = reads_from_host(config, train_set)
    sets = {k: _as_read(v, None if k == "train" else config.batch_size, to, from_host) for k, v in sets.items()}
    return Placed(
        {"train": sets.pop("train"), "val": sets.pop("val"), "eval": sets}, sizes, shapes, from_host, train_set
    )


def _as_read(ds, multiple: int | None, to: NamedSharding, from_host: bool) -> dict[str, dict[str, Any]]:
    """A `select`ed set as a run reads it: its labels padded to whole minibatches of `multiple`
    (None: as they are, the training set), its inputs on `to`'s devices (`place_input`) with its
    labels, or where the run is fed from the host, both on the host."""
    labels = {
        h: a if multiple is None else host_arrays.padded(a, host_arrays.whole_minibatches(len(a), multiple), -1)
        for h, a in ds["labels"].items()
    }
    if from_host:
        return {"inputs": ds["inputs"], "labels": labels}
    inputs = dict(place_input(a, m, multiple, to) for m, a in ds["inputs"].items())
    return {"inputs": inputs, "labels": sharding.put(labels, to)}
