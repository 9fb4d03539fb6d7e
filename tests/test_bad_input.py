"""Bad input gets a clear error naming the file and the field, through the path the studies use
(`data.load_sequences`: index -> archives -> feature cache -> sequences), never a crash deep in
numpy/jax or a silently wrong number.

Already covered by `read_archive` tests in test_archive.py (not repeated): every field's NaN/Inf,
dtype and shape check, truncated / corrupt / non-zip files, wrong format version, an index listing
a missing archive, a killed writer; in test_data.py: a trial shorter than one sequence, frames
missing for an image config; in test_checkpoint.py: a checkpoint made with another config or
other seeds.
"""

import json
import os
import re

import numpy as np
import pytest

from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.sequences import data
from fabricjax.store import archive, dataset_index, workspace
from fabricjax.training import checkpoint, train
from tests.helpers import npz_fields, tiny_archive, tiny_dataset

TRIALS = [(4, 1, 0, "lab"), (4, 1, 1, "lab"), (4, 3, 0, "lab")]  # train, val, test
VICTIM = "fabric04_day1_trial01_lab.npz"
CFG = Config(preset="smoke", seq_len=20, modalities=("internal", "proprio"))


def load(ds, tmp_path, cfg=CFG):
    return data.load_sequences(cfg, ds, workdir=tmp_path / "ws", progress=False, workers=1)


@pytest.fixture
def dataset(tmp_path):
    ds = tiny_dataset(tmp_path / "ds", TRIALS, n_steps=41, images=None)
    load(ds, tmp_path)  # indexed and cached: damage below happens to a dataset already in use
    return ds


def _npz_fields(**changes):
    return npz_fields(tiny_archive(41, fabric_id=4, day=1, trial=1, images=None, seed=1), **changes)


def _meta(**kw):
    m = tiny_archive(41, fabric_id=4, day=1, trial=1, images=None).meta
    m.update(kw)
    return np.array(json.dumps(m))


