import dataclasses
import json
import os
import signal
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from fabricjax.store import archive, dataset_index, workspace
from tests.helpers import npz_fields, tiny_archive


def test_round_trip(tmp_path):
    a = tiny_archive()
    p = archive.write_archive(tmp_path / "t.npz", a)
    b = archive.read_archive(p)
    assert b.meta == a.meta
    for k, v in a.arrays().items():
        np.testing.assert_array_equal(getattr(b, k), v)
        assert getattr(b, k).dtype == v.dtype
    # loadable without pickle by plain numpy
    with np.load(p, allow_pickle=False) as z:
        assert json.loads(str(z["meta"][()]))["fabric_id"] == 4


def test_members_up_to_the_free_inflation_are_deflated_larger_ones_stored_and_both_read_back(tmp_path, monkeypatch):
    a = tiny_archive()
    small = archive.write_archive(tmp_path / "small.npz", a)
    limit = min(a.images.nbytes, a.audio.nbytes) - 1  # frames and audio now count as large, the rest small
    monkeypatch.setattr(archive, "FREE_INFLATION", limit)
    large = archive.write_archive(tmp_path / "large.npz", a)
    types = {p.name: {i.filename: i.compress_type for i in zipfile.ZipFile(p).infolist()} for p in (small, large)}
    assert set(types["small.npz"].values()) == {zipfile.ZIP_DEFLATED}
    assert {k: v == zipfile.ZIP_STORED for k, v in types["large.npz"].items()} == {
        f"{k}.npy": np.asarray(v).nbytes > limit for k, v in npz_fields(a).items()
    }
    assert sum(types["large.npz"][f"{k}.npy"] == zipfile.ZIP_DEFLATED for k in ("joints", "timestamps")) == 2
    plain = tmp_path / "plain.npz"  # as archives were written before: every member stored
    np.savez(plain, **npz_fields(a))
    for p in (small, large, plain):
        b = archive.read_archive(p)
        for k, v in a.arrays().items():
            np.testing.assert_array_equal(getattr(b, k), v)


def test_images_optional_and_skippable(tmp_path):
    p = archive.write_archive(tmp_path / "a.npz", tiny_archive(images=None))
    assert archive.read_archive(p).images is None
    p2 = archive.write_archive(tmp_path / "b.npz", tiny_archive())
    assert archive.read_archive(p2, images=False).images is None


def _rewrite(path, **changes):
    """Write an npz with some fields replaced (None deletes) bypassing validation."""
    np.savez(path, **npz_fields(tiny_archive(), **changes))
    return path


def _meta_with(**kw):
    m = tiny_archive().meta
    m.update(kw)
    return np.array(json.dumps(m))


@pytest.mark.parametrize(
    "changes, field, words",
    [
        ({"audio": None}, "audio", "missing"),
        ({"joints": None}, "joints", "missing"),
        ({"meta": None}, "meta", "missing"),
        ({"force": np.full(30, np.nan, np.float32)}, "force", "non-finite"),
        ({"joints": np.full((30, 6, 3), np.inf, np.float32)}, "joints", "non-finite"),
        ({"audio": np.zeros((2, 100), np.float32)}, "audio", "dtype"),
        ({"joints": np.zeros((30, 5, 3), np.float32)}, "joints", "shape"),
        ({"force": np.zeros(29, np.float32)}, "force", "steps"),
        ({"window_end": np.full((30, 2), 10**9, np.int64)}, "window_end", "must lie in"),
        ({"window_end": np.stack([np.arange(30)[::-1]] * 2, 1).astype(np.int64)}, "window_end", "decrease"),
        ({"meta": _meta_with(format_version=99)}, "meta.format_version", "unknown format version"),
        ({"meta": _meta_with(condition="street")}, "meta.condition", "must be one of"),
        ({"meta": np.array("{not json")}, "meta", "not valid JSON"),
        ({"images": np.zeros((30, 5, 5, 3), np.uint8)}, "images", "image_size"),
    ],
)
def test_validation_errors_name_file_and_field(tmp_path, changes, field, words):
    p = _rewrite(tmp_path / "bad.npz", **changes)
    with pytest.raises(archive.ArchiveError) as e:
        archive.read_archive(p)
    assert e.value.field == field
    assert words in e.value.problem
    assert str(p) in str(e.value)


def test_missing_meta_key(tmp_path):
    m = tiny_archive().meta
    del m["day"]
    p = _rewrite(tmp_path / "bad.npz", meta=np.array(json.dumps(m)))
    with pytest.raises(archive.ArchiveError, match=r"meta\.day.*missing"):
        archive.read_archive(p)


@pytest.mark.parametrize("cut", [0.1, 0.5, 0.9, 0.999])
def test_truncated_file(tmp_path, cut):
    p = archive.write_archive(tmp_path / "t.npz", tiny_archive())
    data = p.read_bytes()
    p.write_bytes(data[: int(len(data) * cut)])
    with pytest.raises(archive.ArchiveError) as e:
        archive.read_archive(p)
    assert str(p) in str(e.value)


