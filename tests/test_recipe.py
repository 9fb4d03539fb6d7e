"""The fitted recipe: early stopping inside the vmapped program, and the grid chosen on validation alone."""

import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.sequences.inputs import feature_shapes
from fabricjax.studies.machinery import recipe, row_training
from fabricjax.training import feed, placement, sharding
from fabricjax.training.train import train_and_evaluate
from fabricjax.training.trainer import make_trainer, seed_keys

TINY = Config(
    preset="smoke",
    modalities=("internal", "proprio"),
    width=16,
    n_layers=1,
    ffn=32,
    audio_hidden=(16, 8),
    proprio_hidden=(16, 8),
    seq_len=8,
    epochs=6,
    batch_size=8,
    learning_rate=3e-3,
    warmup_steps=2,
)


def _shapes(cfg):
    return feature_shapes(placement.select(cfg, synthetic.data_set(cfg, 2))["inputs"])


def data_sets(cfg, n_train=32):
    return {
        "train": synthetic.data_set(cfg, n_train, seed=0),
        "val": synthetic.data_set(cfg, 16, seed=1),
        "test": synthetic.data_set(cfg, 16, seed=2),
    }


def test_early_stopping_picks_the_epoch_a_validation_curve_dictates():
    """Fed a constructed validation curve, the best epoch is its first maximum before the seed
    stops, the seed stops `patience` epochs after it, and a later, higher value is never seen."""
    cfg = dataclasses.replace(TINY, patience=3, epochs=10)
    trainer = make_trainer(cfg, _shapes(cfg))
    state = trainer.init(jax.random.PRNGKey(0))
    curve = [
        0.2,
        0.5,
        0.4,
        0.6,
        0.55,
        0.6,
        0.58,
        0.9,
        0.95,
        0.97,
    ]  # best 0.6 at epoch 3; epochs 4, 5, 6 no better: stops at 6
    for e, acc in enumerate(curve):
        params = jax.tree.map(lambda a: jnp.full_like(a, e), state.params)  # each epoch's parameters are its number
        params, opt_state = trainer.unless_stopped(
            state.stopped_at, (params, state.opt_state), (state.params, state.opt_state)
        )
        # a stopped seed's parameters are frozen, so its validation accuracy is that of its last trained epoch
        acc = acc if state.stopped_at < 0 else curve[int(state.stopped_at)]
        state, _ = trainer.end_epoch(
            state.replace(params=params, opt_state=opt_state),
            {"train_loss": jnp.float32(1.0)},
            {"accuracy": {"fabric": jnp.float32(acc)}, "predictions": {}},
        )
    assert int(state.best_epoch) == 3
    assert int(state.stopped_at) == 6
    assert float(state.best_val) == pytest.approx(0.6)
    assert all(np.all(np.asarray(a) == 3) for a in jax.tree.leaves(state.best_params))
    assert all(np.all(np.asarray(a) == 6) for a in jax.tree.leaves(state.params))  # trained up to the stop, then frozen


def test_no_patience_never_stops():
    trainer = make_trainer(TINY, _shapes(TINY))
    state = trainer.init(jax.random.PRNGKey(0))
    for _ in range(5):
        state, _ = trainer.end_epoch(
            state, {"train_loss": jnp.float32(1.0)}, {"accuracy": {"fabric": jnp.float32(0.1)}, "predictions": {}}
        )
    assert int(state.stopped_at) == -1


