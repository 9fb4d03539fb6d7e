"""Sequences from a rig unlike the hand (issue 26): the PSD at the microphone's own rate, the
band capped at its Nyquist, rows checked against the streams the data has, the classes from the
label map, and every trial not used said so."""

import logging

import numpy as np
import pytest
import scipy.signal

from fabricjax.config import Config
from fabricjax.errors import UserError
from fabricjax.features import welch
from fabricjax.sequences import data
from fabricjax.store import archive
from tests.helpers import tiny_dataset
from tests.test_rig_archive import rig_archive, rig_streams


def _config(**kw):
    return Config.from_preset("smoke", **kw)


def test_welch_at_another_rate_is_scipys():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(3, archive.WINDOW))
    ours = np.asarray(welch.welch_psd(x, bandwidth_khz=1.1, log=False, rate=2200))
    _, ref = scipy.signal.welch(x, **{**welch.SCIPY_KWARGS, "fs": 2200})
    np.testing.assert_allclose(ours, ref, rtol=1e-4)
    assert welch.n_bins(1.1, 2200) == welch.n_bins(15.0, 2200) == welch.N_BINS  # capped at Nyquist
    assert welch.n_bins(0.55, 2200) == 256 and welch.n_bins(15.0) == 320  # the hand's unchanged
    assert welch.frequencies(24.0, 2200)[-1] == pytest.approx(1100.0)


def _rig_dataset(folder, labels_splits, n_steps=60, streams=None):
    for t, (label, split) in enumerate(labels_splits):
        a = rig_archive(n_steps=n_steps, streams=streams, split=split)
        a.meta.update(label=label, trial=t, label_name=["oak", "pine", "felt"][label])
        archive.write_archive(folder / archive.trial_filename(a.meta), a)
    return folder


def test_rig_sequences_use_the_mics_rate_and_say_the_band_is_capped(tmp_path, caplog):
    ds = _rig_dataset(tmp_path / "ds", [(0, "train"), (1, "train"), (2, "val"), (0, "test")])
    with caplog.at_level(logging.WARNING):
        sets = data.load_sequences(
            _config(modalities=("internal", "proprio")), ds, workdir=tmp_path / "ws", progress=False
        )
    assert "above the vibration microphone's Nyquist (1.1 kHz at 2200 Hz)" in caplog.text
    # the paper's 42.67 ms at 2.2 kHz: 94 samples, hop 23, 24 bins ~47.8 Hz apart, said once
    assert caplog.text.count("step window is 94 samples at 2200 Hz: its PSD has only 24 bins") == 1
    assert sets["train"].inputs["internal"].shape[2] == welch.full_bins(94) == 24  # the whole 0-1.1 kHz band
    assert sets["train"].inputs["proprio"].shape[2] == 7 * 3
    assert sets["train"].classes == ("oak", "pine", "felt") and sets["train"].rates == {"internal": 2200}
    assert set(sets["test"].info["day"].tolist()) == {-1}
    narrowed = data.narrow(sets, _config(modalities=("internal",), bandwidth_khz=0.55))
    assert narrowed["train"].inputs["internal"].shape[2] == 12 and "proprio" not in narrowed["train"].inputs


def test_a_longer_step_window_is_chosen_by_duration(tmp_path, caplog):
    """--set mic_window_s: 2048 samples at 2.2 kHz (0.93 s) give the 512 bins of the paper's window length, unwarned."""
    ds = _rig_dataset(tmp_path / "ds", [(0, "train"), (1, "train"), (2, "val"), (0, "test")])
    config = _config(modalities=("internal",), mic_window_s=archive.WINDOW / 2200)
    with caplog.at_level(logging.WARNING):
        sets = data.load_sequences(config, ds, workdir=tmp_path / "ws", progress=False)
    assert "its PSD has only" not in caplog.text
    assert sets["train"].inputs["internal"].shape[2] == welch.N_BINS
    with pytest.raises(
        UserError, match=r"mic_window_s=0.001: the vibration microphone's window is 2 samples at 2200 Hz, too short"
    ):
        data.load_sequences(
            _config(modalities=("internal",), mic_window_s=0.001), ds, workdir=tmp_path / "ws", progress=False
        )


def _declaring(window_s):
    streams = rig_streams()
    streams["steps"]["mic_window_s"] = window_s
    return streams


