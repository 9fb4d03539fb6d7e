import dataclasses
import json
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

from fabricjax import runtime
from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.model import FabricNet, make_predict
from fabricjax.sequences.inputs import input_statistics, training_layout
from fabricjax.training import placement, sharding, train
from fabricjax.training.train import train_and_evaluate
from fabricjax.training.trainer import make_trainer, masked_accuracy, masked_cross_entropy
from tests import helpers

TINY = Config(
    preset="smoke",
    modalities=("internal", "proprio"),
    width=16,
    n_layers=1,
    ffn=32,
    cnn_features=(16, 32, 64),
    audio_hidden=(16, 8),
    proprio_hidden=(16, 8),
    seq_len=8,
    epochs=3,
    batch_size=8,
    learning_rate=1e-3,
    warmup_steps=100,
    property_heads=True,
)


def data_sets(cfg, n_train=24):
    train = synthetic.data_set(cfg, n_train, seed=0)
    train["labels"]["roughness"][:5] = -1  # unknown labels are masked out of the loss
    return {
        "train": train,
        "val": synthetic.data_set(cfg, 10, seed=1),
        "test": synthetic.data_set(cfg, 12, seed=2),
    }


@pytest.fixture(scope="module")
def four_seeds():
    """Seeds 3, 4, 3, 5 in one vmapped program: a leading seed axis, distinct and repeated seeds."""
    return train_and_evaluate(TINY, data_sets(TINY), seeds=[3, 4, 3, 5])


def test_metrics_have_a_leading_seed_axis(four_seeds):
    m = four_seeds.metrics
    assert m["train_loss"].shape == m["val_acc"].shape == (4, TINY.epochs)
    assert m["best_epoch"].shape == m["best_val_acc"].shape == (4,)
    for head in ("fabric", "stretchiness", "roughness", "thickness"):
        assert m["eval"]["test"]["accuracy"][head].shape == (4,)
        assert m["eval"]["test"]["predictions"][head].shape == (4, 12)
    assert m["eval"]["val"]["predictions"]["fabric"].shape == (4, 10)
    assert np.isfinite(m["train_loss"]).all()


def test_different_seeds_differ_and_the_same_seed_repeats(four_seeds):
    loss = four_seeds.metrics["train_loss"]
    assert not np.allclose(loss[0], loss[1])
    np.testing.assert_array_equal(loss[0], loss[2])
    for a, c in zip(jax.tree.leaves(four_seeds.params(0)), jax.tree.leaves(four_seeds.params(2))):
        np.testing.assert_array_equal(a, c)


def test_best_validation_epoch_is_selected(four_seeds):
    m = four_seeds.metrics
    np.testing.assert_array_equal(m["best_epoch"], np.argmax(m["val_acc"], axis=1))
    np.testing.assert_array_equal(m["best_val_acc"], m["val_acc"].max(axis=1))
    # The returned model is the best epoch's: its validation accuracy is the recorded best.
    np.testing.assert_allclose(m["eval"]["val"]["accuracy"]["fabric"], m["best_val_acc"], atol=1e-6)


def test_validation_results_are_the_best_epoch_models_own(four_seeds):
    """The validation predictions come from the epoch scan's evaluation at each seed's best epoch
    (`BestEpochValidation`): they are the returned model's predictions on the validation set."""
    val = data_sets(TINY)["val"]
    for i in range(len(four_seeds.seeds)):
        logits = make_predict(four_seeds.graphdef)(four_seeds.params(i), val["inputs"])
        for head, predictions in four_seeds.metrics["eval"]["val"]["predictions"].items():
            np.testing.assert_array_equal(predictions[i], np.argmax(logits[head], -1), err_msg=head)
            assert four_seeds.metrics["eval"]["val"]["accuracy"][head][i] == pytest.approx(
                float(masked_accuracy(predictions[i], val["labels"][head]))
            )


