"""A workspace that cannot mix runs: one writer at a time (`fabricjax.store.lock`), a full disk in one
line with nothing half-written (`fabricjax.store.disk`, `fabricjax.store.atomic`), results written as a set,
and no process pool outliving its parent (`fabricjax.parallel`)."""

import errno
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from fabricjax.config import Config
from fabricjax.store import atomic, disk, lock
from fabricjax.training import checkpoint

REPO = Path(__file__).resolve().parents[1]

HOLD = """
import sys, time
from fabricjax.store import lock
thing = lock.lock_file(sys.argv[1], sys.argv[2])
with lock.hold(thing, "the thing", "writing it for a test", shared=sys.argv[3] == "shared"):
    print("held", flush=True)
    time.sleep(120)
"""


def _holder(tmp_path, how="exclusive"):
    thing = tmp_path / "thing"
    p = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(thing), str(tmp_path / "ws"), how], stdout=subprocess.PIPE, text=True, cwd=REPO
    )
    assert p.stdout.readline().strip() == "held"
    return p, lock.lock_file(thing, tmp_path / "ws")


def test_a_second_writer_is_refused_in_one_line_naming_the_first_and_a_kill_frees_the_lock(tmp_path):
    p, path = _holder(tmp_path)
    try:
        for shared in (False, True):
            with pytest.raises(lock.Busy) as e:
                with lock.hold(path, "the thing", "a second run", shared=shared):
                    pass
            message = str(e.value)
            assert f"PID {p.pid}" in message and "writing it for a test" in message and "\n" not in message
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    with lock.hold(path, "the thing", "after the kill"):  # the kernel released it with the process
        pass


def test_readers_share_a_lock_and_a_reader_cannot_become_a_writer_while_another_reads(tmp_path):
    p, path = _holder(tmp_path, "shared")
    try:
        with lock.hold(path, "the thing", "reading too", shared=True):
            with pytest.raises(lock.Busy, match=f"PID {p.pid}"):
                with lock.hold(path, "the thing", "simulating it"):
                    pass
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    with lock.hold(path, "the thing", "reading", shared=True):
        with lock.hold(path, "the thing", "writing after reading"):  # alone: the upgrade succeeds
            with lock.hold(path, "the thing", "nested", shared=True):
                pass


def test_a_full_disk_while_writing_a_file_is_one_error_and_leaves_the_old_file(tmp_path):
    target = tmp_path / "index.json"
    target.write_text("old")
    with pytest.raises(disk.DiskFull) as e:
        with atomic.atomic_open(target, "w", what="the dataset index") as f:
            f.write("x" * 5000)
            raise OSError(errno.ENOSPC, "No space left on device")
    message = str(e.value)
    assert (
        message.startswith(f"no space left on the disk for the dataset index ({target}): needs at least 5 kB,")
        and "\n" not in message
    )
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["index.json"]


def test_results_written_together_appear_all_or_none(tmp_path):
    for name in ("a.md", "a.json", "a.png"):
        (tmp_path / name).write_text("old")
    with pytest.raises(disk.DiskFull):
        with atomic.together():
            for name in ("a.md", "a.json"):
                with atomic.atomic_open(tmp_path / name, "w") as f:
                    f.write("new")
            with atomic.atomic_open(tmp_path / "a.png", "w") as f:
                raise OSError(errno.ENOSPC, "No space left on device")
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == {"a.md": "old", "a.json": "old", "a.png": "old"}
    with atomic.together():
        for name in ("a.md", "a.json", "a.png"):
            with atomic.atomic_open(tmp_path / name, "w") as f:
                f.write("new")
        assert (tmp_path / "a.md").read_text() == "old"  # not before the set is complete
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == dict.fromkeys(("a.md", "a.json", "a.png"), "new")


def test_sizes_below_a_gigabyte_are_not_rounded_to_zero():
    assert (disk.size(3.2e9), disk.size(4.6e6), disk.size(1.2e4)) == ("3.2 GB", "5 MB", "12 kB")


def test_a_checkpoint_that_would_not_fit_is_refused_before_orbax_writes(tmp_path, monkeypatch):
    state = {"params": np.zeros((1000,), np.float32)}
    mngr = checkpoint.manager(tmp_path / "ckpt")
    monkeypatch.setattr(disk, "free_bytes", lambda path: 1000)
    with pytest.raises(
        disk.DiskFull, match=r"for the checkpoint of epoch 2 \(.*ckpt\): needs at least 4 kB, 1 kB free"
    ):
        checkpoint.save(mngr, 2, state, checkpoint.meta(Config.from_preset("smoke"), [0], {}))
    assert mngr.latest_step() is None and not list((tmp_path / "ckpt").iterdir())


FULL_IN_A_LIBRARY = """
from fabricjax import cli
def main(argv):
    raise RuntimeError("Event loop is closed") from OSError(28, "No space left on device", "/data/ws/checkpoints/x/4")
cli.run(main, before=lambda: None)
"""


def test_a_full_disk_found_by_a_librarys_own_write_is_one_line():
    r = subprocess.run([sys.executable, "-c", FULL_IN_A_LIBRARY], capture_output=True, text=True, cwd=REPO)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and r.stderr.startswith(
        "error: no space left on the disk for a file (/data/ws/checkpoints/x/4)"
    )


ORPHANS = """
import os, sys, time
from fabricjax import parallel

def job(path):
    open(path, "w").write(str(os.getpid()))
    time.sleep(300)

if __name__ == "__main__":
    parallel.run_jobs(job, [sys.argv[1] + "/a", sys.argv[1] + "/b"], 2, lambda: None)
"""


def test_no_pool_worker_outlives_its_killed_parent(tmp_path):
    script = tmp_path / "pool.py"
    script.write_text(textwrap.dedent(ORPHANS))
    p = subprocess.Popen(
        [sys.executable, str(script), str(tmp_path)], cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO)}
    )
    deadline = time.time() + 60
    while not all((tmp_path / n).exists() and (tmp_path / n).read_text() for n in "ab"):
        assert time.time() < deadline, "the workers did not start"
        time.sleep(0.2)
    workers = [int((tmp_path / n).read_text()) for n in "ab"]
    p.send_signal(signal.SIGKILL)
    p.wait()
    deadline = time.time() + 5
    while any(_running(w) for w in workers) and time.time() < deadline:
        time.sleep(0.1)
    assert not any(_running(w) for w in workers), "a worker outlived its parent by 5 s"


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


def test_results_of_another_preset_or_data_are_replaced_with_a_note(tmp_path, capsys):
    from fabricjax.reporting import results_files

    doc = lambda preset, folder: {"study": "ablation", "preset": preset, "dataset": {"folder": folder}}  # noqa: E731
    results_files.write(tmp_path, doc("smoke", "workspace/datasets/smoke"), None)
    results_files.write(tmp_path, doc("smoke", "workspace/datasets/smoke"), None)  # the same run again: nothing to say
    assert "note:" not in capsys.readouterr().err
    results_files.write(tmp_path, doc("default", "workspace/datasets/default"), None)
    err = capsys.readouterr().err
    assert "held the results of preset smoke on workspace/datasets/smoke" in err and "--results=DIR keeps both" in err