def test_the_data_declares_its_step_window_and_set_overrides_it(tmp_path, caplog):
    """A rig file's steps.mic_window_s, recorded in the archives, is the window a config that leaves
    it unset (the default) loads with; an explicit mic_window_s wins, said once."""
    ds = _rig_dataset(
        tmp_path / "ds",
        [(0, "train"), (1, "train"), (2, "val"), (0, "test")],
        streams=_declaring(archive.WINDOW / 2200),
    )
    sets = data.load_sequences(_config(modalities=("internal",)), ds, workdir=tmp_path / "ws", progress=False)
    assert sets["train"].window_s == pytest.approx(archive.WINDOW / 2200)
    assert sets["train"].inputs["internal"].shape[2] == welch.N_BINS  # 2048 samples at 2.2 kHz
    assert (
        data.narrow(sets, _config(modalities=("internal",), bandwidth_khz=0.55))["train"].inputs["internal"].shape[2]
        == 256
    )
    with caplog.at_level(logging.INFO):
        short = data.load_sequences(
            _config(modalities=("internal",), mic_window_s=0.0427), ds, workdir=tmp_path / "ws", progress=False
        )
    assert short["train"].window_s == 0.0427 and short["train"].inputs["internal"].shape[2] == welch.full_bins(94) == 24
    assert caplog.text.count("mic_window_s=0.0427 s (the config's) is used, not the 0.930909 s the data declares") == 1


def test_trials_declaring_different_step_windows_are_refused(tmp_path):
    ds = _rig_dataset(tmp_path / "ds", [(0, "train"), (1, "train")], streams=_declaring(0.5))
    a = rig_archive(n_steps=60, streams=_declaring(0.25), split="test")
    a.meta.update(label=2, fabric_id=2, trial=9)
    archive.write_archive(ds / archive.trial_filename(a.meta), a)
    with pytest.raises(
        archive.ArchiveError,
        match=r"meta\.streams\.steps\.mic_window_s': 0\.5 s, but 0\.25 s in felt_trial009\.npz \(one step "
        r"window per dataset\)",
    ):
        data.load_sequences(_config(modalities=("internal",)), ds, workdir=tmp_path / "ws", progress=False)


@pytest.mark.parametrize("bad", [0, -0.1, "0.5", True, float("nan")])
def test_a_bad_declared_step_window_names_the_field(tmp_path, bad):
    a = rig_archive(streams=_declaring(bad))
    with pytest.raises(
        archive.ArchiveError, match=r"meta\.streams\.steps\.mic_window_s': must be a duration in seconds > 0"
    ):
        archive.validate_meta(a.meta, tmp_path / "t.npz")


def test_the_papers_hand_loads_with_its_2048_sample_window(tmp_path):
    """The hand's archives declare no window: the default config loads the paper's 2048 samples at 48 kHz."""
    ds = tiny_dataset(tmp_path / "hand", [(0, 1, 0, "lab"), (1, 1, 0, "lab")], n_steps=12, images=None)
    sets = data.load_sequences(
        _config(modalities=("internal",), seq_len=4),
        ds,
        workdir=tmp_path / "ws",
        progress=False,
        split_names=("train",),
    )
    assert Config().mic_window_s is None and sets["train"].window_s == archive.WINDOW / archive.AUDIO_RATE
    assert (
        data.window_of(Config(), archive.AUDIO_RATE)
        == welch.window_samples(sets["train"].window_s, archive.AUDIO_RATE)
        == archive.WINDOW
    )


def test_a_row_needing_a_stream_the_data_lacks_lists_what_it_has(tmp_path):
    ds = _rig_dataset(tmp_path / "ds", [(0, "train"), (1, "test")])
    with pytest.raises(archive.ArchiveError) as e:
        data.load_sequences(_config(modalities=("internal", "external")), ds, workdir=tmp_path / "ws", progress=False)
    msg = str(e.value)
    assert "\n" not in msg and "no external (palm mic)" in msg
    assert "vibration (2200 Hz, feeds internal)" in msg and "7 joints" in msg and "no camera" in msg
    assert not (tmp_path / "ws" / "features").exists() or not any((tmp_path / "ws" / "features").rglob("*.npz"))


