"""The pure pieces of a training run, in the order a run executes them: the trainer of a config
(`make_trainer`) with its optimiser and learning-rate schedule, one seed's state (`TrainState`),
then the `Trainer`'s functions of that state from `init` through an epoch (its minibatches, the
optimiser steps, the loss, the validation and the early stop) to the masked loss and accuracy.

Every function here is written for one seed; `fabricjax.training.train` runs them vmapped over the
seeds, which stay together while each minibatch's samples are split over the devices
(`fabricjax.training.sharding`). An epoch reads its sets through a feed (`fabricjax.training.feed`):
on the devices, where the epochs are a `lax.scan` inside one jitted program, or from the host a
block of minibatches at a time; either way the feed only hands over minibatches, and the steps
(`Trainer.train_steps`) and the evaluation (`Trainer.evaluate`) are the ones here.

A data set is a mapping {"inputs": {modality: (n, N, ...)}, "labels": {head: int (n,)}}; label -1
means unknown and is masked out of losses and accuracies. Every epoch's randomness is
`fold_in(key, epoch)`, so a run resumed from a checkpoint is the uninterrupted run.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

import jax
import jax.numpy as jnp
import optax
from flax import nnx, struct
from jax.sharding import Mesh

from fabricjax.config import Config
from fabricjax.model import FabricNet
from fabricjax.training import sharding
from fabricjax.training.feed import Feed


def make_trainer(
    config: Config,
    shapes: Mapping[str, tuple[int, ...]],
    mesh: Mesh | None = None,
    n_train: int | None = None,
) -> Trainer:
    """The pieces of a run of `config` on inputs of per-sample `shapes` and `n_train` training
    sequences, which fix the learning-rate schedule's length (None: one minibatch per epoch, for a
    trainer built to initialise, restore or predict, whose optimiser never steps)."""
    shapes = {m: tuple(shapes[m]) for m in config.modalities}
    graphdef = nnx.split(nnx.eval_shape(lambda: FabricNet(config, shapes, rngs=nnx.Rngs(0))))[0]
    n_train = config.batch_size if n_train is None else n_train
    return Trainer(config, shapes, graphdef, make_optimizer(config, total_steps(config, n_train)), n_train, mesh)


def minibatch_size(batch_size: int, n_train: int) -> int:
    """The samples of a training minibatch: `batch_size`, or every sequence where there are fewer."""
    return min(batch_size, n_train)


def steps_per_epoch(batch_size: int, n_train: int) -> int:
    """Optimiser steps of an epoch on `n_train` (at least 1) training sequences: whole minibatches,
    the remainder dropped."""
    return n_train // minibatch_size(batch_size, n_train)


def total_steps(config: Config, n_train: int) -> int:
    """Optimiser steps of a whole run on `n_train` training sequences."""
    return config.epochs * steps_per_epoch(config.batch_size, n_train)


def make_optimizer(config: Config, total_steps: int) -> optax.GradientTransformation:
    """The whole learning-rate schedule lives here, counted by optax's own step counters: a
    global-norm clip at 1.0, AdamW with the warm-up (`warmup_schedule`; weight decay on weight
    matrices only), then the decay over `total_steps` (`decay_schedule`) scaling AdamW's step.

    AdamW is `optax.adamw`'s own chain, with the clip and Adam's moments on all parameters as one
    flat vector (`optax.flatten`): a few kernels a step instead of some for every parameter array,
    each of which XLA would compile on its own."""
    decay_mask = lambda params: jax.tree.map(lambda p: p.ndim > 1, params)  # noqa: E731
    chain = [
        optax.flatten(optax.chain(optax.clip_by_global_norm(1.0), optax.scale_by_adam())),
        optax.add_decayed_weights(config.weight_decay, decay_mask),
        optax.scale_by_learning_rate(warmup_schedule(config)),
    ]
    decay = decay_schedule(config, total_steps)
    if decay is not None:
        chain.append(optax.scale_by_schedule(decay))
    return optax.chain(*chain)


def warmup_schedule(config: Config) -> optax.ScalarOrSchedule:
    """AdamW's learning rate: a linear warm-up to `config.learning_rate`, or constant."""
    if config.warmup_steps > 0:
        return optax.linear_schedule(0.0, config.learning_rate, config.warmup_steps)
    return config.learning_rate


