"""Where an epoch (`trainer.Trainer.epoch`) reads its sets: the `Feed`s, which only hand over
blocks of minibatches to the trainer's one step body (`Trainer.train_steps`) and one evaluation
(`Trainer.predict`, then `Trainer.accuracy`).

`DeviceFeed` reads sets placed on the devices (`placement.place_sets`) inside the one jitted,
seed-vmapped program of a run: an epoch's minibatches are one block, indexed by the epoch's order
into the training set, and the epochs are a `lax.scan`.

`HostFeed` reads sets kept on the host (memory-mapped sequence files, `data.load_sequences`) a
block of steps at a time, for inputs larger than memory (`placement.reads_from_host`:
`Config.input_source` "disk", or "auto" and the loaded inputs are memory-mapped files):

  * each epoch's order is `Trainer.epoch_order`'s, computed on the devices from the same key;
  * the host gathers each block of steps' sequences for every seed (each seed reads its own
    shuffle) from the arrays, lays frames out as rows (`inputs.training_layout`) and places the
    block; the devices run its steps (`Trainer.train_steps`). JAX dispatches asynchronously, so
    the next block is read while the devices train on this one;
  * validation and evaluation read their sets a block of minibatches at a time
    (`Trainer.predict`), padded as `host_arrays.whole_minibatches` pads them;
  * the epoch's other pieces (`Trainer.epoch_summary`, `Trainer.end_epoch`, ...) run as programs
    of their own, vmapped over the seeds (`HostFeed.per_seed`).

The computation is the device-resident run's; compiled without XLA's fusions, as the tests compile,
the parameters are its bits (tests/test_feed.py). The host holds about two blocks at a time, each
`BLOCK_BYTES` or one step's minibatches where that is more (`host_bytes`), whatever the size of the
data.
"""

from __future__ import annotations

from typing import Any, Callable, Iterable, Mapping, Protocol

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import NamedSharding

from fabricjax import host_arrays
from fabricjax.sequences.inputs import training_input
from fabricjax.training import sharding

# What one placed block of training steps (all seeds' minibatches) or of evaluation minibatches
# holds at most, unless one step's minibatches alone hold more.
BLOCK_BYTES = 64 << 20


class Feed(Protocol):
    """How an epoch's pieces, each written for one seed, run on the seeds, and how its sets'
    minibatches reach them: `DeviceFeed` inside one jitted, seed-vmapped program, `HostFeed` from
    the host."""

    def per_seed(self, fn: Callable, in_axes: Any = 0) -> Callable:
        """`fn`, written for one seed, as it runs on this feed's seeds (`in_axes` as `jax.vmap`'s:
        None for an argument every seed shares)."""

    def repeat(self, epoch: Callable, state: Any, n: int) -> tuple[Any, Any]:
        """`epoch` (state to (state, outputs)) `n` times: (state, the epochs' outputs stacked)."""

    def train(self, steps: Callable, carry: Any, order: Any, step_keys: Any, train: Mapping[str, Any]):
        """`steps` (`Trainer.train_steps`) over the epoch's minibatches `order` of set `train`, a
        block at a time: (carry, the steps' outputs in order)."""

    def predict(self, predict: Callable, params: Any, inputs: Mapping[str, Any]) -> dict[str, Any]:
        """`predict` (`Trainer.predict`) of `params` on every sequence of `inputs`, a block of
        minibatches at a time, padded to whole minibatches."""


class DeviceFeed:
    """The `Feed` of a run's sets on the devices, inside the one jitted, seed-vmapped program that
    runs `Trainer.run`: code written for one seed runs as it is, the epoch's minibatches are one
    block, and the epochs are a `lax.scan`."""

    @staticmethod
    def per_seed(fn, in_axes=0):
        return fn

    @staticmethod
    def repeat(epoch, state, n: int):
        return jax.lax.scan(lambda s, _: epoch(s), state, length=n)

    @staticmethod
    def train(steps, carry, order, step_keys, train):
        return steps(carry, order, step_keys, train)

    @staticmethod
    def predict(predict, params, inputs):
        return predict(params, inputs)


def sequence_bytes(inputs: Mapping[str, np.ndarray]) -> int:
    """Bytes of one sequence of every input."""
    return sum(a[0].nbytes for a in inputs.values())