def test_mics_at_different_rates_are_refused_for_the_shared_encoder(tmp_path):
    streams = rig_streams(mics=(("vibration", 2200, "internal"), ("room", 2200 * 2, "external")))
    ds = _rig_dataset(tmp_path / "ds", [(0, "train"), (1, "test")], streams=streams)
    with pytest.raises(Exception, match="different bin counts"):
        data.load_sequences(
            _config(modalities=("internal", "external"), bandwidth_khz=1.5), ds, workdir=tmp_path / "ws", progress=False
        )


def test_a_training_label_outside_the_classes_is_an_error(tmp_path):
    ds = tiny_dataset(tmp_path / "ds", [(4, 1, 0, "lab"), (21, 1, 0, "lab"), (4, 3, 0, "lab")], n_steps=45)
    with pytest.raises(
        archive.ArchiveError,
        match=r"fabric21_day1_trial00_lab\.npz: field 'meta.label': label 21 of a train trial is outside the 5 "
        r"classes 0..4",
    ):
        data.load_sequences(_config(), ds, workdir=tmp_path / "ws", progress=False)


def test_unused_trials_are_reported(tmp_path, caplog):
    ds = tiny_dataset(
        tmp_path / "ds", [(4, 1, 0, "lab"), (4, 7, 0, "lab"), (4, 3, 0, "lab"), (22, 3, 0, "lab")], n_steps=45
    )
    with caplog.at_level(logging.INFO):
        sets = data.load_sequences(_config(), ds, workdir=tmp_path / "ws", progress=False)
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "1 trials belong to no split and are not used (days 7" in warnings[0]
    # the hand's new fabric on the test day is said as what it is, not warned about
    assert (
        "the test day's new fabrics 22 (1 test trial) have no training trials: they are the property study's holdouts"
        in caplog.text
    )
    assert len(sets["test"]) > 0


def test_trials_of_splits_a_study_does_not_read_are_counted(tmp_path, caplog):
    ds = _rig_dataset(tmp_path / "ds", [(0, "train"), (1, "train"), (2, "val"), (0, "test"), (1, "cafe"), (2, "cafe")])
    with caplog.at_level(logging.INFO):
        sets = data.load_sequences(
            _config(modalities=("proprio",)),
            ds,
            workdir=tmp_path / "ws",
            progress=False,
            split_names=("train", "val", "test"),
        )
    assert "2 trials on split cafe are not used by this study (it reads train, val, test)" in caplog.text
    assert set(sets) == {"train", "val", "test"}


def test_label_maps_must_agree(tmp_path):
    ds = _rig_dataset(tmp_path / "ds", [(0, "train"), (1, "test")])
    other = rig_archive(split="train")
    other.meta.update(label_map={"oak": 0, "pine": 1, "felt": 2, "silk": 3}, trial=9)
    archive.write_archive(ds / archive.trial_filename(other.meta), other)
    with pytest.raises(archive.ArchiveError, match="meta.label_map.*differs"):
        data.load_sequences(_config(), ds, workdir=tmp_path / "ws", progress=False)


def test_reproduce_on_a_rig_runs_what_its_streams_and_splits_allow(tmp_path):
    """A camera-less rig without cafe or holdout trials: the ablation and probe keep the rows of its
    streams, the bandwidth study runs whole, the protocol's studies are skipped, one line each."""
    from fabricjax.studies.paper import ablation
    from fabricjax.studies.release import reproduce_plan

    ds = _rig_dataset(tmp_path / "ds", [(0, "train"), (1, "train"), (2, "val"), (0, "test")])
    said = []
    plan = {s.study: s for s in reproduce_plan.fit_plan(reproduce_plan.PLAN, "smoke", ds, tmp_path / "ws", said.append)}
    assert list(plan) == ["ablation", "probe", "day_shift", "bandwidth", "decide"]
    assert plan["decide"].rows == ("internal",)  # of its rows, the one the ablation trains here
    assert set(plan["ablation"].rows) == {r.name for r in ablation.ROWS if set(r.modalities) <= {"internal", "proprio"}}
    assert plan["bandwidth"].rows is None
    text = "\n".join(said)
    assert len(said) == 8 and "ablation" in said[0] and "rows left out (they need external, flow, image" in said[0]
    assert "noise       skip  (the paper's protocol: it needs trials of the cafe condition (split cafe)" in text
    assert "properties  skip  (the paper's protocol: it needs held-out fabrics (split holdout)" in text
    assert "latents     skip" in text
    assert "camera_frames skip  (it draws the simulator's frames, not the data's)" in text
    assert "flow_budget skip  (it draws the simulator's frames, not the data's)" in text