def test_a_stopped_seed_no_longer_changes_while_the_others_train():
    """Two seeds in one vmapped program, the first marked stopped: another epoch leaves its
    parameters and optimiser state bit for bit and changes the other's, on the devices and fed
    from the host (`feed.HostFeed`), whose epochs are the same state and curves, the stopped seed's
    included: both run the trainer's one step body and mask a stopped seed after the epoch."""
    cfg = dataclasses.replace(TINY, patience=2)
    two = {k: v for k, v in data_sets(cfg).items() if k in ("train", "val")}
    mesh = sharding.training_mesh(cfg.batch_size)
    trainer = make_trainer(cfg, _shapes(cfg), mesh, n_train=32)
    state = jax.jit(jax.vmap(trainer.init))(seed_keys([0, 1]))
    state = state.replace(stopped_at=jnp.array([0, -1], jnp.int32))
    before = jax.tree.map(np.array, (state.params, state.opt_state))
    on_host = placement.place_sets(dataclasses.replace(cfg, input_source="disk"), two, sharding.replicated(mesh))
    assert on_host.from_host
    host = trainer.run(state, on_host.sets, feed.HostFeed(cfg.batch_size, sharding.replicated(mesh)), n_epochs=1)
    data = placement.place_sets(cfg, two, sharding.replicated(mesh)).sets
    on_devices = jax.jit(jax.vmap(lambda s, d: trainer.run(s, d, feed.DeviceFeed(), 1), in_axes=(0, None)))(state, data)
    for after, _ in (on_devices, host):
        for old, new in zip(jax.tree.leaves(before), jax.tree.leaves((after.params, after.opt_state))):
            np.testing.assert_array_equal(np.asarray(new)[0], old[0])
        moved = [
            not np.array_equal(np.asarray(new)[1], old[1])
            for old, new in zip(jax.tree.leaves(before[0]), jax.tree.leaves(after.params))
        ]
        assert any(moved)
    for a, b in zip(jax.tree.leaves(on_devices), jax.tree.leaves(host), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_a_run_ends_when_every_seed_has_stopped():
    """With patience 1 and a learning rate too small to move the validation accuracy, every seed
    stops within a few epochs: the run ends there instead of at the cap, its curves NaN beyond."""
    cfg = dataclasses.replace(TINY, patience=1, epochs=30, learning_rate=1e-9, warmup_steps=0)
    res = train_and_evaluate(cfg, data_sets(cfg), seeds=[0, 1])
    stopped = res.metrics["stopped_at"]
    assert (stopped >= 0).all() and stopped.max() < 29
    ran = np.isfinite(res.metrics["epochs"]["val/accuracy/fabric"]).sum(axis=1)
    assert (ran == stopped.max() + 1).all()
    np.testing.assert_array_equal(res.metrics["best_epoch"] + cfg.patience, stopped)


def test_the_grid_expands_in_its_declared_order():
    cfg = dataclasses.replace(TINY, lr_grid=(1e-3, 3e-3), width_grid=(16, 32))
    pts = recipe.points(cfg)
    assert [(p.learning_rate, p.width) for p in pts] == [(1e-3, 16), (1e-3, 32), (3e-3, 16), (3e-3, 32)]
    assert all(not recipe.has_grid(p) for p in pts)
    assert recipe.points(TINY) == [TINY]


class _Set:
    """A data set as `data.narrow` and the trainer read it (inputs, labels, `narrow`ed as itself)."""

    def __init__(self, d):
        self.inputs, self.labels = d["inputs"], d["labels"]

    def __len__(self):
        return len(next(iter(self.labels.values())))


@pytest.mark.slow
def test_a_corrupted_test_split_changes_no_choice(monkeypatch):
    """Every choice (the grid point, each seed's best and stopping epoch, the validation scores)
    is the same whether the test split is the real one or noise with shuffled labels."""
    monkeypatch.setattr(
        row_training.data,
        "narrow",
        lambda sets, config: {
            k: placement.select(config, {"inputs": v.inputs, "labels": v.labels}) for k, v in sets.items()
        },
    )
    cfg = dataclasses.replace(TINY, patience=1, epochs=4, lr_grid=(1e-4, 3e-3))
    clean = {k: _Set(v) for k, v in data_sets(cfg).items()}
    rng = np.random.default_rng(7)
    test = clean["test"]
    corrupt = dict(
        clean,
        test=_Set(
            {
                "inputs": {m: rng.normal(size=a.shape).astype(a.dtype) * 100 for m, a in test.inputs.items()},
                "labels": {h: rng.permutation(a) for h, a in test.labels.items()},
            }
        ),
    )

    def fit(sets):
        row = row_training.train_fitted("t", "row", cfg, row_training.place_row(cfg, sets, ["test"]), [0, 1])
        return (
            row.recipe,
            row.results.metrics["best_epoch"].tolist(),
            row.results.metrics["stopped_at"].tolist(),
            row.results.metrics["eval"]["test"]["accuracy"]["fabric"],
        )

    a, b = fit(clean), fit(corrupt)
    for doc in (a[0], b[0]):
        for p in doc["grid"]:
            p.pop("wall_s")
        doc.pop("grid_s")
    assert a[:3] == b[:3]
    assert len(a[0]["grid"]) == 2
    assert not np.array_equal(a[3], b[3])  # the test split itself did change


LMT108 = Path(__file__).resolve().parents[2] / "shared" / "data" / "lmt108_sound"


@pytest.mark.slow
@pytest.mark.skipif(
    not (LMT108 / "manifest.csv").exists(), reason="the LMT-108 recordings are not beside this checkout"
)
def test_real_contact_sound_trains_to_its_linear_probe(tmp_path):
    """Real recordings (LMT-108, 22 materials): imported as they are and trained with the fitted
    recipe and no other setting, the row lands within 3 pp of the linear probe of its inputs."""
    from acquisition import batch_import
    from fabricjax.store.workspace import Location
    from fabricjax.studies.paper import ablation

    out = tmp_path / "lmt108"
    batch_import.run(LMT108 / "manifest.csv", out, rig=LMT108 / "rig.toml", progress=False, say=lambda s: None)
    doc = ablation.run(
        n_seeds=1,
        rows=["internal"],
        where=Location(workdir=tmp_path / "ws", data_dir=out, results=tmp_path / "results", command="test"),
    )
    (row,) = doc["rows"]
    assert 100 * np.mean(row["accuracy"]["test"]["fabric"]) >= 100 * row["probe"]["accuracy"]["test"] - 3
    assert len(row["recipe"]["grid"]) == 4 and "License" in doc["dataset"]["provenance"]["sections"]


def test_an_epoch_count_asked_for_is_trained_not_replaced_by_the_presets_step_budget():
    """`--set=epochs=4` on a preset with a step budget trains 4 epochs (the budget gives way); a
    config built from all its fields keeps them as they are."""
    import dataclasses

    from fabricjax.config import Config

    budget = Config.from_preset("default")
    assert budget.train_steps > 0 and budget.patience_steps > 0
    asked = Config.from_preset("default", epochs=4, patience=1)
    assert (asked.epochs, asked.train_steps, asked.patience, asked.patience_steps) == (4, 0, 1, 0)
    assert dataclasses.replace(budget, epochs=7).train_steps == budget.train_steps
