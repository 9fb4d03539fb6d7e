"""A smoke trial in Rerun: `experiments.view --save` writes a .rrd the SDK reads back."""

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fabricjax import presets
from fabricjax.bench import synthetic
from fabricjax.features import welch
from fabricjax.inference import view
from fabricjax.sim.dataset import scene_for
from fabricjax.sim.trial import simulate
from fabricjax.store import archive
from fabricjax.store.workspace import Location
from fabricjax.studies.diagnostics import stream as stream_command
from fabricjax.training.train import train_and_evaluate
from tests.helpers import read_rrd
from tests.test_train import TINY

pytest.importorskip("rerun")

ROOT = Path(__file__).resolve().parents[1]
# streamable (Minsound + joints), a 6-step window, 54 PSD bins
CONFIG = dataclasses.replace(TINY, seq_len=6, bandwidth_khz=2.5, epochs=1)
SENSORS = (
    {"/minsight/frame", "/minsight/flow", "/force"}
    | {f"/audio/{m}/spectrogram" for m in archive.MIC_NAMES}
    | {f"/joints/{j}/{f}" for j in archive.JOINT_NAMES for f in archive.JOINT_FIELDS}
)
WAVES = {f"/audio/{m}/wave" for m in archive.MIC_NAMES}
# what a trial archive's own view adds: its session's no-contact reference (once) and each frame's difference to it
REFERENCE = {"/minsight/reference", "/minsight/difference"}
PREDICTION = {f"/prediction/{k}" for k in ("probabilities", "confidence", "class", "latency_ms")}
# what the viewer and the stream add from a checkpoint: the sequential rule's posterior, and its decision (logged once)
SEQUENTIAL = {"/prediction/posterior", "/prediction/decision"}


@pytest.fixture(scope="module")
def smoke_trial(tmp_path_factory):
    """The smoke preset's first trial, simulated with camera frames."""
    preset = presets.get("smoke").dataset
    trial = simulate(scene_for(preset.trials()[0], preset, ("audio", "proprio", "images")))
    return archive.write_archive(tmp_path_factory.mktemp("trial") / archive.trial_filename(trial.meta), trial), trial


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    ckpt = tmp_path_factory.mktemp("ckpt")
    bins = welch.n_bins(CONFIG.bandwidth_khz)
    sets = {
        k: synthetic.data_set(CONFIG, n, seed=i, psd_bins=bins) for i, (k, n) in enumerate([("train", 24), ("val", 10)])
    }
    train_and_evaluate(CONFIG, sets, [0], workdir=ckpt)
    return ckpt


def command(*args):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "experiments.view", *map(str, args)],
        env=env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.slow  # ~15 s on 2 cores: a Rerun recording written and read back
def test_view_save_writes_every_sensor_entity_at_every_step(smoke_trial, tmp_path):
    path, trial = smoke_trial
    out = command(path, f"--save={tmp_path / 'trial.rrd'}")
    assert out.returncode == 0, out.stderr
    assert f"{trial.n_steps} steps" in out.stdout
    read = read_rrd(tmp_path / "trial.rrd")
    assert set(read) == SENSORS | WAVES | REFERENCE
    for entity in SENSORS | {"/minsight/difference"}:
        assert read[entity]["steps"] == list(range(trial.n_steps)), entity
    assert read["/minsight/reference"]["steps"] == [0]
    new = np.diff(trial.window_end[:, 0])
    assert read["/audio/internal/wave"]["rows"] == archive.WINDOW + int(np.minimum(new, archive.WINDOW).sum())


@pytest.mark.slow  # ~30-55 s on 2 cores: run with -m slow
def test_view_save_with_a_checkpoint_adds_the_models_predictions(smoke_trial, checkpoint, tmp_path):
    path, trial = smoke_trial
    doc = view.view_archive(path, checkpoint=checkpoint, save=tmp_path / "trial.rrd")
    read = read_rrd(tmp_path / "trial.rrd")
    assert set(read) == SENSORS | WAVES | REFERENCE | PREDICTION | SEQUENTIAL
    decided = list(range(CONFIG.seq_len - 1, trial.n_steps))  # the window's first N - 1 steps only fill it
    assert read["/prediction/probabilities"]["steps"] == decided == read["/prediction/confidence"]["steps"]
    assert read["/prediction/posterior"]["steps"] == decided and len(read["/prediction/decision"]["steps"]) == 1
    assert read["/prediction/latency_ms"]["steps"] == list(range(trial.n_steps))
    assert doc["decided_steps"] == len(decided)


