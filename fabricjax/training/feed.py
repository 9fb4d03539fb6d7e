"""Training fed from the host: minibatches read from host arrays (memory-mapped sequence files,
`data.load_sequences`) a block of steps at a time, for inputs larger than memory.

`train.train_and_evaluate` places a set on the devices and runs whole epochs there when it fits.
When it does not (`placement.reads_from_host`: `Config.input_source` "disk", or "auto" and the
loaded inputs are memory-mapped files) the same epoch (`Trainer.epoch`) reads its sets through
`HostFeed`:

  * each epoch's order is `Trainer.epoch_order`'s, computed on the devices from the same key;
  * the host gathers each block of steps' sequences for every seed (each seed reads its own
    shuffle) from the arrays, lays frames out as rows (`inputs.training_layout`) and places the
    block; the devices run its steps in a scan of `Trainer.train_step`, the step the device-
    resident epoch runs. JAX dispatches asynchronously, so the next block is read while the
    devices train on this one;
  * validation and evaluation read their sets a block of minibatches at a time
    (`Trainer.predict`), padded as `host_arrays.whole_minibatches` pads them;
  * the epoch's other pieces (`Trainer.epoch_summary`, `Trainer.end_epoch`) run as programs of
    their own, vmapped over the seeds (`HostFeed.per_seed`).

The computation is the device-resident run's; compiled without XLA's fusions, as the tests compile,
the parameters are its bits (tests/test_feed.py). The host holds about two blocks at a time, each
`BLOCK_BYTES` or one step's minibatches where that is more (`host_bytes`), whatever the size of the
data.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

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
    """The `train.Feed` of a run's sets on the host (`placement.select`ed), read a block at a time
    (see the module docstring), so that `Trainer.run` is the run's epochs wherever its sets are."""

    def __init__(self, trainer, per_seed: NamedSharding):
        self.trainer, self.per_seed_sharding = trainer, per_seed
        self._compiled: dict[Callable, Callable] = {}

        # the carry is donated a block at a time, so a stopped seed's carry passes through each
        # step unchanged (`Trainer.unless_stopped`)
        def scan(carry, block, keys, stopped_at):
            def step(c, xs):
                new, out = trainer.train_step(c, *xs)
                return trainer.unless_stopped(stopped_at, new, c), out

            return jax.lax.scan(step, carry, (block, keys))

        self._steps = jax.jit(sharding.vmap_seeds(scan), donate_argnums=0)
        self._predict = jax.jit(sharding.vmap_seeds(trainer.predict, in_axes=(0, None)))

    def per_seed(self, fn: Callable) -> Callable:
        """`fn`, written for one seed, jitted and vmapped over the seeds (compiled once)."""
        if fn not in self._compiled:
            self._compiled[fn] = jax.jit(sharding.vmap_seeds(fn))
        return self._compiled[fn]

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

    def train_steps(self, state, order, step_keys, train: Mapping[str, Any]):
        """The epoch's steps over minibatches `order` (seeds, steps, batch) of host set `train`, a
        block of steps at a time (`train.Feed.train_steps`)."""
        order = np.asarray(order)
        n_seeds, steps, batch = order.shape
        k = block_steps(train["inputs"], batch, n_seeds, steps)
        carry, outputs = (state.params, state.opt_state), []
        for start in range(0, steps, k):
            rows = order[:, start : start + k]  # (seeds, steps, batch)
            block = {
                "inputs": {
                    m: a.reshape(*rows.shape, *a.shape[1:])
                    for m, a in _laid_out(train["inputs"], rows.reshape(-1)).items()
                },
                "labels": {h: a[rows] for h, a in train["labels"].items()},
            }
            carry, out = self._steps(carry, self._place(block), step_keys[:, start : start + k], state.stopped_at)
            outputs.append(out)
        params, opt_state = carry
        return state.replace(params=params, opt_state=opt_state), jax.tree.map(
            lambda *xs: jnp.concatenate(xs, axis=1), *outputs
        )

    def evaluate(self, params, ds: Mapping[str, Any]) -> dict[str, dict[str, jax.Array]]:
        """`Trainer.evaluate` of every seed's `params` on host set `ds`, a block of minibatches at a time."""
        batch = self.trainer.config.batch_size
        n = len(next(iter(ds["labels"].values())))
        per_block = batch * _per_block(batch * sequence_bytes(ds["inputs"]))
        preds = []
        for start in range(0, max(n, 1), per_block):
            stop = min(start + per_block, n)
            length = host_arrays.whole_minibatches(stop - start, batch)
            preds.append(self._predict(params, self._place(_laid_out(ds["inputs"], np.arange(start, stop), length))))
        preds = jax.tree.map(lambda *xs: jnp.concatenate(xs, axis=1), *preds)
        labels = {
            h: np.concatenate([a, np.full(host_arrays.whole_minibatches(n, batch) - n, -1, a.dtype)])
            for h, a in ds["labels"].items()
        }
        accuracy = jax.vmap(self.trainer.accuracy, in_axes=(0, None))(preds, labels)
        return {"accuracy": accuracy, "predictions": preds}
