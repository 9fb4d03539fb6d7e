"""Runs through one workspace: two datasets never share a model, a killed row resumes to the
uninterrupted run's bits, two runs started together never mix or hang, and a full disk at any
write is one line, with a rerun after freeing space giving the clean results."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fabricjax import presets
from fabricjax.store.workspace import Location
from fabricjax.studies.paper import ablation
from tests.helpers import tiny_dataset

REPO = Path(__file__).resolve().parents[1]
TRIALS = [(t.fabric_id, t.day, t.trial, t.condition) for t in presets.get("smoke").dataset.trials()]
# one grid point, two epochs of a small model: what these tests compare is where a model comes
# from, not how good it is
QUICK = dict(epochs=2, train_steps=0, patience_steps=0, patience=0, width=16, n_layers=1, lr_grid=(), width_grid=())


def _outcome(doc):
    """Each row's per-seed accuracies and validation curves: what a reused model would repeat."""
    return {
        r["name"]: (r["accuracy"], {tag: v for tag, v in r["epochs"].items() if tag != "epoch_wall_s"})
        for r in doc["rows"]
    }


@pytest.mark.slow  # ~30 s: four small trainings
def test_two_datasets_through_one_workspace_each_give_their_fresh_workspace_result(tmp_path):
    a = tiny_dataset(tmp_path / "a", TRIALS, n_steps=41, images=None)
    b = tiny_dataset(tmp_path / "b", TRIALS, n_steps=41, images=None, seed=1000)

    def run(data, workdir):
        where = Location(workdir=workdir, data_dir=data, results=tmp_path / "results", command="test")
        return _outcome(ablation.run(n_seeds=1, rows=["internal"], preset="smoke", overrides=QUICK, where=where))

    shared = tmp_path / "shared"
    first_a, then_b, a_again = run(a, shared), run(b, shared), run(a, shared)
    fresh_b = run(b, tmp_path / "fresh")
    assert json.dumps(then_b, sort_keys=True) == json.dumps(fresh_b, sort_keys=True)
    assert json.dumps(a_again, sort_keys=True) == json.dumps(first_a, sort_keys=True)
    assert json.dumps(then_b, sort_keys=True) != json.dumps(first_a, sort_keys=True)  # B's model is not A's


def _command(workdir, results, epochs=2, seeds=1):
    return [
        sys.executable,
        "-m",
        "experiments.ablation",
        "--preset=smoke",
        "--rows=internal",
        f"--seeds={seeds}",
        f"--set=epochs={epochs}",
        "--set=width=16",
        "--set=n_layers=1",
        f"--workdir={workdir}",
        f"--results={results}",
    ]


def _accuracies(results):
    return {r["name"]: r["accuracy"] for r in json.loads((Path(results) / "ablation.json").read_text())["rows"]}


def _session_processes(sid: int) -> list[int]:
    out = subprocess.run(["ps", "-eo", "pid=,sid=,stat="], capture_output=True, text=True).stdout.split("\n")
    return [
        int(p)
        for p, s, st in (line.split() for line in out if line.strip())
        if int(s) == sid and not st.startswith("Z")
    ]


@pytest.mark.slow  # ~2 min: three smoke trainings of 6 epochs
def test_a_row_killed_mid_way_resumes_from_its_last_save_to_the_uninterrupted_bits(tmp_path):
    from fabricjax.training import train

    clean, killed = tmp_path / "clean", tmp_path / "killed"
    command = lambda ws, res: _command(ws, res, epochs=6, seeds=2)  # noqa: E731  saves at epochs 2, 4 and 6
    subprocess.run(command(clean, tmp_path / "r_clean"), check=True, cwd=REPO, capture_output=True)
    killed.mkdir()
    shutil.copytree(clean / "datasets", killed / "datasets")
    p = subprocess.Popen(
        command(killed, tmp_path / "r_killed"),
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.time() + 300
    while not list(killed.glob("checkpoints/ablation/internal-*/2/")):
        assert p.poll() is None and time.time() < deadline, "the run ended before its first save"
        time.sleep(0.05)
    p.send_signal(signal.SIGKILL)
    p.wait()
    time.sleep(5)
    assert _session_processes(p.pid) == []  # nothing of the killed run is left
    assert not list(killed.glob("checkpoints/ablation/internal-*/6"))  # killed mid-row
    subprocess.run(command(killed, tmp_path / "r_killed"), check=True, cwd=REPO, capture_output=True)
    assert _accuracies(tmp_path / "r_killed") == _accuracies(tmp_path / "r_clean")
    (a,), (b,) = (list(ws.glob("checkpoints/ablation/internal-*")) for ws in (clean, killed))
    for x, y in zip(*(jax_leaves(train.restore(d).state) for d in (a, b)), strict=True):
        np.testing.assert_array_equal(x, y)


def jax_leaves(tree):
    import jax

    return [np.asarray(x) for x in jax.tree.leaves(tree)]


@pytest.mark.slow  # ~5 min: 20 pairs of smoke runs
def test_two_runs_started_together_both_finish_clean_or_the_second_refuses_in_one_line(tmp_path):
    ws = tmp_path / "ws"
    subprocess.run(_command(ws, tmp_path / "clean"), check=True, cwd=REPO, capture_output=True)
    clean = _accuracies(tmp_path / "clean")
    outcomes = []
    for rep in range(20):
        shutil.rmtree(ws / "checkpoints", ignore_errors=True)
        runs = [
            subprocess.Popen(
                _command(ws, tmp_path / f"r{rep}_{k}"),
                cwd=REPO,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
            )
            for k in range(2)
        ]
        for k, p in enumerate(runs):
            try:
                _, err = p.communicate(timeout=300)
            except subprocess.TimeoutExpired:
                p.kill()
                pytest.fail(f"repetition {rep}: run {k} hung")
            lines = [line for line in err.splitlines() if line.startswith("error:")]
            if p.returncode == 0:
                assert _accuracies(tmp_path / f"r{rep}_{k}") == clean
                outcomes.append("finished")
            else:
                assert p.returncode == 2 and len(lines) == 1 and "is in use by PID" in lines[0], err[-2000:]
                assert not (tmp_path / f"r{rep}_{k}" / "ablation.json").exists()
                outcomes.append("refused")
        assert "finished" in outcomes[-2:]
    print({o: outcomes.count(o) for o in set(outcomes)})


def _tmpfs(path: Path, size: int) -> None:
    path.mkdir(parents=True, exist_ok=True)
    if os.path.ismount(path):
        subprocess.run(["mount", "-o", f"remount,size={size}", str(path)], check=True)
    else:
        subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], check=True)


