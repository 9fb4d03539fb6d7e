"""Whoever starts a process or a pool ends it on every path: an error or an early stop leaves
nothing running."""

import os
import time

import pytest

from acquisition import wire
from fabricjax import parallel


def test_arecord_ends_when_its_reader_stops_early(tmp_path, monkeypatch):
    pid_file = tmp_path / "pid"
    fake = tmp_path / "arecord"
    fake.write_text(f"#!/bin/sh\necho $$ > {pid_file}\nexec cat /dev/zero\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    with pytest.raises(ConnectionError):
        with wire.arecord_periods("hw:test") as periods:
            assert len(next(periods)) == wire.PERIOD * wire.FRAME_BYTES
            raise ConnectionError("the receiver went away")
    with pytest.raises(ProcessLookupError):  # ended and reaped
        os.kill(int(pid_file.read_text()), 0)


def _job(job):
    folder, k = job
    if k == 0:
        raise ValueError("the first job fails")
    time.sleep(1.0)
    (folder / f"done{k}").touch()


def test_a_failing_job_drops_the_jobs_not_started(tmp_path):
    jobs = [(tmp_path, k) for k in range(20)]
    with pytest.raises(ValueError, match="first job fails"):
        parallel.run_jobs(_job, jobs, 2, lambda: None)
    # the running jobs and those already in the pool's call queue (workers + 1) finish; not all 19
    assert len(list(tmp_path.glob("done*"))) <= 6


def test_the_soak_sees_a_process_left_in_a_runs_session():
    import subprocess

    from fabricjax.studies.release import soak

    leader = subprocess.Popen(["sh", "-c", "sleep 30 & exit 0"], start_new_session=True)
    leader.wait()
    try:
        left = soak._session_processes(leader.pid)
        assert left and all(int(entry.split()[0]) != leader.pid for entry in left), left
    finally:
        for entry in left:
            os.kill(int(entry.split()[0]), 9)


def test_the_soak_holds_only_when_memory_is_flat_nothing_is_left_and_runs_agree():
    from fabricjax.studies.release.soak import FROM_RUN, Run, Soak

    def soak(rss, left=(), accuracies=None, threads=None):
        acc = accuracies or [{"internal": [0.5, 0.6]}] * len(rss)
        return Soak(
            "processes", [Run(m, list(left) if i == 2 else [], a, threads) for i, (m, a) in enumerate(zip(rss, acc))]
        )

    flat = [900.0] * (FROM_RUN - 1) + [600.0, 640.0, 655.0]  # warm-up runs before FROM_RUN do not count
    assert soak(flat).holds and abs(soak(flat).memory_change - 55 / 600) < 1e-12
    assert not soak(flat[:-1] + [700.0]).holds  # +16.7 %
    assert not soak(flat, left=["thread feature-cache-reader_0"]).holds
    assert not soak(flat, accuracies=[{"internal": [0.5, 0.6]}] * 6 + [{"internal": [0.5, 0.61]}]).holds
