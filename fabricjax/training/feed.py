"""Training fed from the host: minibatches read from host arrays (memory-mapped sequence files,
`data.load_sequences`) a block of steps at a time, for inputs larger than memory.

`train.train_and_evaluate` places a set on the devices and runs whole epochs there
(`Trainer.run`) when it fits. When it does not (`placement.reads_from_host`: `Config.input_source`
"disk", or "auto" and the loaded inputs are memory-mapped files) it runs the same epochs from here:

  * each epoch's order is `Trainer.epoch_order`'s, computed on the devices from the same key;
  * the host gathers each block of steps' sequences for every seed (each seed reads its own
    shuffle) from the arrays, lays frames out as rows (`inputs.training_layout`) and places the
    block; the devices run its steps in a scan of `Trainer.train_step`, the step the device-
    resident epoch runs. JAX dispatches asynchronously, so the next block is read while the
    devices train on this one;
  * validation and evaluation read their sets a block of minibatches at a time
    (`Trainer.predict`), padded as `host_arrays.whole_minibatches` pads them.

The parameters are the device-resident run's, bit for bit (tests/test_feed.py). The host holds
about two blocks at a time, each `BLOCK_BYTES` or one step's minibatches where that is more
(`host_bytes`), whatever the size of the data.
"""

from __future__ import annotations

from typing import Any, Mapping

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


class HostFed:
    """`Trainer.run` and `Trainer.finish` with the sets on the host: the same signatures, run a
    block at a time (see the module docstring). `sets` are `placement.select`ed host sets."""

    def __init__(self, trainer, per_seed: NamedSharding):
        self.trainer, self.per_seed = trainer, per_seed
        self._plan = jax.jit(
            sharding.vmap_seeds(
                lambda key, epoch, n: trainer.epoch_order(jax.random.fold_in(key, epoch), n), in_axes=(0, None, None)
            ),
            static_argnums=2,
        )

        # a stopped seed's carry passes through unchanged (`Trainer.unless_stopped`)
        def scan(carry, block, keys, stopped_at):
            def step(c, xs):
                new, out = trainer.train_step(c, *xs)
                return trainer.unless_stopped(stopped_at, new, c), out

            return jax.lax.scan(step, carry, (block, keys))

        self._steps = jax.jit(sharding.vmap_seeds(scan), donate_argnums=0)
        self._summary = jax.jit(sharding.vmap_seeds(trainer.epoch_summary, in_axes=(0, 0, None)))
        self._predict = jax.jit(sharding.vmap_seeds(trainer.predict, in_axes=(0, None)))
        self._end_epoch = jax.jit(sharding.vmap_seeds(trainer.end_epoch))

    def _place(self, tree):
        return sharding.put(tree, self.per_seed)

    def run(self, state: dict[str, Any], data: Mapping[str, Any], n_epochs: int):
        """`n_epochs` more epochs: (state, per-epoch summary) as `Trainer.run` gives them."""
        train = data["train"]
        n = len(next(iter(train["labels"].values())))
        n_seeds = len(state["best_val"])
        outputs = []
        for _ in range(n_epochs):
            epoch = jnp.int32(jax.device_get(state["epoch"])[0])  # every seed is at the same epoch
            order, keys = self._plan(state["key"], epoch, n)
            order = np.asarray(order)
            k = block_steps(train["inputs"], order.shape[2], n_seeds, order.shape[1])
            carry, losses, counts = (state["params"], state["opt_state"]), [], []
            for start in range(0, order.shape[1], k):
                rows = order[:, start : start + k]  # (seeds, steps, batch)
                block = {
                    "inputs": {
                        m: a.reshape(*rows.shape, *a.shape[1:])
                        for m, a in _laid_out(train["inputs"], rows.reshape(-1)).items()
                    },
                    "labels": {h: a[rows] for h, a in train["labels"].items()},
                }
                carry, (loss, count) = self._steps(
                    carry, self._place(block), keys[:, start : start + k], state["stopped_at"]
                )
                losses.append(loss)
                counts.append(count)
            losses, counts = (
                jax.tree.map(lambda *xs: jnp.concatenate(xs, axis=1), *parts) for parts in (losses, counts)
            )
            summary = self._summary(losses, counts, epoch)
            validation = self.evaluate(carry[0], data["val"])
            rest = {k: v for k, v in state.items() if k not in ("params", "opt_state")}
            state = self._end_epoch(rest, *carry, summary["train_loss"], validation)
            outputs.append(
                {**summary, "val_accuracy": validation["accuracy"], "val_predictions": validation["predictions"]}
            )
        return state, jax.tree.map(lambda *xs: jnp.stack(xs, axis=1), *outputs)

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

    def finish(self, state: dict[str, Any], sets: Mapping[str, Any]) -> dict[str, Any]:
        """`Trainer.finish`: the curves and the best-validation model on every set of `sets`."""
        return self.trainer.finished(
            state, {name: self.evaluate(state["best_params"], ds) for name, ds in sets.items()}
        )