def test_without_the_sdk_a_one_line_error_says_what_to_install(smoke_trial, tmp_path):
    path, _ = smoke_trial
    code = (
        "import sys; sys.modules['rerun'] = None; sys.argv[0] = 'view'; from experiments import view; from "
        "fabricjax import cli; cli.run(view.main)"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", code, str(path), f"--save={tmp_path / 'x.rrd'}"],
        env=env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == ['error: viewing needs the Rerun SDK: pip install -e ".[viz]"']


@pytest.mark.slow  # ~30 s on 2 cores; the recorder's --view_save test covers live viewing by default
def test_stream_view_save_logs_each_steps_sensors_and_result(smoke_trial, checkpoint, tmp_path):
    path, trial = smoke_trial
    doc = stream_command.run(
        archive_path=path,
        checkpoint_dir=checkpoint,
        realtime=False,
        print_every=0,
        where=Location(results=tmp_path),
        out=lambda line: None,
        view_save=tmp_path / "stream.rrd",
    )
    read = read_rrd(tmp_path / "stream.rrd")
    assert set(read) == SENSORS | WAVES | PREDICTION | SEQUENTIAL
    assert read["/minsight/frame"]["steps"] == read["/prediction/latency_ms"]["steps"] == list(range(trial.n_steps))
    assert len(read["/prediction/probabilities"]["steps"]) == doc["decided_steps"]


@pytest.mark.slow  # ~15 s on 2 cores: a Rerun recording written and read back
def test_record_view_save_logs_the_trial_as_it_is_recorded(checkpoint, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    args = [
        "--fabric=12",
        "--trials=1",
        "--cycles=2",
        "--simulate",
        f"--out={tmp_path}",
        f"--view_save={tmp_path / 'rec.rrd'}",
        f"--checkpoint={checkpoint}",
    ]
    out = subprocess.run(
        [sys.executable, "-m", "acquisition.record", *args],
        env=env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    assert "connection ended" not in out.stderr + out.stdout  # the simulated Pi's end of stream is no news
    trial = archive.read_archive(next(tmp_path.glob("*.npz")), images=False)
    read = read_rrd(tmp_path / "rec.rrd")
    assert set(read) == SENSORS | WAVES | PREDICTION
    assert read["/force"]["steps"] == list(range(trial.n_steps))
    assert read["/prediction/confidence"]["steps"] == list(range(CONFIG.seq_len - 1, trial.n_steps))


@pytest.mark.parametrize(
    "module, args, save_flag",
    [
        ("experiments.view", ["{trial}"], "--save"),
        ("experiments.stream", ["--view", "--preset=smoke", "--workdir={tmp}"], "--view_save"),
        (
            "acquisition.record",
            ["--view", "--simulate", "--fabric=12", "--trials=1", "--cycles=2", "--out={tmp}/rec"],
            "--view_save",
        ),
    ],
)
def test_viewing_without_a_display_is_one_line_naming_the_save_flag(smoke_trial, tmp_path, module, args, save_flag):
    """No command waits for a viewer that cannot open: before any work, one line and status 2."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["PYTHONPATH"] = str(ROOT)
    args = [a.format(trial=smoke_trial[0], tmp=tmp_path) for a in args]
    out = subprocess.run(
        [sys.executable, "-m", module, *args], env=env, cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 2, out.stderr[-2000:]
    [line] = out.stderr.strip().splitlines()
    assert line.startswith("error: the Rerun viewer needs a display") and f"{save_flag}=FILE.rrd" in line
    assert not (tmp_path / "rec").exists()


def test_viewing_another_rigs_trial_is_one_line_saying_what_it_has(tmp_path):
    from fabricjax.errors import UserError
    from tests.test_rig_archive import rig_archive

    path = tmp_path / "rig.npz"
    archive.write_archive(path, rig_archive())
    with pytest.raises(
        UserError,
        match=r"rig\.npz: meta\.streams: the viewer shows the hand's streams .*; this trial has microphones: "
        r"vibration \(2200 Hz",
    ):
        view.view_archive(path, save=tmp_path / "rig.rrd")
    assert not (tmp_path / "rig.rrd").exists()
