"""Batch import of a rig unlike the hand (issue 26): one vibration channel at 2.2 kHz, 7 joints
with torque, no camera, no palm microphone, string labels, no days."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from acquisition import import_manifest, rig_bench
from fabricjax import archive
from fabricjax.errors import UserError

LABELS = ["cotton canvas", "felt", "oak"]
SPLITS = {0: "train", 1: "train", 2: "val", 3: "test"}


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    return rig_bench.write_recordings(tmp_path_factory.mktemp("rig"), LABELS, 4, splits=SPLITS)


@pytest.fixture(scope="module")
def archives(recordings, tmp_path_factory):
    """The recordings imported as they are (the studies below only read them)."""
    out = tmp_path_factory.mktemp("imported") / "archives"
    _run(recordings, out)
    return out


def _run(manifest, out, **kw):
    said = []
    summary = import_manifest.run(manifest, out, rig=manifest.parent / "rig.toml", workers=1, progress=False, say=said.append, **kw)
    return summary, "\n".join(said)


def test_one_command_imports_the_rig_as_it_is(recordings, tmp_path):
    out = tmp_path / "archives"
    proc = subprocess.run([sys.executable, "-m", "acquisition.import_manifest", str(recordings), f"--out={out}",
                           f"--rig={recordings.parent / 'rig.toml'}"], capture_output=True, text=True, cwd=Path(__file__).parents[1])
    assert proc.returncode == 0, proc.stderr
    assert "12 trials imported" in proc.stdout and "3 classes" in proc.stdout
    assert "gripper_temperature (12 trials)" in proc.stdout  # the column the rig file does not name is reported
    files = sorted(p.name for p in out.glob("*.npz"))
    assert files[0] == "cotton_canvas_trial000_lab.npz" and len(files) == 12
    a = archive.read_archive(out / "felt_trial003_lab.npz")
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


def test_rerun_resumes_and_a_foreign_archive_needs_overwrite(recordings, tmp_path):
    out = tmp_path / "archives"
    first, _ = _run(recordings, out)
    assert first["imported"] == 12
    again, said = _run(recordings, out)
    assert again["imported"] == 0 and again["resumed"] == 12 and "12 already there (resumed)" in said
    victim = out / "oak_trial000_lab.npz"
    foreign = archive.read_archive(out / "oak_trial001_lab.npz")
    archive.write_archive(victim, foreign)  # an archive of another recording under this row's name
    before = victim.read_bytes()
    with pytest.raises(UserError, match="oak_trial000_lab.npz: exists and was not imported from .*--overwrite"):
        _run(recordings, out)
    assert victim.read_bytes() == before
    replaced, _ = _run(recordings, out, overwrite=True)
    assert replaced["imported"] == 12
    assert archive.read_meta(victim)[0]["source"]["path"].endswith("02_000")


def test_fraction_rule_splits_each_class_in_trial_order(tmp_path):
    manifest = rig_bench.write_recordings(tmp_path / "rig", LABELS[:2], 4, seconds=(2.0, 2.5))
    summary, _ = _run(manifest, tmp_path / "out", split="fraction:0.5,0.25,0.25")
    assert summary["splits"] == {"train": 4, "val": 2, "test": 2}
    assert archive.read_meta(tmp_path / "out" / "felt_trial003_lab.npz")[0]["split"] == "test"
    assert archive.read_meta(tmp_path / "out" / "felt_trial000_lab.npz")[0]["split"] == "train"


def test_trial_rule_splits_every_class_by_trial_index(tmp_path):
    manifest = rig_bench.write_recordings(tmp_path / "rig", LABELS[:2], 4, seconds=(2.0, 2.5))
    summary, _ = _run(manifest, tmp_path / "out", split="trial:train=0-1,val=2,test=3")
    assert summary["splits"] == {"train": 4, "val": 2, "test": 2}
    assert [archive.read_meta(tmp_path / "out" / f"felt_trial00{k}_lab.npz")[0]["split"] for k in range(4)] == ["train", "train", "val", "test"]
    with pytest.raises(UserError, match=r"manifest\.csv: line \d+: trial: trial 3 is in no range of --split=trial:train=0-1,val=2"):
        _run(manifest, tmp_path / "out2", split="trial:train=0-1,val=2")
    for bad in ("trial:train=0-2,val=2", "trial:train=3-1", "trial:dev=0-3", "trial:train=0-x"):
        with pytest.raises(UserError, match=f"--split={bad}: expected trial:SPLIT=FIRST-LAST"):
            import_manifest.parse_split_rule(bad)
    assert import_manifest.parse_split_rule("trial:test=2,train=0-1") == ("trial", {2: "test", 0: "train", 1: "train"})


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
    extra = _edit_manifest(recordings, recordings.parent / "extra.csv", lambda rows: [r + (["notes"] if i == 0 else ["x"]) for i, r in enumerate(rows)])
    _, said = _run(extra, out)
    assert "columns not used: notes" in said
    # two rows naming one archive
    dup = _edit_manifest(recordings, recordings.parent / "dup.csv", lambda rows: rows + [rows[1]])
    with pytest.raises(UserError, match="gives the archive cotton_canvas_trial000_lab.npz, as line 2 does"):
        _run(dup, tmp_path / "out2")
    with pytest.raises(UserError, match="--split=fraction:0.5,0.5,0.5: expected"):
        _run(no_split, tmp_path / "out3", split="fraction:0.5,0.5,0.5")


def test_rig_file_mistakes_are_named(tmp_path):
    from acquisition import rig

    bad = tmp_path / "rig.toml"
    bad.write_text('[[mics]]\nname = "v"\nfile = "v.wav"\nrole = "palm"\n[steps]\nrate = 50\n')
    with pytest.raises(UserError, match=r"rig\.toml: mics\[0\]\.role: must be one of"):
        rig.load_rig(bad)
    bad.write_text('[[mics]]\nname = "v"\nfile = "v.wav"\n')
    with pytest.raises(UserError, match=r"steps\.rate: missing: without a camera or joints"):
        rig.load_rig(bad)


@pytest.mark.slow  # ~1-3 min on 2 shared cores: import and two smoke-size rows
def test_a_study_trains_and_tests_on_the_imported_rig(archives, tmp_path, capsys):
    from fabricjax.studies import ablation

    names = sorted(p.name for p in archives.iterdir())
    doc = ablation.run(n_seeds=1, rows=["proprio", "internal+proprio"], preset="smoke", workdir=tmp_path / "ws",
                       data_dir=archives, results=tmp_path / "results", command="test")
    assert sorted(p.name for p in archives.iterdir()) == names  # the data folder is only read: no invented files
    printed = capsys.readouterr().out
    assert "recorded data" in printed and "train 6 trials /" in printed and "val 3 trials /" in printed and "test 3 trials /" in printed
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
    from fabricjax.studies import ablation

    with pytest.raises(archive.ArchiveError, match=r"field 'audio': absent: the data has no external \(palm mic\).*it has microphones: vibration"):
        ablation.run(n_seeds=1, rows=["internal+external"], preset="smoke", workdir=tmp_path / "ws", data_dir=archives,
                     results=tmp_path / "results", command="test")
    assert not (tmp_path / "results" / "ablation.md").exists()


def test_the_probe_reads_the_imported_rig(archives, tmp_path):
    from fabricjax.studies import probe

    doc = probe.run(rows=["proprio", "internal"], preset="smoke", workdir=tmp_path / "ws", data_dir=archives,
                    results=tmp_path / "results", command="test")
    assert doc["splits"] == ["train", "val", "test"] and doc["classes"] == [0, 1, 2]  # no cafe trials: no cafe column filled
    assert doc["inputs"]["proprio"]["step_dims"] == 7 * 3 and doc["inputs"]["internal"]["step_dims"] == 512
    assert all(0 <= r["accuracy"]["test"] <= 1 for r in doc["rows"])
    md = (tmp_path / "results" / "probe.md").read_text()
    assert "recorded data" in md and "chance 33.3 %" in md and "(recorded data, read as it is)" in md
    assert "simulat" not in md.lower()


def test_the_bandwidth_plot_names_the_rigs_microphone(archives, tmp_path):
    from fabricjax.studies import bandwidth, loading

    assert bandwidth.microphone(loading.Dataset({}, archives, "recorded", 0.0, 0.0), tmp_path / "ws") == "vibration"
    assert bandwidth.microphone(loading.Dataset({}, archives, "simulated", 0.0, 0.0)) == "Minsound"


def test_import_benchmark_entry_and_row(tmp_path):
    from fabricjax.studies import bench

    doc = bench.run(only=["import"], results=tmp_path, command="test", out=lambda s: None,
                    importer=lambda trials: rig_bench.bench_import(trials=20, seconds=(2.0, 3.0), workers=1))
    entry = doc["benchmarks"]["import"]
    assert entry["trials"] == 20 and entry["steps"] > 0 and entry["wall_s"] > 0
    assert "batch import, 20 trials of 2-3 s" in (tmp_path / "bench.md").read_text()
    with pytest.raises(ValueError, match="the import benchmark needs its function"):
        bench.run(only=["import"], results=tmp_path, command="test", out=lambda s: None)
