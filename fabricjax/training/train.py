"""Pure, jitted multi-seed training with one entry point, `train_and_evaluate`: the optimiser, the
`Trainer` (a run as pure functions of one seed's state, and the one epoch they make), its compiled
programs and the loop over chunks of epochs.

`Trainer.init`, `Trainer.run` and `Trainer.evaluate_sets` are each `jax.jit(jax.vmap(...))`ed over
the seeds, which stay together while each minibatch's samples are split over the devices
(`fabricjax.training.sharding`). An epoch and the epochs of a chunk are `lax.scan`s, so training
runs without the host, which reads back each chunk's curves. The epoch (`Trainer.epoch`) reads its
sets through a feed: on the devices (`DeviceFeed`), or from the host a block of steps at a time
for inputs larger than memory (`fabricjax.training.feed.HostFeed`, which compiles the epoch's
pieces one by one). Where the inputs live is `fabricjax.training.placement`'s.

A data set is a mapping {"inputs": {modality: (n, N, ...)}, "labels": {head: int (n,)}} (objects
with `.inputs` / `.labels` work too); label -1 means unknown and is masked out of losses and
accuracies. Every epoch's randomness is `fold_in(key, epoch)`, so a run resumed from a checkpoint
is the uninterrupted run.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import time
from typing import Any, Callable, Mapping, NamedTuple, Protocol, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import nnx, struct
from jax.sharding import Mesh, NamedSharding

from fabricjax import runtime
from fabricjax.config import Config
from fabricjax.model import FabricNet
from fabricjax.sequences.inputs import input_statistics, with_input_statistics
from fabricjax.training import checkpoint, curves, feed, sharding
from fabricjax.training.placement import Placed, place_sets


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


def total_steps(config: Config, n_train: int) -> int:
    """Optimiser steps of a whole run on `n_train` training sequences (the remainder batch dropped)."""
    return config.epochs * (n_train // min(config.batch_size, n_train))


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


@struct.dataclass
class EpochHistory:
    """Each epoch's training loss and validation accuracy (`Trainer.selection_metric`), (epochs,)
    each, 0 for the epochs not trained: written into the state so that they leave the devices,
    and are saved, with it."""

    train_loss: jax.Array
    val_acc: jax.Array


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


class Feed(Protocol):
    """Where the run's epoch (`Trainer.epoch`) reads its sets, and how its pieces, each written for
    one seed, run on the seeds: `DeviceFeed` inside one jitted, seed-vmapped program, or
    `feed.HostFeed` from the host."""

    def per_seed(self, fn: Callable) -> Callable:
        """`fn`, written for one seed, as it runs on this feed's seeds."""

    def repeat(self, epoch: Callable, state: TrainState, n: int) -> tuple[TrainState, Any]:
        """`epoch` (state to (state, outputs)) `n` times: (state, the epochs' outputs stacked)."""

    def train_steps(self, state: TrainState, order, step_keys, train) -> tuple[TrainState, Any]:
        """An epoch's optimiser steps (`Trainer.train_step`) over minibatches `order` of set
        `train`: (state with the trained parameters and optimiser state, a stopped seed's as they
        were; the steps' outputs, stacked)."""

    def evaluate(self, params, ds) -> dict[str, dict[str, jax.Array]]:
        """`Trainer.evaluate`'s of `params` on set `ds`."""


