"""The plan a study prints before it starts (fabricjax/studies/machinery/plan.py)."""

import dataclasses

import numpy as np
import pytest

from fabricjax import catalog, presets
from fabricjax.bench import program_timing
from fabricjax.bench.program_timing import row_cost  # the real one: conftest stands a fixed cost in
from fabricjax.config import Config
from fabricjax.sim import dataset as sim_dataset
from fabricjax.studies.machinery import plan


def rows(preset, *modalities):
    return [("+".join(m), Config.from_preset(preset, modalities=m)) for m in modalities]


def test_missing_trials_are_timed_on_this_host_and_their_disk_counted(tmp_path, timed):
    spec = presets.get("smoke").dataset
    stages = plan.stages("smoke", rows("smoke", ("internal",), ("flow", "internal")), 2, tmp_path)
    sim, features, sequences, *training = stages
    n = len(spec.trials())
    assert sim.name.startswith(f"simulation ({n} of {n} trials missing)") and sim.seconds > 0
    assert sim.disk_bytes == n * sim_dataset.trial_bytes(spec, True)
    assert features.seconds > 0 and features.disk_bytes > 0 and "flow " in features.basis
    assert "does not fit" in plan.markdown("smoke", stages, 2, 2, free_bytes=1)
    assert sequences.disk_bytes == 0 and "held in memory" in sequences.basis
    assert len(training) == 2 and all(t.seconds > 0 for t in training)  # one stage per row, each timed
    assert [sorted(arrays) for _, _, arrays in timed] == [["internal"], ["flow", "internal"]]
    assert "peak host memory" in sequences.basis
    text = plan.markdown("smoke", stages, 2, 2, free_bytes=1e15)
    assert text.startswith("Plan: 2 rows x 2 seeds on preset 'smoke': about ")


COST = program_timing.RowCost(
    s_per_step=0.02, s_per_eval_batch=0.005, flops_per_step=2e9, flops_per_eval_batch=5e8, compile_s=3.0
)


@pytest.fixture
def timed(monkeypatch):
    """Every row's step timed at `COST`, against a matmul peak of 200 GFLOP/s; records what was timed."""
    calls = []
    monkeypatch.setattr(plan, "host_peak_flops", lambda: 200e9)

    def time_row(config, n_seeds, arrays):
        calls.append((config, n_seeds, arrays))
        return COST

    monkeypatch.setattr(program_timing, "row_cost", time_row)
    return calls


ARRAYS = {"internal": ((320,), np.float32), "proprio": ((18,), np.float32), "image": ((30, 40, 3), np.int16)}


