"""Batch import of a rig unlike the hand (issue 26): one vibration channel at 2.2 kHz, 7 joints
with torque, no camera, no palm microphone, string labels, no days."""

import csv
import dataclasses
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fabricjax.errors import UserError
from fabricjax.importers import batch, example_rig, manifest_file
from fabricjax.store import archive
from fabricjax.store.workspace import Location

LABELS = ["cotton canvas", "felt", "oak"]
SPLITS = {0: "train", 1: "train", 2: "val", 3: "test"}


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    return example_rig.write_recordings(tmp_path_factory.mktemp("rig"), LABELS, 4, splits=SPLITS)


@pytest.fixture(scope="module")
def archives(recordings, tmp_path_factory):
    """The recordings imported as they are (the studies below only read them)."""
    out = tmp_path_factory.mktemp("imported") / "archives"
    _run(recordings, out)
    return out


def _run(manifest, out, **kw):
    said = []
    summary = batch.run(
        manifest, out, rig=manifest.parent / "rig.toml", workers=1, progress=False, say=said.append, **kw
    )
    return summary, "\n".join(said)


def test_one_command_imports_the_rig_as_it_is(recordings, tmp_path):
    out = tmp_path / "archives"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "experiments.import_manifest",
            str(recordings),
            f"--out={out}",
            f"--rig={recordings.parent / 'rig.toml'}",
        ],
        capture_output=True,
        text=True,
        cwd=Path(__file__).parents[1],
    )
    assert proc.returncode == 0, proc.stderr
    assert "12 trials imported" in proc.stdout and "3 classes" in proc.stdout
    assert "gripper_temperature (12 trials)" in proc.stdout  # the column the rig file does not name is reported
    files = sorted(p.name for p in out.glob("*.npz"))
    assert files[0] == "cotton_canvas_trial000.npz" and len(files) == 12
    a = archive.read_archive(out / "felt_trial003.npz")
    lay = archive.layout(a.meta)
    assert [(m.name, m.rate, m.role) for m in lay.mics] == [("vibration", 2200, "internal")]
    assert lay.joint_names == tuple(f"arm_{k}" for k in range(7)) and lay.joint_units == ("rad", "rad/s", "N m")
    assert lay.image_size is None and a.images is None and a.force is None
    assert a.audio.shape[0] == 1 and a.joints.shape[1:] == (7, 3)
    assert lay.step_clock == "rate" and lay.step_rate == 50
    assert np.allclose(np.diff(a.timestamps), 0.02)
    # the first step has a full 2048-sample window at 2.2 kHz, and nothing was resampled
    assert a.window_end[0, 0] >= archive.WINDOW and a.meta["import"]["steps_dropped_before_start"] > 0
    assert a.meta["label_map"] == {"cotton canvas": 0, "felt": 1, "oak": 2} and a.meta["label"] == 1
    assert a.meta["label_name"] == "felt" and a.meta["split"] == "test" and a.meta["day"] is None
    assert a.meta["properties"] == {}  # nothing stamped from the fabric catalog
    assert a.meta["import"]["ignored_columns"] == ["gripper_temperature"]


def test_a_rigs_class_is_stored_as_its_class_and_no_condition_is_made_up(archives):
    """A rig's recordings (LMT-108's materials, say) touch no fabric of our catalog and name no lab
    or cafe: the archive holds the class as the label map's (label, label_name), no fabric_id,
    and no condition where the manifest gives none."""
    (path,) = archives.glob("felt_trial003*.npz")
    meta = archive.read_meta(path)[0]
    assert "fabric_id" not in meta and (meta["label"], meta["label_name"]) == (1, "felt")
    assert meta["condition"] is None and path.name == "felt_trial003.npz"
    assert archive.fabric_or_class(meta) == 1  # what the studies group trials by


def test_a_condition_the_manifest_gives_is_kept(recordings, tmp_path):
    manifest = _edit_manifest(
        recordings,
        recordings.parent / "conditions.csv",
        lambda rows: [r + ["condition" if i == 0 else "cafe" if r[1] == "oak" else ""] for i, r in enumerate(rows)],
    )
    _run(manifest, tmp_path / "out")
    assert archive.read_meta(tmp_path / "out" / "oak_trial000_cafe.npz")[0]["condition"] == "cafe"
    assert archive.read_meta(tmp_path / "out" / "felt_trial000.npz")[0]["condition"] is None


def test_an_archive_that_stored_the_class_as_a_fabric_and_lab_still_reads(archives, tmp_path):
    """Rig archives that carry fabric_id (the class) and condition "lab" read, and group, as before."""
    a = archive.read_archive(archives / "felt_trial003.npz")
    old = archive.write_archive(
        tmp_path / "felt_trial003_lab.npz",
        dataclasses.replace(a, meta={**a.meta, "fabric_id": a.meta["label"], "condition": "lab"}),
    )
    meta = archive.read_archive(old).meta
    assert meta["fabric_id"] == meta["label"] == archive.fabric_or_class(meta) == 1


def test_a_trial_without_a_label_map_needs_its_fabric(archives, tmp_path):
    a = archive.read_archive(next(archives.glob("felt_trial003*.npz")))
    meta = {k: v for k, v in a.meta.items() if k not in ("label_map", "label_name")}
    with pytest.raises(archive.ArchiveError, match="meta.fabric_id.*missing") as e:
        archive.write_archive(tmp_path / "x.npz", dataclasses.replace(a, meta=meta))
    assert "\n" not in str(e.value)


def test_rerun_resumes_and_a_foreign_archive_needs_overwrite(recordings, tmp_path):
    out = tmp_path / "archives"
    first, _ = _run(recordings, out)
    assert first["imported"] == 12
    again, said = _run(recordings, out)
    assert again["imported"] == 0 and again["resumed"] == 12 and "12 already there (resumed)" in said
    victim = out / "oak_trial000.npz"
    foreign = archive.read_archive(out / "oak_trial001.npz")
    archive.write_archive(victim, foreign)  # an archive of another recording under this row's name
    before = victim.read_bytes()
    with pytest.raises(
        UserError,
        match="oak_trial000.npz: exists, but was imported from .*02_001, not from .*02_000 as line 10 says; "
        "pass --overwrite",
    ):
        _run(recordings, out)
    assert victim.read_bytes() == before
    replaced, _ = _run(recordings, out, overwrite=True)
    assert replaced["imported"] == 12
    assert archive.read_meta(victim)[0]["source"]["path"].endswith("02_000")


def test_fraction_rule_splits_each_class_in_trial_order(tmp_path):
    manifest = example_rig.write_recordings(tmp_path / "rig", LABELS[:2], 4, seconds=(2.0, 2.5))
    summary, _ = _run(manifest, tmp_path / "out", split="fraction:0.5,0.25,0.25")
    assert summary["splits"] == {"train": 4, "val": 2, "test": 2}
    assert archive.read_meta(tmp_path / "out" / "felt_trial003.npz")[0]["split"] == "test"
    assert archive.read_meta(tmp_path / "out" / "felt_trial000.npz")[0]["split"] == "train"