@dataclasses.dataclass(frozen=True)
class Trainer:
    """The pure pieces of a run, each a function of one seed's state, and the one epoch they make
    (`epoch`), which reads its sets through a feed (`DeviceFeed`, `feed.HostFeed`)."""

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
        validation set and keeps the best-validation parameters (`end_epoch`). `sets` ({"train",
        "val", ...}, as `placement.place_sets` gives them) are read through `feed`: on the
        devices inside one jitted program (`DeviceFeed`), or from the host a block at a time
        (`feed.HostFeed`); whichever it is, this is the run's epoch."""
        state, summary = self.train_epoch(state, sets["train"], feed)
        validation = feed.evaluate(state.params, sets["val"])
        return feed.per_seed(self.end_epoch)(state, summary, validation)

    def train_epoch(self, state: TrainState, train: Mapping[str, Any], feed: Feed):
        """One pass over the training set in shuffled minibatches (`epoch_order`, `train_step`):
        (state with the new parameters and optimiser state, `epoch_summary`). A stopped seed's
        parameters stay as they were (`unless_stopped`)."""
        order, step_keys = feed.per_seed(self.epoch_order)(state.key, state.epoch)
        state, steps = feed.train_steps(state, order, step_keys, train)
        return state, feed.per_seed(self.epoch_summary)(steps, state.epoch)

    def epoch_order(self, key, epoch) -> tuple[jax.Array, jax.Array]:
        """Epoch `epoch`'s minibatches over the `n_train` training sequences, from the run's key:
        (indices (steps, batch): a permutation, the remainder dropped; each step's key (steps, 2)).
        Its randomness is `fold_in(key, epoch)`, so a resumed run draws what the uninterrupted
        one drew."""
        batch = min(self.config.batch_size, self.n_train)
        steps = self.n_train // batch
        k_perm, k_steps = jax.random.split(jax.random.fold_in(key, epoch))
        return jax.random.permutation(k_perm, self.n_train)[: steps * batch].reshape(steps, batch), jax.random.split(
            k_steps, steps
        )

    def logits(self, params, inputs, key=None) -> dict[str, jax.Array]:
        """Logits per head; with `key` in training mode: dropout and the model's own augmentation
        (the image rotation) on, each from its own stream."""
        model = nnx.merge(self.graphdef, params)
        if key is None:
            return model(inputs)
        k_augment, k_dropout = jax.random.split(key)
        return model(inputs, rngs=nnx.Rngs(dropout=k_dropout, augment=k_augment))

    def loss(self, params, batch, key) -> tuple[jax.Array, dict[str, jax.Array]]:
        """(summed loss over heads, the logits): the logits give the epoch's training accuracy
        without a second forward pass."""
        logits = self.logits(params, batch["inputs"], key)
        return sum(masked_cross_entropy(logits[h], batch["labels"][h]) for h in logits), logits

    def train_step(self, carry, mb, key):
        """One optimiser step on minibatch `mb`: ((params, opt_state), (loss, right and known
        labels per head))."""
        params, opt_state = carry
        mb = sharding.split_samples(mb, self.mesh)
        (loss, logits), grads = jax.value_and_grad(self.loss, has_aux=True)(params, mb, key)
        updates, opt_state = self.tx.update(grads, opt_state, params)
        return (optax.apply_updates(params, updates), opt_state), (loss, _correct_and_known(logits, mb["labels"]))

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

    def predict(self, params, inputs) -> dict[str, jax.Array]:
        """Predicted class per head of a set padded to whole minibatches (see `pad`), a
        minibatch at a time."""
        model = nnx.merge(self.graphdef, params)
        batch = self.config.batch_size
        chunks = sharding.split_samples(
            jax.tree.map(lambda a: a.reshape(-1, batch, *a.shape[1:]), inputs), self.mesh, axis=1
        )
        return {h: jnp.argmax(v, -1).reshape(-1).astype(jnp.int32) for h, v in jax.lax.map(model, chunks).items()}

    def evaluate(self, params, ds) -> dict[str, dict[str, jax.Array]]:
        """Predictions and accuracy per head over a set padded to whole minibatches (see `pad`)."""
        preds = self.predict(params, ds["inputs"])
        return {"accuracy": self.accuracy(preds, ds["labels"]), "predictions": preds}

    @staticmethod
    def accuracy(predictions: Mapping[str, jax.Array], labels: Mapping[str, jax.Array]) -> dict[str, jax.Array]:
        return {h: masked_accuracy(p, labels[h]) for h, p in predictions.items()}

    def selection_metric(self, accuracy: dict[str, jax.Array]) -> jax.Array:
        """Validation accuracy used to pick the best epoch: fabric if trained, else mean over properties."""
        if "fabric" in accuracy:
            return accuracy["fabric"]
        return sum(accuracy.values()) / len(accuracy)

    def end_epoch(self, state, summary, validation):
        """(the state after an epoch that trained it to `summary` (`epoch_summary`'s) and
        `validation` (`evaluate`'s on the validation set), the epoch's curves). The best-validation
        parameters are kept and the seed stops once `config.patience` epochs have passed without
        a better validation accuracy (early stopping; the seed's best-validation parameters are
        its result). The curves are `summary` with the validation accuracy and predictions per
        head ("val_accuracy", "val_predictions"; the best epoch's predictions are the validation
        results, see `BestEpochValidation`)."""
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

    def evaluate_sets(self, params, sets: Mapping[str, Any], feed: Feed) -> dict[str, dict[str, jax.Array]]:
        """`evaluate`'s of `params` on every set of `sets` ({name: set}), read through `feed`."""
        return {name: feed.evaluate(params, ds) for name, ds in sets.items()}