def test_every_training_row_is_timed_on_this_host_and_scaled_by_its_epochs_and_splits(timed):
    """A row's seconds: its compilation + its epochs x (optimiser steps + a validation pass) + the
    last evaluation of every split but training's, at the rates timed on this host; each distinct
    row is timed once, on the data's per-step arrays of its own inputs."""
    config = Config.from_preset("default", modalities=("internal",))
    sizes = {"train": 1600, "val": 300, "test": 200, "cafe": 100}
    (stage, again) = plan.training([("internal", config), ("internal again", config)], 5, sizes, ARRAYS)
    epochs = -(-config.train_steps // (1600 // config.batch_size))
    val, end = -(-300 // config.batch_size), sum(-(-n // config.batch_size) for n in (300, 200, 100))
    per_epoch = (1600 // config.batch_size) * COST.s_per_step + val * COST.s_per_eval_batch
    assert stage.seconds == pytest.approx(COST.compile_s + epochs * per_epoch + end * COST.s_per_eval_batch)
    assert again.seconds == stage.seconds and len(timed) == 1
    assert timed[0][1] == 5 and timed[0][2] == {"internal": ARRAYS["internal"]}
    assert f"at most {epochs} epochs (early stopping may end sooner)" in stage.basis
    assert "50 % of the float32 matmul peak" in stage.basis  # 2 GFLOP in 20 ms against 200 GFLOP/s
    gflop = ((1600 // config.batch_size) * COST.flops_per_step + val * COST.flops_per_eval_batch) / 1e9
    assert f"{gflop:.0f} GFLOP per epoch" in stage.basis
    said = plan.markdown("default", [stage, again], 2, 5, free_bytes=1e15)
    assert said.endswith("Training rates as measured by each row's step, timed on this host just now.")


def test_a_grid_multiplies_a_row_and_early_stopping_is_said_only_when_on(timed):
    config = Config.from_preset("paper", modalities=("internal",))
    sizes = {"train": 100, "val": 20}
    (off,) = plan.training([("internal", dataclasses.replace(config, patience=0, patience_steps=0))], 2, sizes, ARRAYS)
    (on,) = plan.training([("internal", dataclasses.replace(config, patience=3))], 2, sizes, ARRAYS)
    assert "early stopping" not in off.basis and "(early stopping may end sooner)" in on.basis
    grid = dataclasses.replace(config, lr_grid=(1e-3, 3e-3), width_grid=(32, 64))
    (fitted,) = plan.training([("internal", grid)], 2, sizes, ARRAYS)
    assert fitted.seconds == pytest.approx(4 * off.seconds) and "4 grid points" in fitted.basis


def test_a_rows_step_is_timed_on_inputs_of_the_datas_shapes_and_dtypes():
    """The real programs of a tiny row on int16 frames and a PSD: positive times and FLOPs, and a
    step costs more than a validation minibatch (it also runs the backward pass)."""
    config = Config.from_preset("smoke", modalities=("image", "internal"), n_classes=5)
    arrays = {"image": ((12, 16, 3), np.int16), "internal": ((24,), np.float32)}
    cost = row_cost(config, 2, arrays, steps=2, repeats=1)
    assert cost.s_per_step > 0 and cost.s_per_eval_batch > 0 and cost.compile_s > 0
    assert cost.flops_per_step > cost.flops_per_eval_batch > 0


def test_each_feature_says_its_bytes_per_step():
    """`Feature.step_bytes` is one step of the array the feature computes, for every camera reading
    and a microphone window other than the paper's: what the plan sizes the cache and sequences by."""
    import types

    from fabricjax.features import extract
    from fabricjax.sim.trial import simulate

    spec = dataclasses.replace(presets.get("smoke").dataset, cycles_per_trial=1)
    trial = simulate(sim_dataset.scene_for(spec.trials()[0], spec, ("audio", "proprio", "images")))
    frames = types.SimpleNamespace(images=trial.images[:3], reference=trial.reference)
    features = [extract.feature_for("internal", window=1024)]
    for reference in ("session", "none"):
        for resolution in ("down", "full"):
            config = Config.from_preset(
                "smoke",
                modalities=("internal", "proprio", "flow", "image"),
                image_reference=reference,
                image_resolution=resolution,
            )
            features += extract.features_for(config).values()
    for f in features:
        computed = f.compute(frames if f.needs_images else trial)
        assert computed[0].nbytes == f.step_bytes(spec.image_size), f.name


def test_the_training_sequences_are_those_the_splits_train_on(tmp_path, monkeypatch):
    """The plan counts the trials `splits` and `data` put in the training split: a fabric the rows
    exclude (the property holdouts) trains on none, and a day of one trial keeps it for training."""
    from fabricjax.store import splits

    spec = presets.get("smoke").dataset
    counted = {}

    def training(configs, n_seeds, sizes, arrays):
        counted[configs[0][1].exclude_fabrics] = sizes["train"]
        return []

    monkeypatch.setattr(plan, "probe", lambda dataset, config: {"simulate": 0.0})
    monkeypatch.setattr(plan, "training", training)
    for exclude in ((), (spec.fabrics[0],)):
        plan.stages(
            "smoke",
            [("internal", Config.from_preset("smoke", modalities=("internal",), exclude_fabrics=exclude))],
            2,
            tmp_path,
        )
    trained = [f for f in spec.fabrics if f not in catalog.NEW_FABRICS]  # the new fabrics are only tested
    per_fabric = counted[()] // len(trained)
    assert counted[()] == per_fabric * len(trained) > 0
    assert counted[(spec.fabrics[0],)] == counted[()] - per_fabric
    one = dataclasses.replace(spec, train_trials_per_day=1)
    roles = [
        role
        for meta, role in splits.dataset_roles(one)
        if meta["condition"] == "lab" and meta["day"] in one.splits.train_days
    ]
    assert roles and set(roles) == {"train"}


def test_the_peak_memory_counts_minsight_frames_again_as_trainings_rows(tmp_path, timed):
    """Training holds an image row's frames twice (as loaded and as pixel rows): the plan's peak says
    so and counts both; without image rows the peak is the loaded sequences."""
    with_image = plan.stages("smoke", rows("smoke", ("image", "internal")), 1, tmp_path)[2]
    without = plan.stages("smoke", rows("smoke", ("internal",)), 1, tmp_path)[1]
    assert "Minsight frames a second time" in with_image.basis and "second time" not in without.basis
