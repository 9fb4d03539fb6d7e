"""Training curves: what the jitted training returns per epoch is what TensorBoard shows."""

import json
import sys

import numpy as np
import pytest

from fabricjax import sim
from fabricjax.store import workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.paper import ablation
from fabricjax.training import curves
from fabricjax.training.train import train_and_evaluate
from tests.test_train import TINY, data_sets

pytest.importorskip("tensorboardX")

SEEDS = [3, 4]
HEADS = ("fabric", "stretchiness", "roughness", "thickness")
TAGS = {"train/loss", "lr", curves.WALL_TAG} | {f"{s}/accuracy/{h}" for s in ("train", "val") for h in HEADS}


def event_arrays(log_dir, seeds, tags):
    """{tag: (seeds, steps)} read back from each seed's event files."""
    read = [curves.read_scalars(curves.seed_dir(log_dir, s)) for s in seeds]
    return {t: np.array([[r[t][k] for k in sorted(r[t])] for r in read], np.float32) for t in tags}


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    log_dir = tmp_path_factory.mktemp("logs")
    return log_dir, train_and_evaluate(TINY, data_sets(TINY), SEEDS, log_dir=log_dir)


def test_the_curves_are_the_training_history_and_the_event_files_hold_them(logged):
    log_dir, res = logged
    m = res.metrics
    assert set(m["epochs"]) == TAGS
    assert all(v.shape == (len(SEEDS), TINY.epochs) for v in m["epochs"].values())
    np.testing.assert_array_equal(m["epochs"]["train/loss"], m["train_loss"])
    np.testing.assert_array_equal(m["epochs"]["val/accuracy/fabric"], m["val_acc"])  # the selection metric
    assert np.all(np.diff(m["epochs"]["lr"], axis=1) > 0)  # TINY's run lies inside the warm-up
    assert np.all((m["epochs"]["train/accuracy/roughness"] >= 0) & (m["epochs"]["train/accuracy/roughness"] <= 1))
    back = event_arrays(log_dir, SEEDS, TAGS)
    for tag in TAGS:
        np.testing.assert_array_equal(back[tag], m["epochs"][tag], err_msg=tag)
    assert sorted(curves.read_scalars(curves.seed_dir(log_dir, 3))["lr"]) == [1, 2, 3]  # steps are epochs from 1


def hide_tensorboardx(monkeypatch):
    """As if tensorboardX were not installed, in a process that has not yet said so."""
    for name in [m for m in sys.modules if m.split(".")[0] == "tensorboardX"]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setattr(curves, "_said_curves_are_off", False)


def test_without_tensorboardx_training_goes_on_without_curves(logged, tmp_path, monkeypatch, caplog):
    _, with_curves = logged
    hide_tensorboardx(monkeypatch)
    res = train_and_evaluate(TINY, data_sets(TINY), SEEDS, log_dir=tmp_path / "logs")
    assert not (tmp_path / "logs").exists()
    assert any(
        "tensorboardX is not installed" in r.getMessage() and '".[logs]"' in r.getMessage() for r in caplog.records
    )
    np.testing.assert_array_equal(
        res.metrics["eval"]["test"]["accuracy"]["fabric"], with_curves.metrics["eval"]["test"]["accuracy"]["fabric"]
    )
    # still one epoch per call, so each epoch's wall time is its own (not the run's mean, one value repeated)
    assert len(set(res.metrics["epochs"][curves.WALL_TAG][0])) == TINY.epochs


def test_missing_tensorboardx_is_said_once_per_process_not_once_per_row(tmp_path, monkeypatch, caplog):
    hide_tensorboardx(monkeypatch)
    for row in range(3):
        assert curves.open_writer(tmp_path / f"row{row}", SEEDS, 0) is None
    assert sum("training curves are off" in r.getMessage() for r in caplog.records) == 1


def test_a_resumed_run_appends_to_the_curves_of_the_interrupted_one(logged, tmp_path):
    _, uninterrupted = logged
    log_dir, ckpt = tmp_path / "logs", tmp_path / "ckpt"

    def stop(epoch):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_and_evaluate(TINY, data_sets(TINY), SEEDS, workdir=ckpt, save_every=1, on_save=stop, log_dir=log_dir)
    res = train_and_evaluate(TINY, data_sets(TINY), SEEDS, workdir=ckpt, save_every=1, log_dir=log_dir)
    # the epoch the interrupted process trained: from its checkpoint, as it was
    np.testing.assert_array_equal(res.metrics["epochs"]["train/loss"], uninterrupted.metrics["epochs"]["train/loss"])
    back = event_arrays(log_dir, SEEDS, TAGS - {curves.WALL_TAG})
    for tag, values in back.items():
        np.testing.assert_array_equal(values, uninterrupted.metrics["epochs"][tag], err_msg=tag)


def test_a_smoke_study_leaves_event_files_equal_to_the_curves_it_returns(tmp_path):
    sim.ensure_dataset("smoke", tmp_path, streams=("audio", "proprio"), progress=False)
    doc = ablation.run(
        n_seeds=2,
        rows=["internal"],
        preset="smoke",
        overrides=dict(epochs=2, width=16, n_layers=1),
        where=Location(workdir=tmp_path, results=tmp_path / "results", command="test"),
    )
    row = json.loads((tmp_path / "results" / "ablation.json").read_text())["rows"][0]
    assert row["epochs"] == doc["rows"][0]["epochs"]
    epochs = {t: np.array(v, np.float32) for t, v in row["epochs"].items()}
    assert set(epochs) == {"train/loss", "train/accuracy/fabric", "val/accuracy/fabric", "lr", curves.WALL_TAG}
    back = event_arrays(workspace.logs_dir("ablation", "internal", tmp_path), row["seeds"], epochs)
    for tag, values in epochs.items():
        assert values.shape == (2, 2)
        np.testing.assert_array_equal(back[tag], values, err_msg=tag)
    # the reported validation accuracy is the best epoch's
    np.testing.assert_array_equal(
        epochs["val/accuracy/fabric"].max(axis=1), np.array(row["accuracy"]["val"]["fabric"], np.float32)
    )