def test_trial_rule_splits_every_class_by_trial_index(tmp_path):
    manifest = example_rig.write_recordings(tmp_path / "rig", LABELS[:2], 4, seconds=(2.0, 2.5))
    summary, _ = _run(manifest, tmp_path / "out", split="trial:train=0-1,val=2,test=3")
    assert summary["splits"] == {"train": 4, "val": 2, "test": 2}
    assert [archive.read_meta(tmp_path / "out" / f"felt_trial00{k}.npz")[0]["split"] for k in range(4)] == [
        "train",
        "train",
        "val",
        "test",
    ]
    with pytest.raises(
        UserError, match=r"manifest\.csv: line \d+: trial: trial 3 is in no range of --split=trial:train=0-1,val=2"
    ):
        _run(manifest, tmp_path / "out2", split="trial:train=0-1,val=2")
    for bad in ("trial:train=0-2,val=2", "trial:train=3-1", "trial:dev=0-3", "trial:train=0-x"):
        with pytest.raises(UserError, match=f"--split={bad}: expected trial:SPLIT=FIRST-LAST"):
            manifest_file.parse_split_rule(bad)
    assert manifest_file.parse_split_rule("trial:test=2,train=0-1") == ("trial", {2: "test", 0: "train", 1: "train"})


def _edit_manifest(manifest, out_path, change):
    rows = list(csv.reader(open(manifest)))
    rows = change(rows)
    with open(out_path, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    return out_path


def test_silent_cases_are_messages(recordings, tmp_path):
    out = tmp_path / "out"
    # no split and no day: every trial would be unused
    no_split = _edit_manifest(recordings, recordings.parent / "no_split.csv", lambda rows: [r[:3] for r in rows])
    with pytest.raises(UserError, match=r"no_split\.csv: line 2: split: no split and no day"):
        _run(no_split, out)
    # a label outside the label map
    labels = tmp_path / "labels.csv"
    labels.write_text("name,class\ncotton canvas,0\nfelt,1\n")
    with pytest.raises(UserError, match=r"line \d+: label: 'oak' is not in the label map"):
        _run(recordings, out, labels=labels)
    # a manifest column nobody reads
    extra = _edit_manifest(
        recordings,
        recordings.parent / "extra.csv",
        lambda rows: [r + (["notes"] if i == 0 else ["x"]) for i, r in enumerate(rows)],
    )
    _, said = _run(extra, out)
    assert "columns not used: notes" in said
    # two rows naming one archive
    shutil.copytree(
        recordings.parent / "recordings" / "00_000", recordings.parent / "recordings" / "extra", dirs_exist_ok=True
    )
    dup = _edit_manifest(
        recordings, recordings.parent / "dup.csv", lambda rows: rows + [["recordings/extra", *rows[1][1:]]]
    )
    with pytest.raises(
        UserError, match=r"dup\.csv: line 14: trial: gives the archive cotton_canvas_trial000\.npz, as line 2 does"
    ):
        _run(dup, tmp_path / "out2")
    with pytest.raises(UserError, match="--split=fraction:0.5,0.5,0.5: expected"):
        _run(no_split, tmp_path / "out3", split="fraction:0.5,0.5,0.5")


def test_rig_file_mistakes_are_named(tmp_path):
    from fabricjax.importers import rig_folder

    bad = tmp_path / "rig.toml"
    bad.write_text('[[mics]]\nname = "v"\nfile = "v.wav"\nrole = "palm"\n[steps]\nrate = 50\n')
    with pytest.raises(UserError, match=r"rig\.toml: mics\[0\]\.role: must be one of"):
        rig_folder.load_rig(bad)
    bad.write_text('[[mics]]\nname = "v"\nfile = "v.wav"\n')
    with pytest.raises(UserError, match=r"steps\.rate: missing: without a camera or joints"):
        rig_folder.load_rig(bad)
    for value in ("0", "-1.5", '"0.5"', "true", "nan", "inf"):
        bad.write_text(f'[[mics]]\nname = "v"\nfile = "v.wav"\n[steps]\nrate = 50\nmic_window_s = {value}\n')
        with pytest.raises(UserError, match=r"rig\.toml: steps\.mic_window_s: must be a duration in seconds > 0, got"):
            rig_folder.load_rig(bad)
    bad.write_text('[[mics]]\nname = "v"\nfile = "v.wav"\n[steps]\nrate = 50\nwindow = 0.5\n')
    with pytest.raises(UserError, match=r"rig\.toml: steps\.window: unknown key \(known: rate, mic_window_s\)"):
        rig_folder.load_rig(bad)
    for camera, words in [
        ('reference_topic = "/ref"', r"camera\.reference_topic: unknown key \(known: reference, reference_frames\)"),
        ('reference = "ref.txt"', r"camera\.reference: 'ref\.txt': a reference file is an image, a video or a \.npy"),
        (
            'reference = "ref.png"\nreference_frames = 3',
            r"camera\.reference_frames: given with a named source \(ref\.png\)",
        ),
    ]:
        bad.write_text(f'[[mics]]\nname = "v"\nfile = "v.wav"\n[camera]\n{camera}\n')
        with pytest.raises(UserError, match=rf"rig\.toml: {words}"):
            rig_folder.load_rig(bad)
    with pytest.raises(
        UserError,
        match=r"--reference names the session reference of the hand's trial folders; a rig file names its camera's own",
    ):
        batch.run(tmp_path / "manifest.csv", tmp_path / "out", rig=bad, reference="pre_contact")


def test_the_rig_files_step_window_is_recorded_and_loads_by_default(tmp_path):
    """steps.mic_window_s: in every archive's meta, full from the first step, and the window the
    default config loads (3072 samples at 2.2 kHz: 767 bins)."""
    from fabricjax.config import Config
    from fabricjax.features import welch
    from fabricjax.sequences import data

    window_s = archive.WINDOW * 1.5 / example_rig.VIBRATION_RATE
    toml = example_rig.RIG_TOML.replace(
        f"rate = {example_rig.STEP_RATE}\n", f"rate = {example_rig.STEP_RATE}\nmic_window_s = {window_s!r}\n"
    )
    _run(_rig_manifest(tmp_path / "rig", toml), tmp_path / "out")
    a = archive.read_archive(tmp_path / "out" / "cotton_canvas_trial000.npz")
    assert archive.layout(a.meta).mic_window_s == window_s
    assert a.window_end[0, 0] >= 1.5 * archive.WINDOW  # the longer window is full at the first step
    config = Config.from_preset("smoke", modalities=("internal",), seq_len=4)
    sets = data.load_sequences(
        config, tmp_path / "out", workdir=tmp_path / "ws", progress=False, split_names=("train",)
    )
    assert (
        sets["train"].window_s == window_s and sets["train"].inputs["internal"].shape[2] == welch.full_bins(3072) == 767
    )


@pytest.mark.slow  # ~1-3 min on 2 shared cores: import and two smoke-size rows
def test_a_study_trains_and_tests_on_the_imported_rig(archives, tmp_path, capsys):
    from fabricjax.studies.paper import ablation

    names = sorted(p.name for p in archives.iterdir())
    doc = ablation.run(
        n_seeds=1,
        rows=["proprio", "internal+proprio"],
        preset="smoke",
        where=Location(workdir=tmp_path / "ws", data_dir=archives, results=tmp_path / "results", command="test"),
    )
    assert sorted(p.name for p in archives.iterdir()) == names  # the data folder is only read: no invented files
    printed = capsys.readouterr().out
    assert (
        "recorded data" in printed
        and "train 6 trials /" in printed
        and "val 3 trials /" in printed
        and "test 3 trials /" in printed
    )
    assert doc["dataset"]["classes"] == LABELS and doc["dataset"]["trials"] == {"train": 6, "val": 3, "test": 3}
    for row in doc["rows"]:
        assert row["config"]["n_classes"] == 3 and "paper_mean" not in row
        acc = np.asarray(row["accuracy"]["test"]["fabric"])
        assert acc.shape == (1,) and np.isfinite(acc).all()
    assert doc["findings"] == []
    md = (tmp_path / "results" / "ablation.md").read_text()
    assert "recorded data" in md and "chance 33.3 %" in md and "Row − best row" in md
    assert "paper" not in md.lower() and "simulat" not in md.lower()


def test_a_row_the_rig_cannot_feed_is_refused_before_training(archives, tmp_path):
    from fabricjax.studies.paper import ablation

    with pytest.raises(
        archive.ArchiveError,
        match=r"field 'audio': absent: the data has no external \(palm mic\).*it has microphones: vibration",
    ):
        ablation.run(
            n_seeds=1,
            rows=["internal+external"],
            preset="smoke",
            where=Location(workdir=tmp_path / "ws", data_dir=archives, results=tmp_path / "results", command="test"),
        )
    assert not (tmp_path / "results" / "ablation.md").exists()


def test_the_probe_reads_the_imported_rig(archives, tmp_path):
    from fabricjax.studies.diagnostics import probe

    doc = probe.run(
        rows=["proprio", "internal"],
        preset="smoke",
        where=Location(workdir=tmp_path / "ws", data_dir=archives, results=tmp_path / "results", command="test"),
    )
    assert doc["splits"] == ["train", "val", "test"] and doc["classes"] == [
        0,
        1,
        2,
    ]  # no cafe trials: no cafe column filled
    assert (
        doc["inputs"]["proprio"]["step_dims"] == 7 * 3 and doc["inputs"]["internal"]["step_dims"] == 24
    )  # 42.67 ms at 2.2 kHz: 94 samples
    assert all(0 <= r["accuracy"]["test"] <= 1 for r in doc["rows"])
    md = (tmp_path / "results" / "probe.md").read_text()
    assert "recorded data" in md and "chance 33.3 %" in md and "(recorded data, read as it is)" in md
    assert "simulat" not in md.lower()


def test_the_bandwidth_plot_names_the_rigs_microphone(archives, tmp_path):
    from fabricjax.studies.machinery import loading
    from fabricjax.studies.paper import bandwidth

    assert bandwidth.microphone(loading.Dataset({}, archives, "recorded", 0.0, 0.0, tmp_path / "ws")) == "vibration"
    assert bandwidth.microphone(loading.Dataset({}, archives, "simulated", 0.0, 0.0)) == "Minsound"


def test_import_benchmark_entry_and_row(tmp_path, monkeypatch):
    """The suite times the library's own batch import (here at a test's size)."""
    from fabricjax.bench import suite as bench

    full = example_rig.bench_import
    monkeypatch.setattr(example_rig, "bench_import", lambda trials: full(trials=20, seconds=(2.0, 3.0), workers=1))
    doc = bench.run(only=["import"], where=Location(results=tmp_path, command="test"), out=lambda s: None)
    entry = doc["benchmarks"]["import"]
    assert entry["trials"] == 20 and entry["steps"] > 0 and entry["wall_s"] > 0
    assert "batch import, 20 trials of 2-3 s" in (tmp_path / "bench.md").read_text()


def _rig_manifest(root, rig_toml, labels=LABELS[:1], trials=1, seconds=(2.0, 2.0), splits=None):
    """A rig's recordings (`example_rig`) under another rig file: its step clock or microphones."""
    manifest = example_rig.write_recordings(
        root, labels, trials, seconds, splits=splits or {k: "train" for k in range(trials)}
    )
    (root / "rig.toml").write_text(rig_toml)
    return manifest


def test_without_a_camera_or_a_rate_the_joints_timestamps_are_the_steps(tmp_path):
    manifest = _rig_manifest(
        tmp_path / "rig", example_rig.RIG_TOML.replace(f"[steps]\nrate = {example_rig.STEP_RATE}\n", "")
    )
    _run(manifest, tmp_path / "out")
    a = archive.read_archive(tmp_path / "out" / "cotton_canvas_trial000.npz")
    lay = archive.layout(a.meta)
    assert lay.step_clock == "joints" and lay.step_rate == example_rig.JOINT_RATE
    np.testing.assert_allclose(np.diff(a.timestamps), 1 / example_rig.JOINT_RATE, atol=1e-9)
    # every step is one joint reading, as read (no interpolation): the rows from the first usable one
    table = np.loadtxt(tmp_path / "rig" / "recordings" / "00_000" / "joints.csv", delimiter=",", skiprows=1)
    first = a.meta["import"]["steps_dropped_before_start"]
    assert first == int(
        np.ceil(archive.WINDOW / example_rig.VIBRATION_RATE * example_rig.JOINT_RATE)
    )  # a full 2048-sample window
    rows = table[first : first + a.n_steps, 1:-1].reshape(a.n_steps, example_rig.N_JOINTS, 3)
    np.testing.assert_allclose(a.joints, rows.astype(np.float32))
    step_t = table[first : first + a.n_steps, 0]
    np.testing.assert_array_equal(
        a.window_end[:, 0], np.floor(step_t * example_rig.VIBRATION_RATE + 1e-9).astype(np.int64) + 1
    )


def test_a_cameras_timestamps_are_the_steps_at_its_own_frame_rate(tmp_path):
    import cv2

    manifest = _rig_manifest(
        tmp_path / "rig", example_rig.RIG_TOML + '\n[camera]\nreference = "pre_contact"\nreference_frames = 2\n'
    )
    folder = tmp_path / "rig" / "recordings" / "00_000"
    frames = np.random.default_rng(1).integers(0, 255, size=(12, 6, 8, 3), dtype=np.uint8)
    (folder / "camera").mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / "camera" / f"{i:04d}.png"), cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    frame_t = 1.0005 + np.arange(len(frames)) / 30  # 30 fps, from after the first full window
    np.savetxt(folder / "frames.csv", frame_t, header="time", comments="", fmt="%.6f")
    _run(manifest, tmp_path / "out")  # the declared rate gives way to the camera's frames
    a = archive.read_archive(tmp_path / "out" / "cotton_canvas_trial000.npz")
    lay = archive.layout(a.meta)
    assert lay.step_clock == "camera" and lay.step_rate == pytest.approx(30.0, abs=1e-3) and lay.image_size == (6, 8)
    np.testing.assert_allclose(a.timestamps, frame_t - frame_t[0], atol=1e-6)
    np.testing.assert_array_equal(a.images, frames)
    np.testing.assert_array_equal(
        a.window_end[:, 0], np.floor(frame_t * example_rig.VIBRATION_RATE).astype(np.int64) + 1
    )
    assert "image" in lay.modalities() and "flow" in lay.modalities()
    np.testing.assert_array_equal(a.reference, frames[:2])  # the rig file asks for the trial's first frames
    assert a.meta["reference"] == {
        "how": "imported: the trial's first 2 frames (pre-contact, as the rig file asks)",
        "session": "cotton_canvas_trial000",
        "times_s": pytest.approx([0.0, 1 / 30], abs=1e-6),
    }  # no days: the trial's own name
    # a reference file the rig file names, and the manifest's session column; the rig file must name one
    np.save(folder / "reference.npy", frames[-1])
    (tmp_path / "rig" / "rig.toml").write_text(example_rig.RIG_TOML + '\n[camera]\nreference = "reference.npy"\n')
    _edit_manifest(
        manifest, manifest, lambda rows: [r + ["session" if i == 0 else "bench 2"] for i, r in enumerate(rows)]
    )
    _run(manifest, tmp_path / "out2")
    b = archive.read_archive(tmp_path / "out2" / "cotton_canvas_trial000.npz")
    np.testing.assert_array_equal(b.reference, frames[-1:])
    assert b.meta["reference"] == {
        "how": "imported: 1 frame of the file reference.npy (relative to the trial folder)",
        "session": "bench 2",
        "times_s": None,
    }
    (tmp_path / "rig" / "rig.toml").write_text(example_rig.RIG_TOML + '\n[camera]\nreference = "pre_contact"\n')
    with pytest.raises(
        UserError,
        match=r"exists, but its camera reference was read from reference\.npy, not from pre_contact: the first 5 "
        r"frames",
    ):
        _run(manifest, tmp_path / "out2")  # a rerun notices the rig file's new reference
    (tmp_path / "rig" / "rig.toml").write_text(example_rig.RIG_TOML + "\n[camera]\n")
    with pytest.raises(UserError) as e:
        _run(manifest, tmp_path / "out3")
    assert str(e.value) == (
        f"{tmp_path / 'rig' / 'rig.toml'}: camera.reference: missing: a camera needs its session's "
        f"no-contact reference: name the "
        'file of the trial folder that holds it (set reference = "reference.png"), or set reference = '
        '"pre_contact" to use the trial\'s first frames'
    )
    assert not (tmp_path / "out3").exists()