def _per_block(unit_bytes: int) -> int:
    """Units (training steps, evaluation minibatches) of `unit_bytes` a block holds: as many as
    `BLOCK_BYTES` holds, at least one."""
    return max(1, BLOCK_BYTES // max(unit_bytes, 1))


def block_steps(inputs: Mapping[str, np.ndarray], batch: int, n_seeds: int, steps: int) -> int:
    """Training steps per block (of `steps`), every seed's minibatches in each."""
    return min(steps, _per_block(n_seeds * batch * sequence_bytes(inputs)))


def host_bytes(per_sequence: int, batch: int, n_seeds: int) -> int:
    """Host memory a fed run's blocks hold at once (the one the devices read and the next), for
    sequences of `per_sequence` bytes (`sequence_bytes`)."""
    one_step = n_seeds * batch * per_sequence
    return 2 * _per_block(one_step) * one_step


def _laid_out(inputs: Mapping[str, np.ndarray], rows: np.ndarray, length: int | None = None) -> dict[str, np.ndarray]:
    """Sequences `rows` of every input, in training's layout, padded with zeros to `length`: in
    arrays CPU devices read without a copy (`host_arrays`)."""
    out = {}
    for m, a in inputs.items():
        block = host_arrays.empty((len(rows) if length is None else length, *a.shape[1:]), a.dtype)
        np.take(a, rows, axis=0, out=block[: len(rows)])
        out.update([training_input(m, block)])
    return out


class HostFeed:
    """The `Feed` of a run's sets on the host (`placement.place_sets` leaves them there), read a
    block at a time (see the module docstring) and placed on `per_seed`'s devices, so that
    `Trainer.run` is the run's epochs wherever its sets are. Evaluation sets run in whole
    minibatches of `batch_size`."""

    def __init__(self, batch_size: int, per_seed: NamedSharding):
        self.batch_size, self.per_seed_sharding = batch_size, per_seed
        self._compiled: dict[tuple[Callable, Any], Callable] = {}

    def per_seed(self, fn: Callable, in_axes: Any = 0) -> Callable:
        """`fn`, written for one seed, jitted and vmapped over the seeds (compiled once)."""
        if (fn, in_axes) not in self._compiled:
            self._compiled[fn, in_axes] = jax.jit(sharding.vmap_seeds(fn, in_axes=in_axes))
        return self._compiled[fn, in_axes]

    @staticmethod
    def repeat(epoch, state, n: int):
        """`epoch` `n` times: (state, the epochs' outputs stacked on the axis after the seeds')."""
        outputs = []
        for _ in range(n):
            state, out = epoch(state)
            outputs.append(out)
        return state, jax.tree.map(lambda *xs: jnp.stack(xs, axis=1), *outputs)

    def _place(self, tree):
        return sharding.put(tree, self.per_seed_sharding)

    def train(self, steps, carry, order, step_keys, train: Mapping[str, Any]):
        """`steps` over minibatches `order` (seeds, steps, batch) of host set `train`, a block of
        steps at a time, each block's minibatches gathered in order (`Feed.train`)."""
        order = np.asarray(order)
        n_seeds, n_steps, batch = order.shape
        k = block_steps(train["inputs"], batch, n_seeds, n_steps)
        run = self.per_seed(steps, in_axes=(0, None, 0, 0))
        outputs = []
        for start in range(0, n_steps, k):
            rows = order[:, start : start + k]  # (seeds, steps, batch)
            block = {
                "inputs": {
                    m: a.reshape(*rows.shape, *a.shape[1:])
                    for m, a in _laid_out(train["inputs"], rows.reshape(-1)).items()
                },
                "labels": {h: a[rows] for h, a in train["labels"].items()},
            }
            carry, out = run(carry, np.arange(rows.shape[1]), step_keys[:, start : start + k], self._place(block))
            outputs.append(out)
        return carry, _joined(outputs)

    def predict(self, predict, params, inputs: Mapping[str, Any]) -> dict[str, jax.Array]:
        """`predict` of every seed's `params` on host inputs, a block of minibatches at a time
        (`Feed.predict`)."""
        batch = self.batch_size
        n = len(next(iter(inputs.values())))
        per_block = batch * _per_block(batch * sequence_bytes(inputs))
        run = self.per_seed(predict, in_axes=(0, None))
        preds = []
        for start in range(0, max(n, 1), per_block):
            stop = min(start + per_block, n)
            length = host_arrays.whole_minibatches(stop - start, batch)
            preds.append(run(params, self._place(_laid_out(inputs, np.arange(start, stop), length))))
        return _joined(preds)


def _joined(blocks: Iterable[Any]):
    """The blocks' outputs (a leading seed axis) as one, in order along the axis after the seeds'."""
    return jax.tree.map(lambda *xs: jnp.concatenate(xs, axis=1), *blocks)
