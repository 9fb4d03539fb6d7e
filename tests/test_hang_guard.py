"""A hung test fails within minutes and shows where it hangs, instead of running into CI's limit."""

import subprocess
import sys
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_test_has_a_time_limit_of_minutes():
    options = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert 0 < options["timeout"] <= 600 and options["timeout_method"] == "thread"


def test_a_deadlocked_test_fails_fast_and_prints_every_threads_stack(tmp_path):
    (tmp_path / "test_hangs.py").write_text(
        "import threading\n\n\ndef test_waits_for_itself():\n    lock = threading.Lock()\n    lock.acquire()\n"
        "    lock.acquire()\n"
    )
    start = time.monotonic()
    run = subprocess.run(
        [sys.executable, "-m", "pytest", str(tmp_path / "test_hangs.py"), "-c", str(ROOT / "pyproject.toml")]
        + ["--rootdir", str(tmp_path), "-n0", "-p", "no:cacheprovider", "-o", "timeout=2"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    out = run.stdout + run.stderr
    assert run.returncode != 0 and time.monotonic() - start < 60
    assert "Timeout" in out and "Stack of MainThread" in out and "lock.acquire()" in out, out[-2000:]
