"""A training run, top to bottom: `train_and_evaluate` places the sets, builds the run's programs,
initialises the seeds or resumes them from a checkpoint, trains the epochs a chunk at a time with
their saves, and evaluates each seed's best-validation model on every set; `restore` reads a saved
run back.

The pure pieces the programs are made of (the optimiser, the loss, the step, the epoch) are
`fabricjax.training.trainer`'s, jitted and vmapped over the seeds here; where an epoch reads its
sets (on the devices, or from the host a block at a time) is `fabricjax.training.feed`'s, and
where the inputs live `fabricjax.training.placement`'s.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import time
from typing import Any, Callable, Mapping, NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx
from jax.sharding import NamedSharding

from fabricjax import runtime
from fabricjax.config import Config
from fabricjax.model import FabricNet
from fabricjax.sequences.inputs import input_statistics, with_input_statistics
from fabricjax.training import checkpoint, curves, sharding
from fabricjax.training.feed import DeviceFeed, HostFeed
from fabricjax.training.placement import Placed, place_sets
from fabricjax.training.trainer import Trainer, TrainState, make_trainer, seed_keys

# How often a checkpointed run saves by default: a killed run loses at most this many epochs (a
# row of the paper preset is hours), and a save costs a fraction of an epoch.
SAVE_EVERY_EPOCHS = 2


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
    with TimeAccount() as account:
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


class TimeAccount:
    """Where a run's wall time went, in seconds: placing its inputs ("place_s"), initialising
    (building and running the initialisation, the input statistics) or restoring ("initialise_s"),
    its epochs ("epochs_s", the first with its programs' building), saving ("save_s"), evaluating
    the best epoch's models ("evaluate_s"), and the time any of these spent building programs
    ("compile_s": tracing, lowering and XLA's compilation, from JAX's own events, which the account
    listens to while the run is inside it). Each phase waits for its results, so its time is its
    own; what the phases leave of the run's wall time is bookkeeping (curves written, results
    gathered)."""

    BUILD_EVENTS = frozenset(
        f"/jax/core/compile/{e}"
        for e in ("jaxpr_trace_duration", "jaxpr_to_mlir_module_duration", "backend_compile_duration")
    )

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self.building = 0.0

    def _count_build(self, event: str, duration: float, **_) -> None:
        if event in self.BUILD_EVENTS:
            self.building += duration

    def __enter__(self) -> TimeAccount:
        jax.monitoring.register_event_duration_secs_listener(self._count_build)
        return self

    def __exit__(self, *exc) -> None:
        jax.monitoring.unregister_event_duration_listener(self._count_build)

    @contextlib.contextmanager
    def phase(self, name: str):
        start = time.perf_counter()
        yield
        self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start

    def result(self) -> dict[str, float]:
        return {**self.seconds, "compile_s": self.building}


class Programs(NamedTuple):
    """A run's programs, for where its sets live: `init` (the seeds' keys to their stacked
    states), `epochs(n)` ((state, sets) to n more epochs: `Trainer.run`) and `evaluate`
    ((parameters, sets) to `Trainer.evaluate_sets`). With the sets on the devices each is one
    jitted, seed-vmapped, seed-sharded program (`DeviceFeed`); from the host, `Trainer.run` and
    `Trainer.evaluate_sets` run with `HostFeed`, which compiles their pieces."""

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
        host = HostFeed(config.batch_size, per_seed)
        return Programs(
            trainer,
            init,
            lambda n: functools.partial(trainer.run, feed=host, n_epochs=n),
            functools.partial(trainer.evaluate_sets, feed=host),
            per_seed,
        )
    on_devices = DeviceFeed()
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


def chunk_length(config: Config, done: int, save_every: int, epoch_per_call: bool) -> int:
    """Epochs the next call of `Programs.epochs` trains, after `done`: up to the next save and at
    most `config.patience`, so that a chunk ends at most `patience` epochs after a seed could have
    stopped (the run ends when every seed has, `stopped`); one where the epochs' curves are watched
    (`epoch_per_call`), so that each epoch's wall time is its own, the first's with the
    compilation."""
    chunk = 1 if epoch_per_call else min(save_every, config.patience or save_every)
    return min(chunk, save_every - done % save_every, config.epochs - done)


def stopped(state) -> bool:
    """Whether every seed of a run has stopped early (`Trainer.end_epoch`): its remaining epochs
    would change nothing."""
    return bool(np.all(jax.device_get(state.stopped_at) >= 0))


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


def unpad(metrics, sizes: Mapping[str, int]):
    """Cut per-sample predictions (last axis) back to each set's real size."""
    return {
        **metrics,
        "eval": {
            k: {**v, "predictions": jax.tree.map(lambda p: p[..., : sizes[k]], v["predictions"])}
            for k, v in metrics["eval"].items()
        },
    }


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
