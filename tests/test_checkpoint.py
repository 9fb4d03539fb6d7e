import dataclasses
import os
import subprocess
import sys

import jax
import numpy as np
import pytest

from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.model import make_predict
from fabricjax.store.workspace import Location
from fabricjax.training import checkpoint
from fabricjax.training.train import restore, train_and_evaluate

TINY = Config(
    preset="smoke",
    modalities=("internal",),
    width=16,
    n_layers=1,
    ffn=32,
    audio_hidden=(16, 8),
    seq_len=8,
    epochs=4,
    batch_size=8,
)
SEEDS = [0, 7]


def data_sets():
    return {
        "train": synthetic.data_set(TINY, 16, seed=0),
        "val": synthetic.data_set(TINY, 8, seed=1),
        "test": synthetic.data_set(TINY, 8, seed=2),
    }


class Killed(Exception):
    pass


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    workdir = tmp_path_factory.mktemp("full")
    return workdir, train_and_evaluate(TINY, data_sets(), SEEDS, workdir=workdir, save_every=2)


def test_restore_one_seed_gives_identical_predictions(uninterrupted):
    workdir, res = uninterrupted
    graphdef, state, config, seeds, trained_for, _ = restore(workdir, TINY, seed=7)
    assert config == TINY and seeds == SEEDS
    assert trained_for == {
        "heads": ["fabric"],
        "n_classes": TINY.n_classes,
        "classes": None,
        "inputs": ["internal"],
        "preset": "smoke",
        "unseen_fabrics": [],
    }
    test = data_sets()["test"]["inputs"]
    restored = make_predict(graphdef)(state.best_params, test)["fabric"]
    trained = make_predict(res.graphdef)(res.params(1), test)["fabric"]
    np.testing.assert_array_equal(restored, trained)
    np.testing.assert_array_equal(np.argmax(restored, -1), res.metrics["eval"]["test"]["predictions"]["fabric"][1])


def test_restore_the_whole_stack(uninterrupted):
    workdir, res = uninterrupted
    saved = restore(workdir)  # under the config saved with the run
    assert saved.config == TINY and saved.seeds == SEEDS
    for a, b in zip(jax.tree.leaves(saved.state), jax.tree.leaves(res.state)):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(KeyError, match="seed 3"):
        restore(workdir, TINY, seed=3)


def test_resume_after_a_kill_reaches_the_uninterrupted_result(uninterrupted, tmp_path):
    _, full = uninterrupted
    saved = []

    def kill_after_first_save(epoch):
        saved.append(epoch)
        raise Killed

    with pytest.raises(Killed):
        train_and_evaluate(TINY, data_sets(), SEEDS, workdir=tmp_path, save_every=2, on_save=kill_after_first_save)
    assert saved == [2]
    resumed = train_and_evaluate(TINY, data_sets(), SEEDS, workdir=tmp_path, save_every=2, on_save=saved.append)
    assert saved == [2, 4]  # continued from epoch 2, did not start over
    # seed 0's best epoch came before the resume, so `finish` evaluates its validation set again
    # (`train.BestEpochValidation`); seed 7's is among the resumed epochs
    first, second = full.metrics["best_epoch"].tolist()
    assert first < 2 <= second  # epochs 0-1 ran before the kill, 2-3 after the resume
    # the per-epoch curves: the killed process's epochs from its checkpoint, every epoch's value
    # the uninterrupted run's (wall times are each process's own)
    outcome = lambda m: {k: v for k, v in m.items() if k not in ("epochs", "time")}  # noqa: E731
    for a, b in zip(jax.tree.leaves(outcome(resumed.metrics)), jax.tree.leaves(outcome(full.metrics))):
        np.testing.assert_array_equal(a, b)
    curves = resumed.metrics["epochs"], full.metrics["epochs"]
    for tag in set(curves[1]) - {"epoch_wall_s"}:
        np.testing.assert_array_equal(curves[0][tag], curves[1][tag], err_msg=tag)
    for a, b in zip(jax.tree.leaves(resumed.state), jax.tree.leaves(full.state)):
        np.testing.assert_array_equal(a, b)


