"""Content hashes in the index (written at import by `import_manifest`), and `verify` naming each
problem: a flipped byte, a truncated file, an irregular timestamp; read_archive refusing a repeated step."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fabricjax.importers import batch, example_rig
from fabricjax.store import archive, dataset_index, integrity, workspace
from tests.helpers import npz_fields, tiny_archive, tiny_dataset

TRIALS = [(4, 1, 0, "lab"), (4, 1, 1, "lab"), (5, 1, 0, "lab")]


def _dataset(tmp_path):
    folder = tiny_dataset(tmp_path / "data", TRIALS, n_steps=12, images=(8, 10))
    index = dataset_index.load_index(folder, tmp_path / "ws")
    return folder, index


def test_index_records_sha256_and_verify_passes_a_clean_dataset(tmp_path):
    folder, index = _dataset(tmp_path)
    for e in index.entries:
        assert e.sha256 == dataset_index.sha256_file(folder / e.file)
    before = sorted(p.name for p in folder.iterdir())
    problems, counts = integrity.verify(folder, tmp_path / "ws")
    assert problems == [] and counts["hashed"] == 3
    assert sorted(p.name for p in folder.iterdir()) == before  # nothing written into DIR


def test_index_without_hashes_is_rebuilt_once(tmp_path):
    folder, index = _dataset(tmp_path)
    (ipath,) = (tmp_path / "ws" / "indexes").iterdir()  # a folder outside the workspace: its index lives there
    doc = json.loads(ipath.read_text())
    for t in doc["trials"]:
        del t["sha256"]
    ipath.write_text(json.dumps(doc))
    again = dataset_index.load_index(folder, tmp_path / "ws")
    assert all(e.sha256 for e in again.entries)
    assert all(t["sha256"] for t in json.loads(ipath.read_text())["trials"])


def test_verify_names_flipped_byte_truncation_and_gap(tmp_path):
    folder, index = _dataset(tmp_path)
    flipped, truncated, gappy = (folder / e.file for e in index.entries)
    data = bytearray(flipped.read_bytes())
    data[len(data) // 2] ^= 0x01
    flipped.write_bytes(bytes(data))
    truncated.write_bytes(truncated.read_bytes()[:-200])
    a = archive.read_archive(gappy)
    ts = a.timestamps.copy()
    ts[6:] += 0.04  # two frames lost before step 6
    np.savez(gappy, **npz_fields(a, timestamps=ts))  # rewritten behind the index's back
    problems, _ = integrity.verify(folder, tmp_path / "ws")
    text = [str(p) for p in problems]
    assert any(t.startswith(f"{flipped}: <file>: sha256 differs") for t in text), text
    assert any(t.startswith(f"{truncated}: <file>: ") and "truncated" in t for t in text), text
    assert any(t.startswith(f"{gappy}: timestamps: irregular: step 6 comes 60.0 ms after step 5") for t in text), text


def test_verify_command_exits_1_and_prints_each_problem(tmp_path):
    folder, index = _dataset(tmp_path)
    target = folder / index.entries[0].file
    target.write_bytes(target.read_bytes()[:100])
    cmd = [sys.executable, "-m", "experiments.verify", str(folder), f"--workdir={tmp_path / 'ws'}"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert f"{target}: <file>: " in done.stdout
    done = subprocess.run(cmd[:3] + [str(tmp_path / "nowhere")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.strip().count("\n") == 0


def test_a_fresh_import_is_hashed_against_the_index_the_import_wrote(tmp_path):
    manifest = example_rig.write_recordings(
        tmp_path / "rig", ["felt", "oak"], 2, seconds=(2.0, 2.5), splits={0: "train", 1: "test"}
    )
    out, ws = tmp_path / "archives", tmp_path / "ws"
    summary = batch.run(
        manifest, out, rig=manifest.parent / "rig.toml", workers=1, progress=False, say=lambda s: None, workdir=ws
    )
    assert Path(summary["index"]) == workspace.index_file(out, ws) and Path(summary["index"]).parent == ws / "indexes"
    assert {p.suffix for p in out.iterdir()} == {".npz"}  # the index lives in the workspace, not in DIR
    target = sorted(out.glob("*.npz"))[0]
    data = bytearray(target.read_bytes())
    data[len(data) // 2] ^= 0x01  # the bytes change after the import, behind the index's back
    target.write_bytes(bytes(data))
    cmd = [sys.executable, "-m", "experiments.verify", str(out)]
    done = subprocess.run(cmd + [f"--workdir={ws}"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert f"4 archives checked (4 hashed against {summary['index']})" in done.stdout, done.stdout
    assert f"{target}: <file>: sha256 differs" in done.stdout
    elsewhere = subprocess.run(
        cmd + [f"--workdir={tmp_path / 'other_ws'}"], capture_output=True, text=True, timeout=120
    )
    assert f"no index of {out} in this workspace, so no hashes to check" in elsewhere.stdout, elsewhere.stdout
    assert "sha256" not in elsewhere.stdout and not (tmp_path / "other_ws").exists()  # verify writes no index


def test_repeated_step_is_refused_at_load(tmp_path):
    a = tiny_archive(n_steps=10, images=None)
    ts = a.timestamps.copy()
    ts[4] = ts[3]
    path = tmp_path / "dup.npz"
    np.savez(path, **npz_fields(a, timestamps=ts))
    with pytest.raises(archive.ArchiveError, match=r"field 'timestamps': not strictly increasing: step 4"):
        archive.read_archive(path)


def test_reindexing_hashes_only_new_or_rewritten_archives(tmp_path, monkeypatch):
    folder = tiny_dataset(tmp_path / "data", TRIALS, n_steps=12, images=None)
    dataset_index.build_index(folder)
    hashed = []
    real = dataset_index.sha256_file
    monkeypatch.setattr(dataset_index, "sha256_file", lambda p: hashed.append(p.name) or real(p))
    dataset_index.build_index(folder)
    assert hashed == []
    a = tiny_archive(n_steps=12, fabric_id=9, images=None)
    archive.write_archive(folder / archive.trial_filename(a.meta), a)
    dataset_index.build_index(folder)
    assert hashed == [archive.trial_filename(a.meta)]


def test_verify_checks_every_file_of_a_folder_of_every_mutation(tmp_path):
    from tests.test_archive_fuzz import mutations

    folder = tmp_path / "data"
    folder.mkdir()
    bad = [data for _, data, kind, _ in mutations() if kind == "refuse"]
    for k, data in enumerate(bad):
        (folder / f"m{k:03d}.npz").write_bytes(data)
    archive.write_archive(folder / "good.npz", tiny_archive(n_steps=8, images=None))
    problems, counts = integrity.verify(folder, tmp_path / "ws")
    assert counts["archives"] == len(bad) + 1 and counts["failures"] == []
    assert sorted({Path(p.file).name for p in problems}) == [
        f"m{k:03d}.npz" for k in range(len(bad))
    ]  # each named, the good one not


def test_verify_names_its_own_failure_on_a_file_and_still_checks_the_rest(tmp_path, monkeypatch):
    folder, index = _dataset(tmp_path)
    first = folder / index.entries[0].file
    real = archive.read_archive

    def broken(path, **kw):
        if Path(path) == first:
            raise TypeError("a reader bug")
        return real(path, **kw)

    monkeypatch.setattr(archive, "read_archive", broken)
    truncated = folder / index.entries[2].file
    truncated.write_bytes(truncated.read_bytes()[:300])
    problems, counts = integrity.verify(folder, tmp_path / "ws")
    assert [str(f) for f in counts["failures"]] == [
        f"{first}: <verify>: verify failed on this file: TypeError: a reader bug"
    ]
    assert {p.file for p in problems} == {str(truncated)}


def test_a_data_dir_inside_the_workspace_gets_no_index(tmp_path):
    ws = tmp_path / "ws"
    folder = tiny_dataset(ws / "my_recordings", TRIALS, n_steps=12, images=None)
    before = sorted(p.name for p in folder.iterdir())
    dataset_index.load_index(folder, ws)
    assert sorted(p.name for p in folder.iterdir()) == before
    assert workspace.index_file(folder, ws).parent == ws / "indexes" and workspace.index_file(folder, ws).exists()
    sim = tiny_dataset(ws / "datasets" / "smoke", TRIALS, n_steps=12, images=None)  # the simulator's own: beside it
    assert workspace.index_file(sim, ws) == sim.resolve() / workspace.INDEX_NAME


_BROKEN_VERIFY = """
import sys
from fabricjax import cli
from fabricjax.store import integrity
def broken(p, entry, ipath):
    raise TypeError("a reader bug")
integrity._check_file = broken
from experiments import verify
sys.argv = ["verify", {folder!r}, "--workdir={workdir}"]
cli.run(verify.main)
"""


def test_verify_command_exits_2_on_its_own_failure_after_printing_every_file(tmp_path):
    folder, index = _dataset(tmp_path)
    code = _BROKEN_VERIFY.format(folder=str(folder), workdir=tmp_path / "ws")
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=Path(__file__).parents[1]
    )
    assert done.returncode == 2, done.stderr
    assert done.stdout.count("<verify>: verify failed on this file: TypeError: a reader bug") == 3
    assert "verify failed on 3 files (a bug of verify" in done.stderr