def decay_schedule(config: Config, total_steps: int) -> optax.Schedule | None:
    """The factor on AdamW's step over the run, after its warm-up: none for "constant", a cosine
    from 1 to 0 over `total_steps` for "cosine" (short runs on a large dataset end in a low-noise
    phase instead of stopping at full step size)."""
    if config.lr_schedule == "constant":
        return None
    return lambda step: 0.5 * (1.0 + jnp.cos(jnp.pi * jnp.minimum(step / max(total_steps, 1), 1.0))).astype(jnp.float32)


def learning_rate(config: Config, total_steps: int, step: jax.Array) -> jax.Array:
    """The learning rate at `step` that `make_optimizer` applies: warm-up times decay."""
    warmup, decay = warmup_schedule(config), decay_schedule(config, total_steps)
    lr = warmup(step) if callable(warmup) else jnp.float32(warmup)
    return lr if decay is None else lr * decay(step)


def seed_keys(seeds: Sequence[int]) -> jax.Array:
    """The runs' keys, one per seed value (stacked: `Trainer.init` vmapped over them)."""
    return jnp.stack([jax.random.PRNGKey(int(s)) for s in seeds])


@struct.dataclass
class TrainState:
    """One seed's run between epochs; stacked over seeds, every leaf has a leading seed axis."""

    params: Any
    opt_state: Any
    key: jax.Array  # the run's: epoch e's randomness is fold_in(key, e)
    epoch: jax.Array  # epochs trained
    best_params: Any  # the parameters of the best validation epoch so far: the seed's result
    best_val: jax.Array  # their validation accuracy (`Trainer.selection_metric`), -1 before the first epoch
    best_epoch: jax.Array
    stopped_at: jax.Array  # the epoch the seed stopped early at (`Trainer.end_epoch`), -1 while it trains
    history: EpochHistory


@struct.dataclass
class EpochHistory:
    """Each epoch's training loss and validation accuracy (`Trainer.selection_metric`), (epochs,)
    each, 0 for the epochs not trained: written into the state so that they leave the devices,
    and are saved, with it."""

    train_loss: jax.Array
    val_acc: jax.Array