@dataclasses.dataclass(frozen=True)
class DeviceFeed:
    """The `Feed` of a run's sets on the devices (`placement.place_sets`), read inside the one
    jitted, seed-vmapped program that runs `Trainer.run`: code written for one seed runs as it is,
    and the epochs are a `lax.scan`."""

    trainer: Trainer

    @staticmethod
    def per_seed(fn):
        return fn

    @staticmethod
    def repeat(epoch, state, n: int):
        return jax.lax.scan(lambda s, _: epoch(s), state, length=n)

    def train_steps(self, state, order, step_keys, train):
        """The epoch's steps (`Trainer.train_step`) over minibatches `order` of `train` in a
        scan: (state with the trained parameters and optimiser state, the steps' outputs)."""
        trainer = self.trainer

        def step(carry, xs):
            idx, k = xs
            return trainer.train_step(carry, jax.tree.map(lambda a: a[idx], train), k)

        old = (state.params, state.opt_state)
        new, steps = jax.lax.scan(step, old, (order, step_keys))
        params, opt_state = trainer.unless_stopped(state.stopped_at, new, old)
        return state.replace(params=params, opt_state=opt_state), steps

    def evaluate(self, params, ds):
        return self.trainer.evaluate(params, ds)


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


class BestEpochValidation:
    """Each seed's validation results (predictions and accuracy per head) at its best epoch,
    taken from the epochs a call trains: the epoch scan evaluates the validation set anyway
    (`Trainer.epoch`), so the final evaluation (`_evaluate_best`) evaluates it again only where a
    seed's best epoch came before a resume. Saves a camera row a second pass over its validation frames."""

    def __init__(self, n_seeds: int):
        self.found = np.zeros(n_seeds, bool)
        self.predictions: dict[str, np.ndarray] = {}
        self.accuracy: dict[str, np.ndarray] = {}

    def add(
        self,
        first_epoch: int,
        predictions: Mapping[str, np.ndarray],
        accuracy: Mapping[str, np.ndarray],
        best_epoch: np.ndarray,
    ) -> None:
        """The scan's outputs for epochs `first_epoch`, ... (predictions (seeds, n, samples) and
        accuracy (seeds, n) per head) and each seed's best epoch after them."""
        n = np.shape(next(iter(accuracy.values())))[1]
        for seed in np.flatnonzero((best_epoch >= first_epoch) & (best_epoch < first_epoch + n)):
            i = best_epoch[seed] - first_epoch
            for h, p in predictions.items():
                self.predictions.setdefault(h, np.zeros((len(self.found), p.shape[-1]), p.dtype))[seed] = p[seed, i]
                self.accuracy.setdefault(h, np.zeros(len(self.found), accuracy[h].dtype))[seed] = accuracy[h][seed, i]
            self.found[seed] = True

    def results(self) -> dict[str, dict[str, np.ndarray]] | None:
        """{"accuracy", "predictions"} as `Trainer.evaluate` gives them for every seed, or None
        while a seed's best epoch was not among the epochs added."""
        return {"accuracy": self.accuracy, "predictions": self.predictions} if self.found.all() else None