def _truncate(path):
    b = path.read_bytes()
    path.write_bytes(b[: len(b) // 2])


def _corrupt(path):
    b = bytearray(path.read_bytes())
    b[len(b) // 2 : len(b) // 2 + 2000] = os.urandom(2000)
    path.write_bytes(bytes(b))


DAMAGE = {
    "truncated": (_truncate, "<file>|audio|joints|force|window_end|timestamps", "corrupt or truncated"),
    "corrupt_bytes": (
        _corrupt,
        "<file>|audio|joints|force|window_end|timestamps|meta",
        "corrupt or truncated|not valid JSON|CRC",
    ),
    "wrong_version": ({"meta": _meta(format_version=4)}, "meta.format_version", "unknown format version 4"),
    "nan_joints": ({"joints": np.full((41, 6, 3), np.nan, np.float32)}, "joints", "738 non-finite values"),
    "inf_force": ({"force": np.r_[np.ones(40), np.inf].astype(np.float32)}, "force", "1 non-finite values"),
    "nan_timestamps": ({"timestamps": np.r_[np.arange(40) * 0.02, np.nan]}, "timestamps", "non-finite"),
    "short_force": ({"force": np.ones(40, np.float32)}, "force", "40 steps, but timestamps has 41"),
    "joints_shape": ({"joints": np.zeros((41, 6, 2), np.float32)}, "joints", "shape"),
    "audio_rows": ({"audio": np.zeros((1, 50000), np.int32)}, "audio", "shape"),
    "float_audio": ({"audio": np.zeros((2, 50000), np.float32)}, "audio", "dtype float32"),
    "window_past_audio": ({"audio": np.zeros((2, 1000), np.int32)}, "window_end", r"must lie in \[0, 1000\]"),
    "missing_audio": ({"audio": None}, "audio", "missing"),
    "label_bool": ({"meta": _meta(label=True)}, "meta.label", "must be an integer, got true"),
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_damaged_archive_in_a_dataset_is_named(dataset, tmp_path, damage):
    how, field, problem = DAMAGE[damage]
    path = dataset / VICTIM
    if callable(how):
        how(path)
    else:
        np.savez(path, **_npz_fields(**how))
    with pytest.raises(archive.ArchiveError) as e:
        load(dataset, tmp_path)
    assert e.value.path == str(path), str(e.value)
    assert re.fullmatch(field, e.value.field), str(e.value)
    assert re.search(problem, e.value.problem), str(e.value)
    assert str(e.value).startswith(f"{path}: field '{e.value.field}': ")


def test_malformed_index_is_named(dataset, tmp_path):
    index = workspace.index_file(dataset, tmp_path / "ws")  # the dataset lies outside the workspace
    index.write_text("{ not json")
    with pytest.raises(archive.ArchiveError, match=rf"{re.escape(str(index))}: field 'trials': malformed index"):
        load(dataset, tmp_path)
    index.write_text(json.dumps({"format_version": 7, "trials": []}))
    with pytest.raises(archive.ArchiveError, match=r"\.json: field 'format_version': unknown index version 7"):
        load(dataset, tmp_path)
    index.write_text(json.dumps({"format_version": dataset_index.INDEX_VERSION, "trials": [{"file": "x.npz"}]}))
    with pytest.raises(archive.ArchiveError, match="malformed index"):
        load(dataset, tmp_path)
    index.unlink()  # deleting the index re-indexes the folder
    assert len(load(dataset, tmp_path)["train"]) == 2


def test_index_listing_a_missing_archive_through_load_sequences(dataset, tmp_path):
    (dataset / VICTIM).unlink()
    with pytest.raises(archive.ArchiveError, match=rf"\.json: field 'trials\[{VICTIM}\]': listed archive is missing"):
        load(dataset, tmp_path)


def test_read_only_data_folder_is_read_and_left_byte_identical(tmp_path):
    """A folder of recordings may be read-only, shared or under version control: indexing,
    features and sequences all work, and nothing in it changes (checked byte for byte, since
    permissions alone do not stop a test running as root)."""
    ds = tiny_dataset(tmp_path / "recordings", TRIALS, n_steps=41, images=None)
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(ds.iterdir())}
    modes = {p: p.stat().st_mode for p in [ds, *before]}
    for p in [*before, ds]:
        p.chmod(p.stat().st_mode & ~0o222)
    try:
        for _ in range(2):  # indexed, then read back from the workspace's index
            sets = load(ds, tmp_path)
            assert len(sets["train"]) == 2 and len(sets["test"]) == 2
    finally:
        for p, mode in modes.items():
            p.chmod(mode)
    assert {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(ds.iterdir())} == before
    assert workspace.index_file(ds, tmp_path / "ws").is_file()


def test_damaged_feature_cache_is_recomputed(dataset, tmp_path):
    before = load(dataset, tmp_path)
    files = sorted((tmp_path / "ws" / "features").glob("*/*.npz"))
    assert len(files) == 2 * len(TRIALS)
    _truncate(files[0])
    _corrupt(files[1])
    files[2].write_bytes(b"")
    after = load(dataset, tmp_path)
    for s in ("train", "val", "test"):
        for m in CFG.modalities:
            np.testing.assert_array_equal(after[s].inputs[m], before[s].inputs[m])


@pytest.mark.parametrize(
    "modality, sizes", [("image", [(12, 16), (14, 16), (12, 16)]), ("flow", [(12, 16), (15, 16), (12, 16)])]
)
def test_trials_with_other_frame_sizes_are_named(tmp_path, modality, sizes):
    """The first trial fixes the sequence arrays' shapes; a trial whose frames give another shape
    is an error naming it, not a numpy broadcast error."""
    ds = tmp_path / "ds"
    for i, (t, hw) in enumerate(zip(TRIALS, sizes)):
        a = tiny_archive(41, fabric_id=t[0], day=t[1], trial=t[2], images=hw, seed=i)
        archive.write_archive(ds / archive.trial_filename(a.meta), a)
    cfg = Config(preset="smoke", seq_len=20, modalities=(modality,), image_resolution="full")
    with pytest.raises(archive.ArchiveError, match=rf"{VICTIM}: field 'images': {modality} sequences of shape"):
        load(ds, tmp_path, cfg)


def test_incomplete_archive_is_kept_and_readable(tmp_path):
    """An interrupted recording is stored with complete=False and stays usable downstream."""
    ds = tiny_dataset(tmp_path / "ds", TRIALS, n_steps=41, images=None)
    a = tiny_archive(25, fabric_id=4, day=1, trial=0, images=None, seed=5)
    a.meta.update(complete=False, failure="interrupted (Ctrl-C)")
    archive.write_archive(ds / archive.trial_filename(a.meta), a)
    entry = {e.file: e for e in dataset_index.load_index(ds).entries}["fabric04_day1_trial00_lab.npz"]
    assert entry.meta["complete"] is False and entry.n_steps == 25
    sets = load(ds, tmp_path)
    assert (sets["train"].info["trial_key"] == entry.file).sum() == 1


TINY = Config(
    preset="smoke",
    modalities=("internal",),
    width=16,
    n_layers=1,
    ffn=32,
    audio_hidden=(16, 8),
    seq_len=8,
    epochs=1,
    batch_size=8,
)


def test_checkpoint_directory_errors_name_the_directory(tmp_path):
    with pytest.raises(FileNotFoundError, match=str(tmp_path / "empty")):
        train.restore(tmp_path / "empty", TINY)
    sets = {k: synthetic.data_set(TINY, 8, seed=i) for i, k in enumerate(["train", "val"])}
    train.train_and_evaluate(TINY, sets, [0], workdir=tmp_path / "run")
    wider = {k: synthetic.data_set(TINY, 8, psd_bins=32, seed=i) for i, k in enumerate(["train", "val"])}
    with pytest.raises(
        checkpoint.CheckpointMismatch, match=r"run was made with a different run: shapes: saved \{'internal': \[24\]\}"
    ):
        train.train_and_evaluate(TINY, wider, [0], workdir=tmp_path / "run")
    other = Config(**{**TINY.to_json(), "bandwidth_khz": 2.5})
    with pytest.raises(
        checkpoint.CheckpointMismatch, match=rf"{tmp_path / 'run'}.*bandwidth_khz: saved 15.0, requested 2.5"
    ):
        train.restore(tmp_path / "run", other)