def test_a_best_epoch_before_the_epochs_seen_leaves_validation_to_finish():
    """A seed whose best epoch is not among the epochs added (it came before a resume) has no
    validation results; one found stays until a later best epoch replaces it."""
    kept = train.BestEpochValidation(2)
    predictions = {"fabric": np.arange(2 * 2 * 3).reshape(2, 2, 3)}  # (seeds, epochs 4-5, samples)
    accuracy = {"fabric": np.array([[0.1, 0.2], [0.3, 0.4]], np.float32)}
    kept.add(4, predictions, accuracy, best_epoch=np.array([5, 1]))
    assert kept.results() is None and kept.found.tolist() == [True, False]
    kept.add(6, {"fabric": predictions["fabric"] + 100}, accuracy, best_epoch=np.array([5, 6]))
    out = kept.results()
    np.testing.assert_array_equal(out["predictions"]["fabric"], [[3, 4, 5], [106, 107, 108]])
    np.testing.assert_array_equal(out["accuracy"]["fabric"], np.array([0.2, 0.3], np.float32))


def test_masked_loss_and_accuracy_ignore_unknown_labels():
    logits = np.zeros((3, 4), np.float32)
    assert float(masked_cross_entropy(logits, np.array([-1, -1, -1]))) == 0.0
    assert float(masked_cross_entropy(logits, np.array([-1, 4, 0]))) == pytest.approx(np.log(4))
    assert float(masked_accuracy(np.array([1, 2, 3]), np.array([1, -1, 0]))) == 0.5


def test_without_a_fabric_head_the_best_epoch_follows_mean_property_accuracy():
    cfg = Config(**{**TINY.to_json(), "fabric_head": False})
    trainer = make_trainer(cfg, {"internal": (24,), "proprio": (18,)})
    assert float(trainer.selection_metric({"stretchiness": 1.0, "roughness": 0.2, "thickness": 0.3})) == pytest.approx(
        0.5
    )


SHARDED = """
import json, sys
import jax, numpy as np
sys.path.insert(0, {tests!r})
from test_train import TINY, data_sets
from fabricjax.training import sharding
from fabricjax.training.train import train_and_evaluate
assert jax.device_count() == 4
out = {{"mesh": dict(sharding.training_mesh(TINY.batch_size).shape)}}
mesh = sharding.training_mesh(4)  # seeds together, samples over 4 devices
split = jax.jit(sharding.vmap_seeds(lambda x: 2 * sharding.split_samples(x, mesh, axis=1)))
shardings = [split(np.zeros((2, 2, n, 3))).sharding for n in (4, 3)]
out["split"] = [[len(s.device_set), list(getattr(s, "spec", []))] for s in shardings]
for name, seeds in (("seeds", [3, 4, 3, 5]), ("samples", [4])):
    res = train_and_evaluate(TINY, data_sets(TINY), seeds=seeds)
    out[name] = {{"devices": len(res.state.epoch.sharding.device_set),
                  "train_loss": res.metrics["train_loss"].tolist(),
                  "pred": res.metrics["eval"]["test"]["predictions"]["fabric"].tolist()}}
def kill(epoch):
    raise KeyboardInterrupt
try:  # killed after its first save, then resumed from the checkpoint on the same devices
    train_and_evaluate(TINY, data_sets(TINY), seeds=[4], workdir={workdir!r}, save_every=1, on_save=kill)
except KeyboardInterrupt:
    pass
saves = out["resumed_saves"] = []
res = train_and_evaluate(TINY, data_sets(TINY), seeds=[4], workdir={workdir!r}, save_every=1, on_save=saves.append)
out["resumed_loss"] = res.metrics["train_loss"].tolist()
print(json.dumps(out))
"""