def test_a_different_config_is_a_clear_error(uninterrupted):
    workdir, _ = uninterrupted
    other = dataclasses.replace(TINY, learning_rate=0.5, width=32)
    with pytest.raises(checkpoint.CheckpointMismatch, match=r"learning_rate.*width") as err:
        restore(workdir, other)
    assert str(workdir) in str(err.value)
    with pytest.raises(checkpoint.CheckpointMismatch, match="seeds"):
        train_and_evaluate(TINY, data_sets(), [0, 1], workdir=workdir)


def test_a_checkpoint_of_another_state_layout_is_refused_by_name():
    """A checkpoint saved before the optimiser state held the cosine decay's counter (no
    state_version: layout 1) is refused naming the field, not with an error from inside orbax;
    the studies' checkpoint folders are tagged with the layout, so they start afresh instead."""
    expected = checkpoint.meta(TINY, [0, 1], {"internal": (24,)})
    old = {k: v for k, v in expected.items() if k != "state_version"}
    with pytest.raises(
        checkpoint.CheckpointMismatch, match=f"state_version: saved 1, requested {checkpoint.STATE_VERSION}"
    ):
        checkpoint.check_meta("ckpt", old, expected)
    checkpoint.check_meta("ckpt", expected, expected)


def test_a_studys_checkpoint_folder_changes_with_the_code_and_the_data(monkeypatch, tmp_path):
    """A rerun after a change to the code, or on other data, trains afresh: the folder is tagged
    with the source's fingerprint and the data's contents, not only the config and seeds (a change
    in how training rounds, or a second dataset with the same classes, leaves both alike)."""
    from fabricjax import source
    from fabricjax.studies.machinery.checkpoints import checkpoint_dir

    cfg = Config.from_preset("smoke")
    data_a, data_b = {"folder": "a", "content": "1" * 16}, {"folder": "b", "content": "2" * 16}
    folder = checkpoint_dir("properties", "minsound", cfg, [0, 1], data_a, tmp_path)
    assert folder == checkpoint_dir("properties", "minsound", cfg, [0, 1], {**data_a, "folder": "moved"}, tmp_path)
    assert folder != checkpoint_dir("properties", "minsound", cfg, [0, 2], data_a, tmp_path)
    assert folder != checkpoint_dir("properties", "minsound", cfg, [0, 1], data_b, tmp_path)
    monkeypatch.setattr(source, "training", lambda: "other code")
    assert folder != checkpoint_dir("properties", "minsound", cfg, [0, 1], data_a, tmp_path)


def test_a_checkpoint_of_other_data_is_refused_naming_both_datasets():
    """Restoring a run onto other data is a one-line error naming both folders, never a reuse; a
    checkpoint that does not say its data is refused too."""
    cfg = Config.from_preset("smoke")
    trained = checkpoint.meta(cfg, [0], {"internal": (4, 8)}, dataset={"folder": "lab/a", "content": "1" * 16})
    other = checkpoint.meta(cfg, [0], {"internal": (4, 8)}, dataset={"folder": "lab/b", "content": "2" * 16})
    with pytest.raises(checkpoint.CheckpointMismatch, match=r"trained on lab/a .*not on lab/b") as e:
        checkpoint.check_meta("ckpt", trained, other)
    assert "\n" not in str(e.value)
    checkpoint.check_meta("ckpt", trained, {**trained, "dataset": {"folder": "moved/a", "content": "1" * 16}})
    with pytest.raises(checkpoint.WrongCheckpoint, match="does not record the data"):
        checkpoint.require_data("ckpt", {}, other["dataset"])