def unpad(metrics, sizes: Mapping[str, int]):
    """Cut per-sample predictions (last axis) back to each set's real size."""
    return {
        **metrics,
        "eval": {
            k: {**v, "predictions": jax.tree.map(lambda p: p[..., : sizes[k]], v["predictions"])}
            for k, v in metrics["eval"].items()
        },
    }


class Programs(NamedTuple):
    """A run's programs, for where its sets live: `init` (the seeds' keys to their stacked
    states), `epochs(n)` ((state, sets) to n more epochs: `Trainer.run`) and `evaluate`
    ((parameters, sets) to `Trainer.evaluate_sets`). With the sets on the devices each is one
    jitted, seed-vmapped, seed-sharded program (`DeviceFeed`); from the host, `Trainer.run` and
    `Trainer.evaluate_sets` run with `feed.HostFeed`, which compiles their pieces."""

    trainer: Trainer
    init: Callable
    epochs: Callable[[int], Callable]
    evaluate: Callable
    replicated: NamedSharding  # where the states live: whole on every device, like the sets


@functools.lru_cache(maxsize=1)
def _programs(config: Config, shapes: tuple, n_train: int, mesh, from_host: bool) -> Programs:
    """The `Programs` of a run, cached so that reruns of a config (a resume, another data set of
    the same shapes) reuse the compiled programs.

    Only the latest run's: XLA:CPU compiles more slowly the more compiled programs a process holds,
    a study's rows differ in their config, and the persistent compilation cache still serves a
    config that comes back."""
    trainer = make_trainer(config, dict(shapes), mesh, n_train)
    per_seed = sharding.replicated(mesh)
    init = jax.jit(sharding.vmap_seeds(trainer.init), out_shardings=per_seed)
    if from_host:
        host = feed.HostFeed(trainer, per_seed)
        return Programs(
            trainer,
            init,
            lambda n: functools.partial(trainer.run, feed=host, n_epochs=n),
            functools.partial(trainer.evaluate_sets, feed=host),
            per_seed,
        )
    on_devices = DeviceFeed(trainer)
    evaluate = jax.jit(
        sharding.vmap_seeds(functools.partial(trainer.evaluate_sets, feed=on_devices), in_axes=(0, None)),
        out_shardings=per_seed,
    )
    epochs = functools.lru_cache(
        lambda n: jax.jit(
            sharding.vmap_seeds(functools.partial(trainer.run, feed=on_devices, n_epochs=n), in_axes=(0, None)),
            donate_argnums=0,
            out_shardings=per_seed,
        )
    )
    return Programs(trainer, init, epochs, evaluate, per_seed)


@dataclasses.dataclass
class TrainedSeeds:
    """The seeds of a run as `train_and_evaluate` leaves them: their stacked final state (a
    leading seed axis) and their metrics as NumPy arrays."""

    config: Config
    seeds: tuple[int, ...]
    graphdef: Any
    state: TrainState
    metrics: dict[str, Any]

    def params(self, index: int):
        """Best-validation parameters of the `index`-th seed."""
        return checkpoint.select_seed(self.state.best_params, index)

    def model(self, index: int) -> FabricNet:
        return nnx.merge(self.graphdef, self.params(index))


# JAX's events for building a program (tracing, lowering, XLA's compilation), summed over this
# process: `train_and_evaluate` reports its run's share ("compile_s" of its time account).
_BUILD_EVENTS = frozenset(
    f"/jax/core/compile/{e}"
    for e in ("jaxpr_trace_duration", "jaxpr_to_mlir_module_duration", "backend_compile_duration")
)
_build_seconds = [0.0]


def _count_build_time(event: str, duration: float, **_) -> None:
    if event in _BUILD_EVENTS:
        _build_seconds[0] += duration


jax.monitoring.register_event_duration_secs_listener(_count_build_time)