def test_two_microphones_at_their_own_rates_each_give_their_own_psd(tmp_path):
    from scipy.io import wavfile

    from fabricjax.config import Config
    from fabricjax.features import welch
    from fabricjax.sequences import data

    room = example_rig.RIG_TOML.replace(
        "[joints]", '[[mics]]\nname = "room"\nfile = "room.wav"\nrole = "external"\n\n[joints]'
    )
    manifest = _rig_manifest(tmp_path / "rig", room, labels=LABELS[:2], trials=2, splits={0: "train", 1: "test"})
    rng = np.random.default_rng(2)
    for folder in (tmp_path / "rig" / "recordings").iterdir():  # white noise of one level in both microphones
        wavfile.write(folder / "vibration.wav", 2200, rng.normal(0, 2**12, 2 * 2200).astype(np.int16))
        wavfile.write(folder / "room.wav", 4400, rng.normal(0, 2**12, 2 * 4400).astype(np.int16))
    _run(manifest, tmp_path / "out")
    lay = archive.layout(archive.read_meta(tmp_path / "out" / "felt_trial001.npz")[0])
    assert [(m.name, m.rate, m.role) for m in lay.mics] == [("vibration", 2200, "internal"), ("room", 4400, "external")]
    # one step window (42.67 ms): 94 and 188 samples, bins ~47 Hz apart in both, 21 up to 1 kHz
    config = Config.from_preset("smoke", modalities=("internal", "external"), bandwidth_khz=1.0, seq_len=10)
    sets = data.load_sequences(config, tmp_path / "out", workdir=tmp_path / "ws", progress=False)
    for mic, rate in (("internal", 2200), ("external", 4400)):
        assert sets["train"].inputs[mic].shape[2] == welch.n_bins(1.0, rate, data.window_of(config, rate)) == 21
    assert sets["train"].rates == {"internal": 2200, "external": 4400}
    # one noise level: the density (per Hz) of the microphone at half the rate is twice as high
    level = {m: np.mean(sets["train"].inputs[m][..., 1:-1]) for m in ("internal", "external")}
    assert level["internal"] - level["external"] == pytest.approx(np.log10(2), abs=0.02)