# Restores the checkpoint in argv[1] in a process with argv[2] CPU devices, or with argv[3] set
# first trains one there (on those devices), and prints a seed's test logits' sum.
ON_DEVICES = """
import sys
import jax
jax.config.update("jax_disable_most_optimizations", True)
import numpy as np
sys.path.insert(0, {tests!r})
from test_checkpoint import SEEDS, TINY, data_sets
from fabricjax.model import make_predict
from fabricjax.training.train import restore, train_and_evaluate
assert jax.device_count() == int(sys.argv[2])
if len(sys.argv) > 3:
    train_and_evaluate(TINY, data_sets(), SEEDS, workdir=sys.argv[1])
graphdef, state, *_ = restore(sys.argv[1], seed=7)
logits = make_predict(graphdef)(state.best_params, data_sets()["test"]["inputs"])["fabric"]
print("logits", repr(np.asarray(logits).tolist()))
"""


def on_devices(folder, devices: int, train: bool = False) -> np.ndarray:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env.update(JAX_PLATFORMS="cpu", XLA_FLAGS=f"--xla_force_host_platform_device_count={devices}")
    code = ON_DEVICES.format(tests=os.path.dirname(__file__))
    args = [sys.executable, "-c", code, str(folder), str(devices)] + (["train"] if train else [])
    out = subprocess.run(args, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    return np.asarray(eval(out.stdout.split("logits", 1)[1]))


@pytest.mark.slow  # ~17 s on 2 cores: another device count, in its own process
def test_a_checkpoint_restores_on_another_device_count(uninterrupted, tmp_path):
    """Saved on this process's one device, restored on two; saved on two, restored on one."""
    assert jax.device_count() == 1
    workdir, res = uninterrupted
    test = data_sets()["test"]["inputs"]
    trained = np.asarray(make_predict(res.graphdef)(res.params(1), test)["fabric"])
    np.testing.assert_allclose(on_devices(workdir, 2), trained, rtol=1e-6)
    two = on_devices(tmp_path / "two", 2, train=True)
    graphdef, state, *_ = restore(tmp_path / "two", seed=7)
    np.testing.assert_allclose(np.asarray(make_predict(graphdef)(state.best_params, test)["fabric"]), two, rtol=1e-6)


def test_a_path_without_a_checkpoint_is_one_line_and_creates_nothing(uninterrupted, tmp_path):
    workdir, _ = uninterrupted
    with pytest.raises(checkpoint.NoCheckpoint, match=f"no checkpoint at {tmp_path / 'typo'}: no such folder"):
        restore(tmp_path / "typo")
    assert not (tmp_path / "typo").exists()
    parent = workdir.parent
    before = sorted(parent.rglob("*"))
    with pytest.raises(
        checkpoint.NoCheckpoint, match=f"no checkpoint in {parent}; checkpoint folders inside it: .*{workdir.name}"
    ):
        restore(parent)
    assert sorted(parent.rglob("*")) == before


def test_a_checkpoint_made_for_another_job_is_refused_naming_both(uninterrupted, tmp_path):
    """Streaming needs a fabric head; latents a model that never saw the property holdouts."""
    from fabricjax.inference import live
    from fabricjax.studies.paper import latents

    properties_only = dataclasses.replace(TINY, fabric_head=False, property_heads=True, epochs=1)
    sets = {k: synthetic.data_set(properties_only, 8, seed=i) for i, k in enumerate(["train", "val"])}
    train_and_evaluate(properties_only, sets, [0], workdir=tmp_path / "properties")
    with pytest.raises(
        checkpoint.WrongCheckpoint,
        match=(
            rf"streaming needs a model with a fabric head .*; the checkpoint in {tmp_path / 'properties'} "
            rf"holds a model with "
            r"heads stretchiness\+roughness\+thickness, inputs internal"
        ),
    ):
        live.restore_model(tmp_path / "properties")
    workdir, _ = uninterrupted  # trained on every fabric
    with pytest.raises(
        checkpoint.WrongCheckpoint,
        match=r"latents needs a model that never saw the holdout fabrics 1, 10, 21, 22, 23 .*"
        r"heads fabric \(21 classes\), inputs internal, preset smoke, fabrics never seen: none",
    ):
        latents.run(workdir, where=Location(results=tmp_path / "results"))
    assert not (tmp_path / "results").exists()
