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
    jobs = [(tmp_path, k) for k in range(12)]
    with pytest.raises(ValueError, match="first job fails"):
        parallel.run_jobs(_job, jobs, 2, lambda: None)
    # the running jobs and those already handed to a worker finish (at most 2 per worker); not all 11
    assert len(list(tmp_path.glob("done*"))) <= 4