@pytest.mark.slow  # ~30-55 s on 2 cores: run with -m slow
def test_four_host_devices_give_the_same_results_as_one(four_seeds, tmp_path):
    """Four seeds', and one seed's, minibatch samples split over 4 devices (gradients summed across
    devices) train as on one device."""
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=4", "JAX_PLATFORMS": "cpu"}
    code = "import jax; jax.config.update('jax_disable_most_optimizations', True)\n"
    code += "from fabricjax import runtime; runtime.configure_jax()\n"
    code += SHARDED.format(tests=os.path.dirname(__file__), workdir=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    sharded = json.loads(out.stdout.strip().splitlines()[-1])
    assert sharded["mesh"] == {"batch": 4}
    assert sharded["split"] == [[4, [None, None, "batch"]], [1, []]]  # 3 samples: left alone (no constraint)
    single = four_seeds
    assert len(single.state.epoch.sharding.device_set) == 1
    assert sharded["seeds"]["devices"] == sharded["samples"]["devices"] == 4
    np.testing.assert_allclose(sharded["seeds"]["train_loss"], single.metrics["train_loss"], rtol=1e-5)
    np.testing.assert_array_equal(sharded["seeds"]["pred"], single.metrics["eval"]["test"]["predictions"]["fabric"])
    np.testing.assert_allclose(sharded["samples"]["train_loss"], single.metrics["train_loss"][1:2], rtol=1e-5)
    np.testing.assert_array_equal(
        sharded["samples"]["pred"], single.metrics["eval"]["test"]["predictions"]["fabric"][1:2]
    )
    assert sharded["resumed_saves"] == [2, 3] and sharded["resumed_loss"] == sharded["samples"]["train_loss"]


def test_cpu_devices_are_chosen_before_jax_starts_and_an_explicit_count_wins():
    code = "from fabricjax import runtime; print(runtime.use_cpu_cores(3))"
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_NUM_CPU_DEVICES")}
    run = lambda env: subprocess.run(  # noqa: E731
        [sys.executable, "-c", code], env={**env, "JAX_PLATFORMS": "cpu"}, capture_output=True, text=True, timeout=120
    )
    assert run(env).stdout.split() == ["3"]
    assert run({**env, "XLA_FLAGS": "--xla_force_host_platform_device_count=2"}).stdout.split() == ["2"]
    # In this process JAX has started with one CPU device: too late to change, and said so.
    with pytest.warns(UserWarning, match="too late"):
        assert runtime.use_cpu_cores(3) == 1


def test_image_rows_rotate_the_frame_minus_the_reference_in_training_only():
    """The paper's rotation is the model's own augmentation, applied to its input (the frame minus
    the reference frame), through pixel rows: in training the features equal the CNN on the
    standardised frames turned by the rotation the model used to apply to frames (tests/helpers.py,
    same angles from the same key); a frame equal to the reference is no deformation at every
    angle; evaluation never turns, on frames or on rows; without `augment_rotation` nothing turns."""
    cfg = Config(
        **{
            **TINY.to_json(),
            "modalities": ("image",),
            "cnn_features": (4, 8),
            "property_heads": False,
            "image_reference": "training_mean",
        }
    )
    sets = {k: synthetic.data_set(cfg, 8, image_hw=(12, 16), seed=i) for i, k in enumerate(["train", "val"])}
    stats = input_statistics(cfg, sets["train"])
    assert stats["image_shift"].shape == (12, 16, 3) and stats["image_scale"].shape == (3,)

    def built(config):
        model = FabricNet(config, {"image": (12, 16, 3)}, rngs=nnx.Rngs(0))
        for k, v in stats.items():
            getattr(model, k).value = v
        return model

    model = built(cfg)
    reference = jnp.broadcast_to(stats["image_shift"], (2, 4, 12, 16, 3))
    np.testing.assert_allclose(model.standardise("image", reference.reshape(8, 12, 16, 3)), 0.0, atol=1e-4)
    frames = jnp.asarray(sets["train"]["inputs"]["image"][:2])
    b, n = frames.shape[:2]
    standardised = model.standardise("image", frames.reshape(b * n, 12, 16, 3))
    evaluation = model.image_features({"image": frames}, None)
    np.testing.assert_allclose(evaluation, model.image(standardised).reshape(b, n, -1), atol=1e-6)
    np.testing.assert_allclose(model.image_features(training_layout({"image": frames}), None), evaluation, atol=1e-5)
    trained = model.image_features({"image": frames}, nnx.Rngs(dropout=0, augment=1))
    turned = helpers.reference_rotate_batch(
        nnx.Rngs(dropout=0, augment=1).augment(), standardised.reshape(b, n, 12, 16, 3)
    )
    np.testing.assert_allclose(trained, model.image(turned.reshape(b * n, 12, 16, 3)).reshape(b, n, -1), atol=1e-5)
    assert not np.allclose(trained, evaluation, atol=1e-3)  # training: rotated
    np.testing.assert_allclose(  # the reference turned is still no deformation
        model.image_features({"image": reference}, nnx.Rngs(dropout=0, augment=2)),
        model.image(jnp.zeros((8, 12, 16, 3))).reshape(2, 4, -1),
        atol=1e-4,
    )
    still = built(dataclasses.replace(cfg, augment_rotation=False))
    assert not still.rotate_images and model.rotate_images
    np.testing.assert_allclose(
        still.image_features({"image": frames}, nnx.Rngs(dropout=0, augment=1)), evaluation, atol=1e-5
    )
    res = train_and_evaluate(cfg, sets, seeds=[0])
    assert np.isfinite(res.metrics["train_loss"]).all()
    # training evaluates on rows (one compiled image path): the predictions of the model on frames
    on_frames = make_predict(res.graphdef)(res.params(0), {"image": jnp.asarray(sets["val"]["inputs"]["image"])})[
        "fabric"
    ]
    np.testing.assert_array_equal(res.metrics["eval"]["val"]["predictions"]["fabric"][0], np.argmax(on_frames, -1))


def test_image_configs_reuse_their_cached_programs():
    """`_programs` (cached by config, shapes, augmentation, mesh) finds an image config's compiled
    programs again: a rerun (a resume, another seed set) compiles nothing."""
    cfg = Config(**{**TINY.to_json(), "modalities": ("image",), "cnn_features": (4,), "property_heads": False})
    mesh = sharding.training_mesh(cfg.batch_size)
    shapes = (("image", (12, 16, 3)),)
    first = train._programs(cfg, shapes, 24, mesh, False)
    assert train._programs(cfg, shapes, 24, mesh, False) is first


def test_joint_standardisation_comes_from_the_training_split_and_stays_fixed():
    cfg = Config(
        preset="smoke", modalities=("proprio",), width=16, n_layers=1, ffn=16, epochs=2, batch_size=8, seq_len=8
    )
    sets = {k: synthetic.data_set(cfg, n, seed=s) for k, n, s in (("train", 16, 0), ("val", 8, 1))}
    sets["train"]["inputs"]["proprio"] = sets["train"]["inputs"]["proprio"] * 1e-3 + 5.0  # tiny spread, large offset
    x = sets["train"]["inputs"]["proprio"].reshape(-1, 18)
    r = train_and_evaluate(cfg, sets, (0, 1))
    for p in (r.state.params, r.state.best_params):
        np.testing.assert_allclose(np.asarray(p["proprio_shift"])[1], x.mean(0), rtol=1e-5)
        np.testing.assert_allclose(np.asarray(p["proprio_scale"])[0], 1 / x.std(0), rtol=1e-3)
    assert np.all(np.isfinite(r.metrics["train_loss"]))


def test_pixel_and_flow_standardisation_is_per_channel_over_the_training_split():
    """Camera inputs are centred and scaled per colour channel / flow component (inputs.STANDARDISED),
    accumulated in chunks: equal to NumPy's statistics over every sequence, step and position."""
    cfg = Config(
        preset="smoke", modalities=("image", "flow"), epochs=1, batch_size=8, seq_len=4, image_reference="none"
    )
    ds = synthetic.data_set(cfg, 10, image_hw=(6, 8), flow_hw=(3, 4))
    ds["inputs"]["flow"][:, :, 1] *= 1e-3  # a nearly silent component is scaled up, never divided by 0
    stats = input_statistics(cfg, ds, chunk=3)
    image = ds["inputs"]["image"].astype(np.float64).reshape(-1, 3)
    flow = np.moveaxis(ds["inputs"]["flow"].astype(np.float64), 2, -1).reshape(-1, 2)
    np.testing.assert_allclose(stats["image_shift"], image.mean(0), rtol=1e-5)
    np.testing.assert_allclose(stats["image_scale"], 1 / image.std(0), rtol=1e-4)
    np.testing.assert_allclose(stats["flow_shift"], flow.mean(0), rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(stats["flow_scale"], 1 / flow.std(0), rtol=1e-4)
    assert set(stats) == {"image_shift", "image_scale", "flow_shift", "flow_scale"}
    # read from a reference frame: the training mean frame, and the spread about it per colour
    ref = input_statistics(dataclasses.replace(cfg, image_reference="training_mean"), ds, chunk=3)
    pixels = ds["inputs"]["image"].astype(np.float64).reshape(-1, 6, 8, 3)
    np.testing.assert_allclose(ref["image_shift"], pixels.mean(0), rtol=1e-5)
    np.testing.assert_allclose(ref["image_scale"], 1 / (pixels - pixels.mean(0)).reshape(-1, 3).std(0), rtol=1e-4)
    np.testing.assert_allclose(ref["flow_scale"], stats["flow_scale"])


@pytest.mark.parametrize("reference", ["none", "training_mean", "session"])
def test_pixel_standardisation_centres_and_scales_each_pixel_and_colour(reference):
    """`image_standardisation="pixel"`: every pixel and colour its own mean and 1 / SD over the
    training split's sequences and steps, whatever the reference; the model's training rows and its
    frames read them alike, and a frame at the training mean is 0 everywhere."""
    cfg = Config(
        **{
            **TINY.to_json(),
            "modalities": ("image",),
            "cnn_features": (4,),
            "property_heads": False,
            "image_reference": reference,
            "image_standardisation": "pixel",
        }
    )
    ds = synthetic.data_set(cfg, 10, image_hw=(10, 15))
    stats = input_statistics(cfg, ds, chunk=3)
    pixels = ds["inputs"]["image"].astype(np.float64).reshape(-1, 10, 15, 3)
    np.testing.assert_allclose(stats["image_shift"], pixels.mean(0), rtol=1e-5)
    np.testing.assert_allclose(stats["image_scale"], 1 / pixels.std(0), rtol=1e-4)
    model = FabricNet(cfg, {"image": (10, 15, 3)}, rngs=nnx.Rngs(0))
    for k, v in stats.items():
        getattr(model, k).value = v
    frames = jnp.asarray(ds["inputs"]["image"][:2])
    standardised = model.standardise("image", frames.reshape(-1, 10, 15, 3))
    np.testing.assert_allclose(standardised, (pixels[: len(standardised)] - pixels.mean(0)) / pixels.std(0), atol=1e-4)
    evaluation = model.image_features({"image": frames}, None)
    np.testing.assert_allclose(model.image_features(training_layout({"image": frames}), None), evaluation, atol=1e-5)


@pytest.mark.parametrize("reference", ["none", "training_mean"])
def test_frame_statistics_summed_in_integers_equal_the_float64_path_bit_for_bit(reference):
    """8-bit frames take the integer sums (`inputs._sums`); the same frames as float64 take the float
    path: the statistics are identical, not merely close."""
    cfg = Config(preset="smoke", modalities=("image",), epochs=1, batch_size=8, seq_len=4, image_reference=reference)
    ds = synthetic.data_set(cfg, 10, image_hw=(6, 8))
    assert ds["inputs"]["image"].dtype == np.uint8
    as_float = {**ds, "inputs": {"image": ds["inputs"]["image"].astype(np.float64)}}
    ints, floats = input_statistics(cfg, ds, chunk=3), input_statistics(cfg, as_float, chunk=3)
    for k in ("image_shift", "image_scale"):
        np.testing.assert_array_equal(ints[k], floats[k])


def test_input_statistics_do_not_depend_on_the_number_of_cores(monkeypatch):
    """The chunks are summed on every core and added in order: one core gives the same bits."""
    cfg = Config(preset="smoke", modalities=("proprio", "flow"), epochs=1, batch_size=8, seq_len=4)
    ds = synthetic.data_set(cfg, 23, flow_hw=(3, 4))
    many = input_statistics(cfg, ds, chunk=2)
    monkeypatch.setattr(runtime, "available_cores", lambda: 1)
    one = input_statistics(cfg, ds, chunk=2)
    for k in many:
        np.testing.assert_array_equal(many[k], one[k], err_msg=k)


def test_a_runs_time_account_adds_up_and_counts_the_building_of_its_programs(tmp_path):
    """`metrics["time"]`: each phase's seconds, their sum within the run's wall time, the epochs'
    equal to the per-epoch curve's, and the time spent building programs: some for a config this
    process has not built yet, none when its programs are kept."""
    import time

    cfg = dataclasses.replace(TINY, epochs=2, width=12)  # programs this process has not built
    sets = data_sets(cfg)
    start = time.perf_counter()
    first = train_and_evaluate(cfg, sets, (0, 1), workdir=tmp_path / "run")
    wall = time.perf_counter() - start
    account = first.metrics["time"]
    assert set(account) == {"place_s", "initialise_s", "epochs_s", "save_s", "evaluate_s", "compile_s"}
    assert all(v >= 0 for v in account.values())
    assert sum(v for k, v in account.items() if k != "compile_s") <= wall
    np.testing.assert_allclose(account["epochs_s"], first.metrics["epochs"]["epoch_wall_s"][0].sum(), rtol=1e-2)
    assert 0 < account["compile_s"] <= wall
    again = train_and_evaluate(cfg, sets, (0, 1))
    assert again.metrics["time"]["compile_s"] == 0.0 and "save_s" not in again.metrics["time"]


def test_inputs_placed_before_a_run_serve_it_and_change_nothing(monkeypatch):
    """A camera input placed (pixel rows, evaluation sets padded) and its statistics computed
    before a run, as a study does for a camera's first row, serve the run given the placed sets
    and a later run on the same arrays: neither builds them again, and both train to the bits of a
    run that did it all itself."""
    from fabricjax import memo
    from fabricjax.features import images
    from fabricjax.sequences import inputs

    cfg = Config(
        **{**TINY.to_json(), "modalities": ("image",), "cnn_features": (4,), "property_heads": False, "epochs": 1}
    )
    alone = train_and_evaluate(cfg, data_sets(cfg), (0,))
    monkeypatch.setattr(memo, "MIN_BYTES", 0)  # the tiny arrays are kept like a data set's
    monkeypatch.setattr(placement, "KEPT", memo.ByArray(max_entries=12, size=placement.KEPT.size))
    monkeypatch.setattr(inputs, "_STATISTICS", memo.ByArray(max_entries=16))
    sets = data_sets(cfg)  # arrays neither memo has seen
    placed = placement.place_sets(cfg, sets)
    input_statistics(cfg, sets["train"])
    built = []
    for module, name in ((images, "to_rows"), (inputs, "_moments")):
        monkeypatch.setattr(
            module, name, lambda *a, _f=getattr(module, name), _n=name, **k: built.append(_n) or _f(*a, **k)
        )
    for after in (train_and_evaluate(cfg, placed, (0,)), train_and_evaluate(cfg, sets, (0,))):
        assert built == []
        np.testing.assert_array_equal(after.metrics["train_loss"], alone.metrics["train_loss"])
        np.testing.assert_array_equal(
            after.metrics["eval"]["test"]["predictions"]["fabric"],
            alone.metrics["eval"]["test"]["predictions"]["fabric"],
        )


LEVEL_RUN = """
import hashlib, sys
import jax, numpy as np
sys.path.insert(0, {tests!r})
from fabricjax import runtime
runtime.configure_jax()
from test_train import TINY
from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.training.train import train_and_evaluate
cfg = Config(**{{**TINY.to_json(), "modalities": ("image", "internal", "proprio"), "cnn_features": (4,), "epochs": 1}})
sizes = (("train", 24), ("val", 10), ("test", 12))
sets = {{k: synthetic.data_set(cfg, n, seed=i, image_hw=(12, 16)) for i, (k, n) in enumerate(sizes)}}
res = train_and_evaluate(cfg, sets, seeds=[0, 1])
print(hashlib.sha256(b"".join(np.asarray(x).tobytes() for x in jax.tree.leaves(res.state.params))).hexdigest())
"""


@pytest.mark.slow  # ~20 s on 2 cores: two trainings compiled at two LLVM levels
def test_the_backend_optimisation_level_changes_no_bit_of_a_trained_model(monkeypatch):
    """`configure_jax` compiles at LLVM level 2 (`runtime.compile_at_backend_level`), where XLA
    builds programs faster; a model trained at XLA's default level 3 has the same parameters, bit
    for bit (camera, microphone and joint inputs, dropout on). A level already in XLA_FLAGS wins."""
    monkeypatch.setenv("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
    runtime.compile_at_backend_level()
    assert (
        os.environ["XLA_FLAGS"] == f"--xla_force_host_platform_device_count=2 "
        f"--xla_backend_optimization_level={runtime.BACKEND_OPTIMIZATION_LEVEL}"
    )
    monkeypatch.setenv("XLA_FLAGS", "--xla_backend_optimization_level=3")
    runtime.compile_at_backend_level()
    assert os.environ["XLA_FLAGS"] == "--xla_backend_optimization_level=3"

    code = LEVEL_RUN.format(tests=os.path.dirname(__file__))
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    runs = [  # side by side
        subprocess.Popen(
            [sys.executable, "-c", code],
            env={**env, **flags, "JAX_PLATFORMS": "cpu"},
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for flags in ({}, {"XLA_FLAGS": "--xla_backend_optimization_level=3"})
    ]
    (level_2, error_2), (level_3, error_3) = (run.communicate(timeout=300) for run in runs)
    assert all(run.returncode == 0 for run in runs), error_2[-3000:] + error_3[-3000:]
    assert level_2.split()[-1] == level_3.split()[-1]