def _can_mount(tmp_path) -> bool:
    try:
        _tmpfs(tmp_path / "probe", 1 << 20)
    except (OSError, subprocess.CalledProcessError):
        return False
    subprocess.run(["umount", str(tmp_path / "probe")], check=False)
    return True


def _used(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def _leave_free(mount: Path, free: int) -> None:
    """Fill the file system at `mount` so that about `free` bytes stay free."""
    ballast = mount / "ballast"
    ballast.unlink(missing_ok=True)
    fill = shutil.disk_usage(mount).free - free
    if fill > 0:
        with open(ballast, "wb") as f:
            os.posix_fallocate(f.fileno(), 0, fill)


def _check_full_run(mount: Path, seen: set) -> None:
    """Run the smoke ablation on the nearly full `mount`: it ends in one line or completes, and
    leaves nothing half-written; the write it ended at goes into `seen`."""
    r = subprocess.run(_command(mount / "ws", mount / "results"), cwd=REPO, capture_output=True, text=True)
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    if r.returncode != 0:
        assert r.returncode == 2 and len(errors) == 1 and "no space left on the disk" in errors[0], r.stderr[-3000:]
        assert "Traceback" not in r.stderr, r.stderr[-3000:]
        what, where = errors[0].removeprefix("error: no space left on the disk for ").split(" (", 1)
        seen.add((what, Path(where.split(")")[0]).relative_to(mount).parts[:3]))
    half = [p for p in mount.rglob("*") if p.name.endswith(".partial") or "orbax-checkpoint-tmp" in p.name]
    assert half == [], half
    results = {p.suffix for p in (mount / "results").glob("ablation.*")} if (mount / "results").exists() else set()
    assert results in (set(), {".md", ".json"}, {".md", ".json", ".png"}), results  # a set, or none


@pytest.mark.slow  # ~5 min: a smoke run on a file system filled to leave less and less, each full at another write
def test_a_full_disk_at_every_write_is_one_line_and_a_rerun_with_space_gives_the_clean_results(tmp_path):
    if not _can_mount(tmp_path):
        pytest.skip("mounting a small file system needs root")
    mount = tmp_path / "small"
    _tmpfs(mount, 1 << 30)
    try:
        subprocess.run(_command(mount / "ws", mount / "results"), check=True, cwd=REPO, capture_output=True)
        clean = _accuracies(mount / "results")
        dataset = _used(mount / "ws" / "datasets")
        after_dataset = _used(mount) - dataset  # what a run writes once the dataset exists
        seen: set[str] = set()
        cases = [(0.5, True)] + [(f, False) for f in (0.02, 0.1, 0.3, 0.5, 0.7, 0.8, 0.9, 0.95, 0.98, 0.995)]
        for fraction, from_empty in cases:  # from an empty workspace (the simulator), then with the dataset there
            for p in list(mount.iterdir()):
                if p.name != "ws":
                    shutil.rmtree(p) if p.is_dir() else p.unlink()
            for p in list((mount / "ws").iterdir()):
                if from_empty or p.name != "datasets":
                    shutil.rmtree(p)
            _leave_free(mount, int((dataset if from_empty else after_dataset) * fraction))
            _check_full_run(mount, seen)
            (mount / "ballast").unlink(missing_ok=True)  # space freed: the rerun completes with the clean results
            subprocess.run(_command(mount / "ws", mount / "results"), check=True, cwd=REPO, capture_output=True)
            assert _accuracies(mount / "results") == clean
        print(sorted(seen))
        assert len({what for what, _ in seen}) >= 4, (
            seen
        )  # the simulator's check and at least three write sites after it
    finally:
        subprocess.run(["umount", str(mount)], check=False)