class TimeAccount:
    """Where a run's wall time went, in seconds: placing its inputs ("place_s"), initialising
    (building and running the initialisation, the input statistics) or restoring ("initialise_s"),
    its epochs ("epochs_s", the first with its programs' building), saving ("save_s"), evaluating
    the best epoch's models ("evaluate_s"), and the time any of these spent building programs
    ("compile_s": tracing, lowering and XLA's compilation). Each phase waits for its results, so
    its time is its own; what the phases leave of the run's wall time is bookkeeping (curves
    written, results gathered)."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self._built = _build_seconds[0]

    @contextlib.contextmanager
    def phase(self, name: str):
        start = time.perf_counter()
        yield
        self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start

    def result(self) -> dict[str, float]:
        return {**self.seconds, "compile_s": _build_seconds[0] - self._built}


def stopped(state) -> bool:
    """Whether every seed of a run has stopped early (`Trainer.end_epoch`): its remaining epochs
    would change nothing."""
    return bool(np.all(jax.device_get(state.stopped_at) >= 0))


def seed_keys(seeds: Sequence[int]) -> jax.Array:
    return jnp.stack([jax.random.PRNGKey(int(s)) for s in seeds])


# How often a checkpointed run saves by default: a killed run loses at most this many epochs (a
# row of the paper preset is hours), and a save costs a fraction of an epoch.
SAVE_EVERY_EPOCHS = 2


@dataclasses.dataclass(frozen=True)
class Saves:
    """Where and when a run saves: its state and its curves so far into `mngr` (none: the run saves
    nothing) every `every` epochs and at its end, with `meta` (the run's identity,
    `checkpoint.meta`); `on_save(epoch)` is for the caller to call after each durable save. A
    run's epochs go in chunks that end where a save would, whether it saves or not
    (`chunk_length`)."""

    mngr: Any
    meta: dict[str, Any]
    every: int
    on_save: Callable[[int], None] | None = None

    def exist(self) -> bool:
        return self.mngr is not None and self.mngr.latest_step() is not None

    def latest(self, abstract_state) -> tuple[TrainState, int, dict[str, list] | None]:
        """(state, epochs done, the curves saved with it) of the latest save, its arrays as
        `abstract_state` (`checkpoint.restore`)."""
        state, done = checkpoint.restore(self.mngr, abstract_state, self.meta)
        return state, done, checkpoint.read_meta(self.mngr, done).get("curves")

    def due(self, done: int, epochs: int, state: TrainState) -> bool:
        """Whether a run that has trained `done` of its `epochs` saves now: every `every` epochs, at
        the end, and once every seed has stopped."""
        return self.mngr is not None and (done % self.every == 0 or done == epochs or stopped(state))

    def save(self, done: int, state: TrainState, history: curves.History) -> None:
        checkpoint.save(self.mngr, done, state, {**self.meta, "curves": history.to_json()})


def chunk_length(config: Config, done: int, save_every: int, epoch_per_call: bool) -> int:
    """Epochs the next call of `Programs.epochs` trains, after `done`: up to the next save and at
    most `config.patience`, so that a chunk ends at most `patience` epochs after a seed could have
    stopped (the run ends when every seed has, `stopped`); one where the epochs' curves are watched
    (`epoch_per_call`), so that each epoch's wall time is its own, the first's with the
    compilation."""
    chunk = 1 if epoch_per_call else min(save_every, config.patience or save_every)
    return min(chunk, save_every - done % save_every, config.epochs - done)


def train_and_evaluate(
    config: Config,
    data_sets: Mapping[str, Any] | Placed,
    seeds: Sequence[int],
    workdir: str | os.PathLike | None = None,
    save_every: int | None = None,
    on_save: Callable[[int], None] | None = None,
    log_dir: str | os.PathLike | None = None,
) -> TrainedSeeds:
    """Train one model per seed in a single program and evaluate it on every set.

    `data_sets` holds "train", "val" and any number of evaluation sets ("test", "cafe", ...), as
    loaded or placed already (`placement.place_sets`: a study places a row's sets once for every
    point of its recipe grid). With `workdir` (this run's checkpoint directory) the state and the
    curves so far are saved every `save_every` epochs (default `SAVE_EVERY_EPOCHS`) and at the
    end, and a rerun resumes from the latest save to the uninterrupted run's bits; `on_save(epoch)`
    is called after each durable save.

    The per-epoch curves (`curves.tags`: loss, accuracies per head, learning rate, epoch wall
    time) come back in `metrics["epochs"]` as {tag: (seeds, epochs)} arrays, NaN for epochs a
    resumed run did not train itself; where the run's wall time went comes back in
    `metrics["time"]` (`TimeAccount`). With `log_dir` they are also written as TensorBoard event
    files, one folder per seed (`curves.seed_dir`), after every epoch: with `log_dir` the epoch
    scan runs one epoch per call, so that a long run can be watched while it trains (and each
    epoch's wall time is its own, also where tensorboardX is not installed).
    """
    seeds = tuple(int(s) for s in seeds)
    mesh = sharding.training_mesh(config.batch_size)
    account = TimeAccount()
    with account.phase("place_s"):
        placed = (
            data_sets if isinstance(data_sets, Placed) else place_sets(config, data_sets, sharding.replicated(mesh))
        )
        jax.block_until_ready(placed.sets)
    with account.phase("initialise_s"):
        programs = _programs(config, placed.shapes, placed.n_train, mesh, placed.from_host)
        train_set = placed.training_set
        saves = Saves(
            checkpoint.manager(workdir) if workdir is not None else None,
            checkpoint.meta(
                config,
                seeds,
                programs.trainer.shapes,
                getattr(train_set, "classes", None),
                getattr(train_set, "dataset", None),
            ),
            save_every or SAVE_EVERY_EPOCHS,
            on_save,
        )
        state, done, saved_curves = _start(config, programs, seeds, train_set, saves)
    history = curves.History(len(seeds), config.epochs)
    if done and saved_curves:
        history.restore(saved_curves)
    state, validation = _train(config, programs, state, placed.sets, done, history, saves, account, seeds, log_dir)
    with account.phase("evaluate_s"):
        metrics = _evaluate_best(programs, state, placed, validation)
    return TrainedSeeds(
        config,
        seeds,
        programs.trainer.graphdef,
        state,
        {**metrics, "epochs": history.scalars, "time": account.result()},
    )


def _start(
    config: Config, programs: Programs, seeds: tuple[int, ...], train_set, saves: Saves
) -> tuple[TrainState, int, dict[str, list] | None]:
    """(the seeds' stacked states, epochs done, the curves saved with them): the latest save's
    (`Saves.latest`), else new states with `train_set`'s input statistics written into their
    parameters."""
    keys = sharding.put(seed_keys(seeds), programs.replicated)
    if saves.exist():
        abstract = jax.tree.map(
            lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=programs.replicated),
            jax.eval_shape(programs.init, keys),
        )
        state, done, saved_curves = saves.latest(abstract)
        return jax.block_until_ready(state), done, saved_curves
    stats = input_statistics(config, train_set)
    state = programs.init(keys)
    state = state.replace(
        params=with_input_statistics(state.params, stats),
        best_params=with_input_statistics(state.best_params, stats),
    )
    return jax.block_until_ready(sharding.put(state, programs.replicated)), 0, None


def _train(
    config: Config,
    programs: Programs,
    state: TrainState,
    sets: Mapping[str, Any],
    done: int,
    history: curves.History,
    saves: Saves,
    account: TimeAccount,
    seeds: tuple[int, ...],
    log_dir: str | os.PathLike | None,
) -> tuple[TrainState, BestEpochValidation]:
    """The run's epochs after `done`, a chunk at a time (`chunk_length`), until `config.epochs` or
    until every seed has stopped: (state, the validation results of each seed's best epoch among
    them). After each chunk its curves go into `history` and, with `log_dir`, onto disk, and the
    run saves where a save is due (`Saves`)."""
    validation = BestEpochValidation(len(seeds))
    # in a multi-process run only process 0 writes curves; the others open no files but chunk alike
    writer = curves.open_writer(log_dir, seeds if runtime.is_primary() else (), done) if log_dir is not None else None
    while done < config.epochs and not stopped(state):
        n = chunk_length(config, done, saves.every, epoch_per_call=log_dir is not None)
        t0 = time.perf_counter()
        with account.phase("epochs_s"):
            state, chunk_curves = programs.epochs(n)(state, sets)
            chunk_curves = jax.device_get(chunk_curves)  # waits for the chunk
        history.add(done, chunk_curves, (time.perf_counter() - t0) / n)
        validation.add(
            done, chunk_curves.pop("val_predictions"), chunk_curves["val_accuracy"], jax.device_get(state.best_epoch)
        )
        if writer is not None:
            writer.write(history, done, done + n)
        done += n
        if saves.due(done, config.epochs, state):
            with account.phase("save_s"):
                saves.save(done, state, history)
            if saves.on_save is not None:
                saves.on_save(done)
    if writer is not None:
        writer.close()
    return state, validation


def _evaluate_best(
    programs: Programs, state: TrainState, placed: Placed, validation: BestEpochValidation
) -> dict[str, Any]:
    """The run's metrics (NumPy arrays, a leading seed axis): its curves in the state
    (`EpochHistory`), each seed's best epoch, stop and best validation accuracy, and the
    best-validation models' predictions and accuracy on every set ("eval"), cut to the sets' real
    sizes. The validation set's are the best epoch's own where the epochs trained here include it
    (`BestEpochValidation`), else evaluated again."""
    val = validation.results()
    sets = placed.sets["eval"] if val is not None else {"val": placed.sets["val"], **placed.sets["eval"]}
    evaluations = jax.device_get(programs.evaluate(state.best_params, sets))
    return unpad(
        {
            **dataclasses.asdict(jax.device_get(state.history)),
            "best_epoch": jax.device_get(state.best_epoch),
            "stopped_at": jax.device_get(state.stopped_at),
            "best_val_acc": jax.device_get(state.best_val),
            "eval": evaluations if val is None else {"val": val, **evaluations},
        },
        placed.sizes,
    )


class SavedSeeds(NamedTuple):
    """The seeds of a run as its checkpoint holds them (`restore`): the model's graphdef, its state
    (all seeds stacked, or one seed's), the run's config and seeds as saved with it, and what the
    model was trained for (`checkpoint.trained_for`)."""

    graphdef: Any
    state: TrainState
    config: Config
    seeds: list[int]
    trained_for: dict[str, Any]
    dataset: dict[
        str, str
    ]  # the data it was trained on (`DatasetIndex.identity`; empty where the checkpoint does not say)


def restore(directory: str | os.PathLike, config: Config | None = None, seed: int | None = None) -> SavedSeeds:
    """The run saved by `train_and_evaluate` in `directory`: all seeds stacked, or the one `seed`
    (a seed value). `config` None restores under the config saved with the run; a given config
    must be the saved one (else `checkpoint.CheckpointMismatch`). A path holding no checkpoint is a
    `checkpoint.NoCheckpoint` and creates nothing; the arrays come back on this run's devices,
    whatever the device and process count of the run that saved them. `SavedSeeds.trained_for` says
    what the model is for (`checkpoint.trained_for`)."""
    mngr = checkpoint.open_existing(directory)
    saved = checkpoint.read_meta(mngr)
    config = Config.from_json(saved["config"]) if config is None else config
    shapes = {k: tuple(v) for k, v in saved["shapes"].items()}
    expected = checkpoint.meta(config, saved["seeds"], shapes)
    checkpoint.check_meta(mngr.directory, saved, expected)
    trainer = make_trainer(config, shapes)
    abstract = jax.eval_shape(jax.vmap(trainer.init), jax.ShapeDtypeStruct((len(saved["seeds"]), 2), jnp.uint32))
    state, _ = checkpoint.restore(mngr, checkpoint.on_devices(abstract), expected)
    for_ = saved.get("trained_for") or checkpoint.trained_for(config)  # older checkpoints: from their config
    if seed is None:
        return SavedSeeds(trainer.graphdef, state, config, saved["seeds"], for_, saved.get("dataset") or {})
    if seed not in saved["seeds"]:
        raise KeyError(f"seed {seed} is not in the checkpoint in {mngr.directory} (seeds {saved['seeds']})")
    return SavedSeeds(
        trainer.graphdef,
        checkpoint.select_seed(state, saved["seeds"].index(seed)),
        config,
        saved["seeds"],
        for_,
        saved.get("dataset") or {},
    )