def test_a_labels_file_sets_the_classes_and_their_count(recordings, tmp_path):
    from fabricjax.config import Config
    from fabricjax.sequences import data

    labels = tmp_path / "labels.csv"  # two names, one class; the classes in the file's order, not sorted
    labels.write_text("name,class\noak,0\nfelt,1\ncotton canvas,1\n")
    summary, said = _run(recordings, tmp_path / "out", labels=labels)
    assert summary["classes"] == 2 and "; 2 classes" in said
    meta = archive.read_meta(tmp_path / "out" / "felt_trial003.npz")[0]
    assert (
        meta["label_map"] == {"oak": 0, "felt": 1, "cotton canvas": 1}
        and meta["label"] == 1
        and meta["label_name"] == "felt"
    )
    assert archive.read_meta(tmp_path / "out" / "oak_trial000.npz")[0]["label"] == 0
    sets = data.load_sequences(
        Config.from_preset("smoke", modalities=("proprio",)),
        tmp_path / "out",
        workdir=tmp_path / "ws",
        progress=False,
        split_names=("train", "test"),
    )
    assert sets["train"].classes == ("oak", "cotton canvas / felt") and sets["train"].n_classes == 2
    assert set(sets["test"].labels["fabric"].tolist()) == {0, 1}


def test_property_columns_give_levels_only_where_given(tmp_path):
    from fabricjax.config import Config
    from fabricjax.sequences import data

    manifest = example_rig.write_recordings(
        tmp_path / "rig", LABELS[:2], 2, seconds=(2.0, 2.0), splits={0: "train", 1: "test"}
    )
    levels = {"cotton canvas": ("1", "3", ""), "felt": ("0", "", "")}  # stretchiness, roughness, thickness
    _edit_manifest(
        manifest,
        manifest,
        lambda rows: [
            r + (["stretchiness", "roughness", "thickness"] if i == 0 else list(levels[r[1]]))
            for i, r in enumerate(rows)
        ],
    )
    _run(manifest, tmp_path / "out")
    assert archive.read_meta(tmp_path / "out" / "cotton_canvas_trial001.npz")[0]["properties"] == {
        "stretchiness": 1,
        "roughness": 3,
    }
    assert archive.read_meta(tmp_path / "out" / "felt_trial000.npz")[0]["properties"] == {"stretchiness": 0}
    sets = data.load_sequences(
        Config.from_preset("smoke", modalities=("proprio",)),
        tmp_path / "out",
        workdir=tmp_path / "ws",
        progress=False,
        split_names=("train", "test"),
    )
    ss = sets["test"]
    felt = ss.labels["fabric"] == 1
    assert set(ss.labels["stretchiness"][felt].tolist()) == {0} and set(ss.labels["stretchiness"][~felt].tolist()) == {
        1
    }
    assert set(ss.labels["roughness"][felt].tolist()) == {-1} and set(ss.labels["roughness"][~felt].tolist()) == {3}
    assert set(ss.labels["thickness"].tolist()) == {-1}  # no level given: unknown, never the catalog's