@dataclasses.dataclass(frozen=True)
class Trainer:
    """The pure pieces of a run, each a function of one seed's state, and the one epoch they make
    (`epoch`), which reads its sets through a feed (`fabricjax.training.feed`)."""

    config: Config
    shapes: dict[str, tuple[int, ...]]
    graphdef: Any
    tx: optax.GradientTransformation
    n_train: int  # training sequences: an epoch's minibatches and the learning-rate schedule's length
    mesh: Mesh | None = None  # splits minibatch samples over its "batch" devices (`sharding.split_samples`)

    def init(self, key: jax.Array) -> TrainState:
        k_params, k_run = jax.random.split(key)
        params = nnx.to_pure_dict(nnx.state(FabricNet(self.config, self.shapes, rngs=nnx.Rngs(k_params))))
        zeros = jnp.zeros(self.config.epochs, jnp.float32)
        return TrainState(
            params=params,
            opt_state=self.tx.init(params),
            key=k_run,
            epoch=jnp.int32(0),
            best_params=params,
            best_val=jnp.float32(-1.0),
            best_epoch=jnp.int32(-1),
            stopped_at=jnp.int32(-1),
            history=EpochHistory(train_loss=zeros, val_acc=zeros),
        )

    def run(self, state: TrainState, sets: Mapping[str, Any], feed: Feed, n_epochs: int):
        """`n_epochs` more epochs (`epoch`): (state, their curves, each with a leading epoch axis)."""
        return feed.repeat(lambda s: self.epoch(s, sets, feed), state, n_epochs)

    def epoch(self, state: TrainState, sets: Mapping[str, Any], feed: Feed):
        """One epoch of the run: (state, its curves). It trains (`train_epoch`), evaluates the
        validation set (`evaluate`) and keeps the best-validation parameters (`end_epoch`). `sets`
        ({"train", "val", ...}, as `placement.place_sets` gives them) are read through `feed`:
        on the devices inside one jitted program, or from the host a block at a time; whichever
        it is, this is the run's epoch."""
        state, summary = self.train_epoch(state, sets["train"], feed)
        validation = self.evaluate(state.params, sets["val"], feed)
        return feed.per_seed(self.end_epoch)(state, summary, validation)

    def train_epoch(self, state: TrainState, train: Mapping[str, Any], feed: Feed):
        """One pass over the training set in shuffled minibatches (`epoch_order`), their optimiser
        steps (`train_steps`) run on the blocks `feed` hands over: (state with the new parameters
        and optimiser state, `epoch_summary`). A stopped seed's parameters and optimiser state stay
        as they were before the epoch (`unless_stopped`)."""
        order, step_keys = feed.per_seed(self.epoch_order)(state.key, state.epoch)
        before = (state.params, state.opt_state)
        trained, steps = feed.train(self.train_steps, before, order, step_keys, train)
        params, opt_state = feed.per_seed(self.unless_stopped)(state.stopped_at, trained, before)
        state = state.replace(params=params, opt_state=opt_state)
        return state, feed.per_seed(self.epoch_summary)(steps, state.epoch)

    def epoch_order(self, key, epoch) -> tuple[jax.Array, jax.Array]:
        """Epoch `epoch`'s minibatches over the `n_train` training sequences, from the run's key:
        (indices (steps, batch): a permutation, the remainder dropped; each step's key (steps, 2)).
        Its randomness is `fold_in(key, epoch)`, so a resumed run draws what the uninterrupted
        one drew."""
        batch = minibatch_size(self.config.batch_size, self.n_train)
        steps = steps_per_epoch(self.config.batch_size, self.n_train)
        k_perm, k_steps = jax.random.split(jax.random.fold_in(key, epoch))
        return jax.random.permutation(k_perm, self.n_train)[: steps * batch].reshape(steps, batch), jax.random.split(
            k_steps, steps
        )

    def train_steps(self, carry, rows, step_keys, source):
        """The optimiser steps (`train_step`) of a block of minibatches, in a scan: step i trains
        on minibatch `source[rows[i]]` with key `step_keys[i]`. Returns (carry, the steps' outputs
        stacked). On the devices `rows` are the epoch's order (steps, batch) into the training
        set; fed from the host, the indices (steps,) of a block's minibatches, gathered in order."""

        def step(carry, xs):
            idx, k = xs
            return self.train_step(carry, jax.tree.map(lambda a: a[idx], source), k)

        return jax.lax.scan(step, carry, (rows, step_keys))

    def train_step(self, carry, mb, key):
        """One optimiser step on minibatch `mb`: ((params, opt_state), (loss, right and known
        labels per head))."""
        params, opt_state = carry
        mb = sharding.split_samples(mb, self.mesh)
        (loss, logits), grads = jax.value_and_grad(self.loss, has_aux=True)(params, mb, key)
        updates, opt_state = self.tx.update(grads, opt_state, params)
        return (optax.apply_updates(params, updates), opt_state), (loss, _correct_and_known(logits, mb["labels"]))

    def loss(self, params, batch, key) -> tuple[jax.Array, dict[str, jax.Array]]:
        """(summed loss over heads, the logits): the logits give the epoch's training accuracy
        without a second forward pass."""
        logits = self.logits(params, batch["inputs"], key)
        return sum(masked_cross_entropy(logits[h], batch["labels"][h]) for h in logits), logits

    def logits(self, params, inputs, key=None) -> dict[str, jax.Array]:
        """Logits per head; with `key` in training mode: dropout and the model's own augmentation
        (the image rotation) on, each from its own stream."""
        model = nnx.merge(self.graphdef, params)
        if key is None:
            return model(inputs)
        k_augment, k_dropout = jax.random.split(key)
        return model(inputs, rngs=nnx.Rngs(dropout=k_dropout, augment=k_augment))

    @staticmethod
    def unless_stopped(stopped_at, new, old):
        """`new` (what training made of `old`: parameters, optimiser state), or `old` where the
        seed has stopped (`stopped_at` >= 0, `end_epoch`): a stopped seed's parameters no longer
        change, while the seeds beside it in the vmapped program train on."""
        return jax.tree.map(lambda a, b: jnp.where(stopped_at >= 0, b, a), new, old)

    def epoch_summary(self, steps, epoch) -> dict[str, Any]:
        """An epoch's mean loss, its training accuracy per head over the minibatches as they were
        trained (dropout and augmentation on, parameters changing) and the learning rate of its
        last step, from its steps' outputs (`train_step`'s, stacked)."""
        losses, counts = steps
        n = losses.shape[0]
        return {
            "train_loss": losses.mean(),
            "train_accuracy": {h: right.sum() / jnp.maximum(known.sum(), 1) for h, (right, known) in counts.items()},
            "lr": learning_rate(self.config, total_steps(self.config, self.n_train), epoch * n + n - 1),
        }

    def evaluate(self, params, ds, feed: Feed) -> dict[str, dict[str, jax.Array]]:
        """Predictions (`predict`, on the blocks `feed` hands over) and accuracy per head of
        `params` over set `ds`, padded to whole minibatches (`placement.place_sets`)."""
        preds = feed.predict(self.predict, params, ds["inputs"])
        return {"accuracy": feed.per_seed(self.accuracy, in_axes=(0, None))(preds, ds["labels"]), "predictions": preds}

    def predict(self, params, inputs) -> dict[str, jax.Array]:
        """Predicted class per head of inputs padded to whole minibatches, a minibatch at a time."""
        model = nnx.merge(self.graphdef, params)
        batch = self.config.batch_size
        chunks = sharding.split_samples(
            jax.tree.map(lambda a: a.reshape(-1, batch, *a.shape[1:]), inputs), self.mesh, axis=1
        )
        return {h: jnp.argmax(v, -1).reshape(-1).astype(jnp.int32) for h, v in jax.lax.map(model, chunks).items()}

    @staticmethod
    def accuracy(predictions: Mapping[str, jax.Array], labels: Mapping[str, jax.Array]) -> dict[str, jax.Array]:
        return {h: masked_accuracy(p, labels[h]) for h, p in predictions.items()}

    def end_epoch(self, state, summary, validation):
        """(the state after an epoch that trained it to `summary` (`epoch_summary`'s) and
        `validation` (`evaluate`'s on the validation set), the epoch's curves). The best-validation
        parameters are kept and the seed stops once `config.patience` epochs have passed without
        a better validation accuracy (early stopping; the seed's best-validation parameters are
        its result). The curves are `summary` with the validation accuracy and predictions per
        head ("val_accuracy", "val_predictions"; the best epoch's predictions are the validation
        results, see `train.BestEpochValidation`)."""
        e = state.epoch
        val = self.selection_metric(validation["accuracy"])
        better = val > state.best_val
        best_epoch = jnp.where(better, e, state.best_epoch)
        patience = self.config.patience
        stop = (state.stopped_at < 0) & (patience > 0) & (e - best_epoch >= patience)
        return state.replace(
            best_params=jax.tree.map(lambda a, b: jnp.where(better, a, b), state.params, state.best_params),
            best_val=jnp.where(better, val, state.best_val),
            best_epoch=best_epoch,
            stopped_at=jnp.where(stop, e, state.stopped_at),
            epoch=e + 1,
            history=EpochHistory(
                train_loss=state.history.train_loss.at[e].set(summary["train_loss"]),
                val_acc=state.history.val_acc.at[e].set(val),
            ),
        ), {**summary, "val_accuracy": validation["accuracy"], "val_predictions": validation["predictions"]}

    def selection_metric(self, accuracy: dict[str, jax.Array]) -> jax.Array:
        """Validation accuracy used to pick the best epoch: fabric if trained, else mean over properties."""
        if "fabric" in accuracy:
            return accuracy["fabric"]
        return sum(accuracy.values()) / len(accuracy)

    def evaluate_sets(self, params, sets: Mapping[str, Any], feed: Feed) -> dict[str, dict[str, jax.Array]]:
        """`evaluate`'s of `params` on every set of `sets` ({name: set}), read through `feed`."""
        return {name: self.evaluate(params, ds, feed) for name, ds in sets.items()}


def masked_cross_entropy(logits: jax.Array, labels: jax.Array) -> jax.Array:
    """Mean cross-entropy over known labels; -1 (unknown) and labels beyond the head are ignored."""
    valid = (labels >= 0) & (labels < logits.shape[-1])
    ce = optax.softmax_cross_entropy_with_integer_labels(logits, jnp.maximum(labels, 0))
    return jnp.where(valid, ce, 0.0).sum() / jnp.maximum(valid.sum(), 1)


def masked_accuracy(predictions: jax.Array, labels: jax.Array) -> jax.Array:
    valid = labels >= 0
    return ((predictions == labels) & valid).sum() / jnp.maximum(valid.sum(), 1)


def _correct_and_known(
    logits: dict[str, jax.Array], labels: dict[str, jax.Array]
) -> dict[str, tuple[jax.Array, jax.Array]]:
    """Per head, (right predictions, known labels) of a minibatch: summed over an epoch, the
    counts give its training accuracy as `masked_accuracy` counts it."""
    return {
        h: (((jnp.argmax(v, -1) == labels[h]) & (labels[h] >= 0)).sum(), (labels[h] >= 0).sum())
        for h, v in logits.items()
    }