def test_corrupt_bytes(tmp_path):
    p = archive.write_archive(tmp_path / "t.npz", tiny_archive())
    data = bytearray(p.read_bytes())
    data[len(data) // 2 : len(data) // 2 + 4000] = os.urandom(4000)
    p.write_bytes(bytes(data))
    with pytest.raises(archive.ArchiveError):
        archive.read_archive(p)


def test_not_an_archive(tmp_path):
    p = tmp_path / "x.npz"
    p.write_text("hello")
    with pytest.raises(archive.ArchiveError, match="not a readable"):
        archive.read_archive(p)
    with pytest.raises(archive.ArchiveError, match="no such file"):
        archive.read_archive(tmp_path / "absent.npz")


def test_write_refuses_invalid_and_leaves_nothing(tmp_path):
    a = tiny_archive()
    bad = dataclasses.replace(a, force=np.full(30, np.nan, np.float32))
    with pytest.raises(archive.ArchiveError):
        archive.write_archive(tmp_path / "t.npz", bad)
    assert list(tmp_path.iterdir()) == []


_KILLED_WRITER = """
import sys, numpy as np
sys.path.insert(0, {root!r})
from fabricjax.store import archive, workspace
from tests.helpers import tiny_archive
a = tiny_archive(n_steps=400, images=(120, 160))
def slow_write(f, arrays, deflate):
    f.write(b"PK" + b"x" * 1_000_000)
    f.flush()
    print("writing", flush=True)
    import time; time.sleep(60)
archive.write_npz = slow_write
archive.write_archive({out!r}, a)
"""


def test_killed_writer_leaves_no_partial_archive(tmp_path):
    out = tmp_path / "trial.npz"
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    proc = subprocess.Popen(
        [sys.executable, "-c", _KILLED_WRITER.format(root=root, out=str(out))], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "writing"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not out.exists()
    # only the hidden temporary remains, which no reader or index picks up
    assert all(p.name.endswith(".partial") for p in tmp_path.iterdir())
    assert dataset_index.build_index(tmp_path).entries == ()


def test_index_build_load_and_missing_file(tmp_path):
    for t in range(3):
        a = tiny_archive(trial=t)
        archive.write_archive(tmp_path / archive.trial_filename(a.meta), a)
    idx = dataset_index.build_index(tmp_path)
    assert len(idx.entries) == 3 and all(e.n_steps == 30 for e in idx.entries)
    assert dataset_index.load_index(tmp_path).entries == idx.entries
    assert len(idx.select(trial=1)) == 1
    # a new archive is picked up
    a = tiny_archive(trial=7)
    archive.write_archive(tmp_path / archive.trial_filename(a.meta), a)
    assert len(dataset_index.load_index(tmp_path).entries) == 4
    # a listed archive that vanished is an error naming the index and the file
    (tmp_path / archive.trial_filename(a.meta)).unlink()
    with pytest.raises(archive.ArchiveError, match=f"listed archive is missing from {tmp_path}"):
        dataset_index.load_index(tmp_path)


def test_index_of_missing_or_empty_folder(tmp_path):
    with pytest.raises(archive.ArchiveError, match="does not exist"):
        dataset_index.build_index(tmp_path / "nope")
    with pytest.raises(archive.ArchiveError, match="does not exist"):
        dataset_index.load_index(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(
        archive.ArchiveError, match=r"empty: field '<folder>': the folder holds no trial archives \(\*\.npz\)$"
    ):
        dataset_index.load_index(tmp_path / "empty", tmp_path / "ws")


def _tree(folder):
    """Every file below `folder` with its bytes and modification time."""
    return {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(folder.rglob("*")) if p.is_file()}


def test_index_lives_beside_the_workspace_datasets_and_under_the_workspace_for_other_folders(tmp_path):
    ws = tmp_path / "ws"
    inside, outside = ws / "datasets" / "mine", tmp_path / "recordings"
    for folder in (inside, outside):
        folder.mkdir(parents=True)
        a = tiny_archive(trial=0)
        archive.write_archive(folder / archive.trial_filename(a.meta), a)
    assert workspace.index_file(inside, ws) == inside.resolve() / workspace.INDEX_NAME
    assert len(dataset_index.load_index(inside, ws).entries) == 1 and (inside / workspace.INDEX_NAME).exists()
    before = _tree(outside)
    index = dataset_index.load_index(outside, ws)
    assert len(index.entries) == 1 and index.root == outside
    assert _tree(outside) == before  # nothing written into the folder we only read
    (kept,) = (ws / "indexes").iterdir()
    assert kept == workspace.index_file(outside, ws) and kept.name.startswith("recordings-")
    assert workspace.index_file(tmp_path / "elsewhere" / "recordings", ws) != kept  # keyed by the whole path
    assert dataset_index.load_index(outside, ws).entries == index.entries  # read back, not rebuilt


def test_random_bytes_are_not_an_archive_and_nobody_suggests_unpickling(tmp_path):
    path = tmp_path / "noise.npz"
    path.write_bytes(os.urandom(4096))
    with pytest.raises(archive.ArchiveError, match=r"noise\.npz: field '<file>': not a readable \.npz archive") as e:
        archive.read_archive(path)
    assert "pickle" not in str(e.value)


def test_written_files_get_the_usual_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        p = archive.write_archive(tmp_path / "t.npz", tiny_archive())
    finally:
        os.umask(old)
    assert p.stat().st_mode & 0o777 == 0o644