def test_the_hands_folders_import_through_a_manifest(tmp_path):
    from tests.test_import_folder import write_folder

    write_folder(tmp_path / "rec" / "a", seed=0)
    write_folder(tmp_path / "rec" / "b", seed=1)
    manifest = tmp_path / "rec" / "manifest.csv"
    manifest.write_text("path,label,day,trial\na,4,1,0\nb,7,3,2\n")
    with pytest.raises(UserError) as e:
        _run_hand(manifest, tmp_path / "out")
    assert str(e.value) == (
        f"{manifest}: --reference: missing: a camera needs its session's no-contact reference: name the file "
        f"of the trial "
        "folder that holds it (pass --reference=reference.png), or pass --reference=pre_contact to use the "
        "trial's first frames"
    )
    assert not (tmp_path / "out").exists()
    summary, _ = _run_hand(manifest, tmp_path / "out", reference="reference.png")
    assert summary["trials"] == 2 and summary["classes"] is None and summary["splits"] == {"by day": 2}
    a = archive.read_archive(tmp_path / "out" / "fabric04_day1_trial00_lab.npz")
    assert a.meta["fabric_id"] == 4 and a.audio.shape[0] == 2 and a.images is not None and "split" not in a.meta
    b = archive.read_meta(tmp_path / "out" / "fabric07_day3_trial02_lab.npz")[0]
    assert b["day"] == 3 and b["label"] == 7 and b["label"] == b["fabric_id"]  # split by day, as the hand's protocol
    rec = write_folder(tmp_path / "check", seed=1)  # b's recording again: its reference survives the import
    np.testing.assert_array_equal(
        archive.read_archive(tmp_path / "out" / "fabric07_day3_trial02_lab.npz").reference, rec["reference"][None]
    )
    assert b["reference"] == {
        "how": "imported: 1 frame of the file reference.png (relative to the trial folder)",
        "session": "day3_lab",
        "times_s": None,
    }
    manifest.write_text("path,label,day,trial,split,session\na,4,1,0,test,rig A\n")
    _run_hand(manifest, tmp_path / "out1", reference="pre_contact", reference_frames=2)
    a = archive.read_archive(tmp_path / "out1" / "fabric04_day1_trial00_lab.npz")
    assert a.meta["split"] == "test"  # the column wins over the day
    np.testing.assert_array_equal(a.reference, write_folder(tmp_path / "again", seed=0)["frames"][:2])
    assert (
        a.meta["reference"]["session"] == "rig A"
        and a.meta["reference"]["how"] == "imported: the trial's first 2 frames (pre-contact, as the command line asks)"
    )
    manifest.write_text("path,label,split\na,4,train\n")
    with pytest.raises(UserError, match=r"manifest\.csv: line 2: day: missing: the hand's importers need a day"):
        _run_hand(manifest, tmp_path / "out2", reference="reference.png")
    labels = tmp_path / "labels.csv"
    labels.write_text("name,class\nfelt,0\n")
    with pytest.raises(UserError, match="--labels names classes of a rig's recordings"):
        _run_hand(manifest, tmp_path / "out3", labels=labels, reference="reference.png")


def test_bags_import_through_a_manifest_with_a_map(tmp_path):
    pytest.importorskip("rosbags")
    from tests import test_import_bag as bags

    bags.write_bag(tmp_path / "rec" / "bag0", bags.recording(seed=0))
    (tmp_path / "map.toml").write_text(bags.MAPPING_TOML)
    manifest = tmp_path / "rec" / "manifest.csv"
    manifest.write_text(
        "path,label,day,trial,split,session\nbag0,9,2,5,test,rig A\n"
    )  # the row's fields win over the map's [trial]
    summary, _ = _run_hand(manifest, tmp_path / "out", mapping=tmp_path / "map.toml")
    assert summary["trials"] == 1
    a = archive.read_archive(tmp_path / "out" / "fabric09_day2_trial05_lab.npz")
    assert a.meta["split"] == "test" and a.meta["fabric_id"] == 9 and a.meta["source"]["path"].endswith("bag0")
    rec = bags.recording(seed=0)  # aligned as the bag importer aligns alone
    np.testing.assert_allclose(a.timestamps, 0.02 * np.arange(bags.N_FRAMES), atol=1e-6)
    np.testing.assert_array_equal(a.window_end, np.stack([bags.expected_window_end()] * 2, axis=1))
    np.testing.assert_array_equal(a.images, rec["frames"])
    np.testing.assert_array_equal(a.reference, rec["reference"][:2])
    assert a.meta["reference"]["session"] == "rig A" and a.meta["reference"]["times_s"] == pytest.approx([-0.5, -0.3])


def _run_hand(manifest, out, **kw):
    """`batch.run` without a rig file: the hand's folders, or bags with `mapping`."""
    said = []
    return batch.run(manifest, out, workers=1, progress=False, say=said.append, **kw), "\n".join(said)


@pytest.mark.slow  # ~1-2 min on 2 shared cores: one smoke-size point
def test_the_cost_study_reads_the_imported_rig_without_the_paper_point(archives, tmp_path):
    from fabricjax.studies.diagnostics import cost

    doc = cost.run(
        n_seeds=1,
        preset="smoke",
        seq_lens=(10,),
        backbones=("attention",),
        widths=(),
        bandwidths=(),
        modality_sets=[("internal",)],
        latency_repeats=2,
        where=Location(workdir=tmp_path / "ws", data_dir=archives, results=tmp_path / "results", command="test"),
    )
    assert doc["paper_point"] is None and "paper" not in {p["group"] for p in doc["points"]}
    assert doc["dataset"]["step_rate"] == example_rig.STEP_RATE and all(
        p["touch_s"] == p["seq_len"] / example_rig.STEP_RATE for p in doc["points"]
    )
    md = (tmp_path / "results" / "cost.md").read_text()
    assert md.startswith("# What accuracy costs in time on recorded data") and "paper" not in md.lower()


@pytest.mark.slow  # ~1-2 min on 2 shared cores: one smoke-size property row and its t-SNE
def test_properties_and_latents_hold_out_the_rigs_holdout_split_not_the_catalogs_fabrics(tmp_path):
    from fabricjax.studies.paper import latents, properties

    labels = [*LABELS, "silk"]
    manifest = example_rig.write_recordings(tmp_path / "rig", labels, 4, seconds=(3.0, 3.5), splits=SPLITS)
    roughness = {"cotton canvas": "1", "felt": "0", "oak": "1", "silk": "0"}
    _edit_manifest(
        manifest,
        manifest,
        lambda rows: [
            r + ["roughness"] if i == 0 else r[:3] + ["holdout" if r[1] == "silk" else r[3], roughness[r[1]]]
            for i, r in enumerate(rows)
        ],
    )
    _run(manifest, tmp_path / "out")
    doc = properties.run(
        n_seeds=1,
        rows=["internal+proprio"],
        preset="smoke",
        where=Location(
            workdir=tmp_path / "ws", data_dir=tmp_path / "out", results=tmp_path / "results", command="test"
        ),
    )
    # class 1 (felt) trains, as the data says: the catalog's holdout ids (1, 10, 21-23) are not a rig's classes
    assert doc["dataset"]["trials"]["train"] == 6 and doc["fabrics"] == {"test": [0, 1, 2], "holdout": [3]}
    arm = f"joints arm_0–arm_{example_rig.N_JOINTS - 1} (angle, velocity, torque)"
    assert doc["dataset"]["names"] == {"internal": "vibration", "proprio": arm}  # the rig file's names, in the results
    pmd = (tmp_path / "results" / "properties.md").read_text()
    assert (
        f"holdout fabrics: vibration + {arm} [%]" in pmd
        and "Minsound" not in pmd.replace("`", " ").split("Checkpoint")[0]
    )
    ld = latents.run(
        doc["rows"][0]["checkpoint"],
        where=Location(
            workdir=tmp_path / "ws", data_dir=tmp_path / "out", results=tmp_path / "results", command="test"
        ),
    )
    assert ld["holdouts"] == [3] and [p["fabric_id"] for p in ld["points"]] == [0, 1, 2, 3] and ld["findings"] == []
    assert [(p["holdout"], p["chance"]) for p in ld["neighbours"]["pairs"]] == [
        (3, pytest.approx(1 / 3))
    ]  # roughness 0 as felt only
    md = (tmp_path / "results" / "latents.md").read_text()
    assert md.startswith("# Latent space on recorded data") and "paper" not in md.lower()


# The import cases of a transaction: each an error naming file, field and problem, or declared in the meta.


def _small(root, labels=LABELS[:2], trials=2, seconds=(2.0, 2.0)):
    return example_rig.write_recordings(root, labels, trials, seconds, splits={0: "train", 1: "test", 2: "val"})


def test_every_problem_of_a_manifest_is_listed_and_nothing_written(tmp_path):
    manifest = _small(tmp_path / "rig")
    (tmp_path / "rig" / "recordings" / "00_001" / "vibration.wav").unlink()
    (tmp_path / "rig" / "recordings" / "01_000" / "joints.csv").unlink()
    _edit_manifest(manifest, manifest, lambda rows: rows + [rows[1]] + [[rows[2][0], rows[2][1], "x", rows[2][3]]])
    with pytest.raises(batch.ImportProblems) as e:
        _run(manifest, tmp_path / "out")
    lines = str(e.value).splitlines()
    assert lines[0] == f"{manifest}: line 7: trial: 'x' is not an integer"
    assert (
        lines[1]
        == f"{tmp_path / 'rig' / 'recordings' / '00_001'}: <folder>: missing vibration.wav (named by the rig file)"
    )
    assert (
        lines[2]
        == f"{tmp_path / 'rig' / 'recordings' / '01_000'}: <folder>: missing joints.csv (named by the rig file)"
    )
    assert lines[3].startswith(
        f"{manifest}: line 6: path: the recording {tmp_path / 'rig' / 'recordings' / '00_000'} is listed again (line 2)"
    )
    assert lines[4] == f"{tmp_path / 'out'}: nothing was written (4 problems above)" and len(lines) == 5
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("workers", [1, 2])
def test_a_trial_failing_in_a_worker_is_the_same_one_line_error_and_nothing_is_written(tmp_path, workers):
    manifest = _small(tmp_path / "rig")
    joints = tmp_path / "rig" / "recordings" / "01_001" / "joints.csv"
    joints.write_text(joints.read_text().splitlines()[0] + "\n")  # a header only
    with pytest.raises(batch.ImportProblems) as e:
        batch.run(
            manifest,
            tmp_path / "out",
            rig=tmp_path / "rig" / "rig.toml",
            workers=workers,
            progress=False,
            say=lambda s: None,
        )
    assert str(e.value) == f"{joints}: <rows>: no readings (a header row only)"
    assert [p.name for p in (tmp_path / "out").iterdir()] == []  # no archive, no staging folder


def test_a_new_class_changes_the_label_map_which_needs_overwrite_and_then_replaces(tmp_path):
    grown = _small(tmp_path / "rig", labels=["cotton", "felt", "oak"])
    first = _edit_manifest(grown, tmp_path / "rig" / "first.csv", lambda rows: [r for r in rows if r[1] != "cotton"])
    _run(first, tmp_path / "out")
    with pytest.raises(UserError) as e:
        _run(grown, tmp_path / "out")
    assert str(e.value).splitlines()[0] == (
        f"{tmp_path / 'out' / 'felt_trial000.npz'}: exists, but its label map {{'felt': 0, 'oak': 1}} differs "
        "from the manifest's {'cotton': 0, 'felt': 1, 'oak': 2} (classes added or renamed); pass --overwrite "
        "to replace the dataset"
    )
    summary, _ = _run(grown, tmp_path / "out", overwrite=True)
    assert summary["imported"] == 6 and len(list((tmp_path / "out").glob("*.npz"))) == 6
    assert {archive.read_meta(p)[0]["label_map"]["oak"] for p in (tmp_path / "out").glob("*.npz")} == {2}


def test_a_relabelled_row_with_overwrite_leaves_no_stale_archive_and_a_foreign_out_is_refused(tmp_path):
    manifest = _small(tmp_path / "rig")
    _run(manifest, tmp_path / "out")
    relabelled = _edit_manifest(
        manifest,
        tmp_path / "rig" / "relabelled.csv",
        lambda rows: rows[:-1] + [[rows[-1][0], "cotton canvas", "5", rows[-1][3]]],
    )
    with pytest.raises(
        UserError,
        match=r"holds 1 archive no row of .*relabelled\.csv produces \(felt_trial001\.npz\): another dataset, "
        r"or rows since removed or relabelled; choose another --out, or pass --overwrite",
    ):
        _run(relabelled, tmp_path / "out")
    summary, said = _run(relabelled, tmp_path / "out", overwrite=True)
    assert summary["removed"] == 1 and "1 archives no row produces removed (--overwrite)" in said
    assert sorted(p.name for p in (tmp_path / "out").glob("*.npz")) == [
        "cotton_canvas_trial000.npz",
        "cotton_canvas_trial001.npz",
        "cotton_canvas_trial005.npz",
        "felt_trial000.npz",
    ]


def test_resume_imports_a_damaged_archive_again(tmp_path):
    manifest = _small(tmp_path / "rig")
    _run(manifest, tmp_path / "out")
    victim = tmp_path / "out" / "felt_trial000.npz"
    good = victim.read_bytes()
    data = bytearray(good)
    data[len(data) // 2] ^= 0x04  # one bit of a stream: only the member's CRC tells
    victim.write_bytes(bytes(data))
    summary, said = _run(manifest, tmp_path / "out")
    assert summary["imported"] == 1 and summary["resumed"] == 3
    assert f"note: {victim}: damaged (" in said and "imported again" in said
    assert victim.read_bytes() == good  # the same recording gives the same bytes


def test_timestamps_in_milliseconds_holes_and_cut_off_wavs(tmp_path):
    manifest = _small(tmp_path / "rig", labels=LABELS[:1], trials=3)
    rec = tmp_path / "rig" / "recordings"
    header = (rec / "00_000" / "joints.csv").read_text().splitlines()[0]
    table = np.loadtxt(rec / "00_000" / "joints.csv", delimiter=",", skiprows=1)
    ms = table.copy()
    ms[:, 0] *= 1000
    np.savetxt(rec / "00_000" / "joints.csv", ms, delimiter=",", header=header, comments="", fmt="%.6f")
    with pytest.raises(
        UserError,
        match=r"00_000/joints\.csv: time: timestamps span 1990, but the microphones hold 2\.00 s of audio: "
        r"timestamps must be seconds",
    ):
        _run(manifest, tmp_path / "out")
    hole = (table[:, 0] > 1.2) & (table[:, 0] < 1.79)  # 0.59 s without a joint reading
    np.savetxt(rec / "00_000" / "joints.csv", table[~hole], delimiter=",", header=header, comments="", fmt="%.6f")
    wav = rec / "00_001" / "vibration.wav"
    wav.write_bytes(wav.read_bytes()[: wav.stat().st_size // 2])
    _, said = _run(manifest, tmp_path / "out")
    gaps = archive.read_meta(tmp_path / "out" / "cotton_canvas_trial000.npz")[0]["import"]["joint_gaps"]
    assert gaps == [
        {"from_s": pytest.approx(1.2), "seconds": pytest.approx(0.59), "steps": 29}
    ]  # steps 1.22 .. 1.78 s hold the 1.2 s reading
    cut = archive.read_meta(tmp_path / "out" / "cotton_canvas_trial001.npz")[0]
    assert cut["complete"] is False and cut["import"]["truncated"] == ["vibration.wav"]
    assert archive.read_meta(tmp_path / "out" / "cotton_canvas_trial002.npz")[0]["complete"] is True
    assert "note: 1 trials are incomplete" in said and "note: 1 trials have holes in the joints" in said


def test_a_wav_cut_short_is_named_not_the_joints_it_fails_to_cover(tmp_path):
    """A vibration.wav cut to 1,000 samples is the file at fault: a 7 s trial's joints span far more
    than its 0.45 s (readings 10 ms apart are seconds), a 2 s trial's steps find no full window in it;
    both errors name the WAV, in one line."""
    from scipy.io import wavfile

    for seconds in (7.0, 2.0):
        root = tmp_path / f"rig{seconds:g}"
        manifest = _small(root, labels=LABELS[:1], trials=1, seconds=(seconds, seconds))
        wav = root / "recordings" / "00_000" / "vibration.wav"
        rate, samples = wavfile.read(wav)
        wavfile.write(wav, rate, samples[:1000])
        with pytest.raises(UserError) as e:
            _run(manifest, root / "out")
        assert re.fullmatch(
            rf"{re.escape(str(wav))}: samples: 1000 samples.*: the (file|recording) is cut short", str(e.value)
        )
        assert not list((root / "out").glob("*.npz"))


@pytest.mark.filterwarnings("ignore:overflow encountered in cast:RuntimeWarning")  # the 1e39 joints
def test_a_manifests_bad_trial_is_named_by_its_line_not_by_a_staged_archive(tmp_path):
    """A negative trial index is the manifest's line; an archive its recording cannot make (joints
    beyond float32) is named by the line and the recording, never by the hidden staging folder."""
    manifest = _small(tmp_path / "rig", labels=LABELS[:1], trials=2)
    _edit_manifest(manifest, manifest, lambda rows: [rows[0], rows[1], [*rows[2][:2], "-1", *rows[2][3:]]])
    with pytest.raises(UserError) as e:
        _run(manifest, tmp_path / "out")
    assert str(e.value) == f"{manifest}: line 3: trial: must be an integer from 0 to {archive.MAX_INT}, got '-1'"
    _edit_manifest(manifest, manifest, lambda rows: [rows[0], rows[1], [*rows[2][:2], "1", *rows[2][3:]]])
    joints = tmp_path / "rig" / "recordings" / "00_001" / "joints.csv"
    header, *rows = joints.read_text().splitlines()
    rows = [",".join([time, "1e39", *rest]) for time, _, *rest in (r.split(",") for r in rows)]
    joints.write_text("\n".join([header, *rows]) + "\n")  # every arm_0_angle beyond float32
    with pytest.raises(UserError) as e:
        _run(manifest, tmp_path / "out")
    assert re.fullmatch(
        rf"{re.escape(str(manifest))}: line 3: joints: \d+ non-finite values \(NaN or Inf\), in the archive made "
        rf"from {re.escape(str(joints.parent))}",
        str(e.value),
    )
    assert not list((tmp_path / "out").glob("*.npz"))


def test_latin1_manifest_read_only_out_and_unread_columns_are_one_line(tmp_path):
    manifest = _small(tmp_path / "rig", labels=["felt"], trials=1)
    latin = tmp_path / "rig" / "latin1.csv"
    latin.write_bytes(manifest.read_text().replace("felt", "feutre lav\u00e9").encode("latin-1"))
    with pytest.raises(
        UserError,
        match=r"latin1\.csv: line -: <file>: not UTF-8 text \(byte 0xe9 at offset \d+\): save the manifest as UTF-8$",
    ):
        _run(latin, tmp_path / "out")
    (tmp_path / "a_file").write_text("")
    with pytest.raises(
        UserError, match=rf"^{tmp_path / 'a_file' / 'out'}: --out: cannot write there: Not a directory$"
    ):
        _run(manifest, tmp_path / "a_file" / "out")
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o555)
    try:
        if not os.access(out, os.W_OK):  # (root may write anywhere)
            with pytest.raises(UserError, match=rf"^{out}: --out: cannot write there: Permission denied$"):
                _run(manifest, out)
    finally:
        out.chmod(0o755)
    from tests.test_import_folder import write_folder

    write_folder(tmp_path / "hand" / "a", seed=0)
    (tmp_path / "hand" / "manifest.csv").write_text("path,label,day,roughness\na,4,1,2\n")
    _, said = _run_hand(tmp_path / "hand" / "manifest.csv", tmp_path / "hand_out", reference="reference.png")
    assert said.count("columns not used: roughness") == 1  # the hand's levels come from the catalog


_KILL_IMPORT = """
import sys
sys.path.insert(0, {root!r})
from fabricjax.importers import batch
batch.run({manifest!r}, {out!r}, rig={rig!r}, workers=2, progress=False)
"""


def _stat(pid):
    """(parent pid, state) of a process from /proc, None when it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2 :].split()
    return int(fields[1]), fields[0]


def _workers(pid):
    """The worker processes `pid` started (its children but the multiprocessing resource tracker)."""
    out = []
    for p in Path("/proc").iterdir():
        if p.name.isdigit() and (st := _stat(p.name)) is not None and st[0] == pid:
            cmdline = (p / "cmdline").read_bytes() if (p / "cmdline").exists() else b""
            out += [] if b"resource_tracker" in cmdline else [int(p.name)]
    return out


def _alive(pid):
    st = _stat(pid)
    return st is not None and st[1] not in "ZX"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc (Linux)")
def test_killing_the_import_ends_its_workers_and_a_rerun_removes_what_it_left(tmp_path):
    manifest = example_rig.write_recordings(
        tmp_path / "rig", LABELS, 6, seconds=(6.0, 8.0), splits={k: "train" for k in range(6)}
    )
    out = tmp_path / "out"
    root = str(Path(__file__).parents[1])
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            _KILL_IMPORT.format(root=root, manifest=str(manifest), out=str(out), rig=str(manifest.parent / "rig.toml")),
        ]
    )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (
        list(out.glob(".import-*.partial/*.npz")) and len(_workers(proc.pid)) >= 2
    ):
        time.sleep(0.05)
    workers = _workers(proc.pid)
    assert workers, "the import started no workers"
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(w) for w in workers):
        time.sleep(0.1)
    assert not any(_alive(w) for w in workers), "workers outlived the killed import"
    assert list(out.glob(".import-*.partial")) and not list(out.glob("*.npz"))  # staged, never in DIR
    summary, _ = _run(manifest, out)
    assert summary["imported"] == 18 and not list(out.glob(".*"))


README = """demo_rig: contact sound of three materials

What was recorded
  Three materials rubbed by a probe (Doe et al., 2030).

Source
  example.org/demo (commit abc)

Channels
  one microphone at 2.2 kHz

License
  research use only; cite Doe et al. 2030.
"""


def test_the_readme_beside_the_manifest_gives_every_results_page_its_source_and_terms(recordings, tmp_path):
    """The data's own words on where it comes from and on what terms reach the import's folder
    and the top of a results page; a section on anything else does not."""
    root = tmp_path / "rig"
    shutil.copytree(recordings.parent, root)
    (root / "README.txt").write_text(README)
    out = tmp_path / "archives"
    _run(root / recordings.name, out)
    from fabricjax.store import provenance
    from fabricjax.studies.machinery import documents

    source = provenance.read(out)
    assert source["title"] == "demo_rig: contact sound of three materials"
    assert source["sections"] == {
        "What was recorded": "Three materials rubbed by a probe (Doe et al., 2030).",
        "Source": "example.org/demo (commit abc)",
        "License": "research use only; cite Doe et al. 2030.",
    }
    line = documents.data_markdown(
        "default",
        {"source": "recorded", "folder": "x", "classes": LABELS, "trials": {}, "sequences": {}, "provenance": source},
    )
    assert "**License**: research use only; cite Doe et al. 2030." in line and "2.2 kHz" not in line


def test_an_archive_says_what_its_wav_files_held(archives):
    """A 16-bit WAV from another microphone is stored as SPH0645-style words; the archive says so
    rather than naming only the word format."""
    meta, _ = archive.read_meta(next(archives.glob("*.npz")))
    mic = meta["streams"]["mics"][0]
    assert mic["recorded_as"].startswith("16-bit PCM WAV")
    assert meta["streams"]["audio_format"].endswith(f"{mic['name']}: from {mic['recorded_as']}")


def test_without_rows_a_study_on_recorded_data_runs_the_rows_it_can_feed(archives, tmp_path, caplog):
    """No --rows on a rig without a palm microphone or a camera: the probe reads the rows the data
    feeds and says in one line which it left out, instead of stopping at the first it cannot."""
    import logging

    from fabricjax.studies.diagnostics import probe

    with caplog.at_level(logging.WARNING):
        doc = probe.run(
            preset="smoke",
            where=Location(workdir=tmp_path / "ws", data_dir=archives, results=tmp_path / "results", command="test"),
        )
    names = [r["name"] for r in doc["rows"]]
    assert names and all(not {"image", "flow", "external"} & set(n.split("+")) for n in names)
    assert "internal" in names and "proprio" in names
    left = [r.message for r in caplog.records if "rows left out" in r.message]
    assert len(left) == 1 and "external" in left[0] and "flow" in left[0]


HOLD_IMPORT = """
import sys, time
from fabricjax.importers import batch
from fabricjax.store import lock
out_lock = __import__("pathlib").Path(sys.argv[1]) / batch.IMPORT_LOCK
with lock.hold(out_lock, "the import", "importing for a test", transient=True):
    print("held", flush=True)
    time.sleep(120)
"""


def test_a_second_import_into_one_folder_is_refused_in_one_line_and_writes_nothing(recordings, tmp_path):
    """Two imports into one --out at once: the second refuses, naming the first, before it has
    written an archive; once the first is gone (killed) the import runs and leaves no lock behind."""
    out = tmp_path / "archives"
    out.mkdir()
    first = subprocess.Popen(
        [sys.executable, "-c", HOLD_IMPORT, str(out)], stdout=subprocess.PIPE, text=True, cwd=Path(__file__).parents[1]
    )
    try:
        assert first.stdout.readline().strip() == "held"
        with pytest.raises(
            UserError,
            match=re.escape(f"the import into {out} is in use by PID {first.pid} (") + ".*importing for a test",
        ) as e:
            _run(recordings, out)
        assert "\n" not in str(e.value) and not list(out.glob("*.npz"))
    finally:
        first.kill()
        first.wait()
    summary, _ = _run(recordings, out)
    assert len(list(out.glob("*.npz"))) == 12 and not list(out.glob(".*"))
