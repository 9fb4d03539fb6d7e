"""The install check run back to back: memory stays flat, nothing is left running, every run agrees.

    python -m experiments.soak --results=results   # 50 runs as processes, then 50 in one process
    python -m experiments.soak --runs=6            # a shorter soak

The install check is README's `python -m experiments.ablation --preset=smoke --rows=internal,proprio
--seeds=2`. The soak runs it `runs` times as processes of their own, then `runs` times inside this
process through the library function (`ablation.STUDY.run`), all in one workspace of its own
(<workspace>/soak): the first run simulates the data and caches the features, and before every run
the rows' checkpoints are removed, so that every run trains both rows as a first run does.

It records no time: a soak measures what stays, and its runs' times are in their logs. Per run it
records the resident memory (a process's peak, from `wait4`; in this process, the resident set after
the run, once garbage is collected and freed pages returned), what is left running after it
(processes in a run's session; in this process, its Python threads, its native threads and its child
processes) and both rows' per-seed test accuracies. It holds when, from the `FROM_RUN`th run to the
last, the memory stays within `FLAT` of the `FROM_RUN`th's, nothing is left running and every run's
accuracies are identical.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import gc
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
from absl import logging
from tqdm import tqdm

from fabricjax.reporting import plots, results_files
from fabricjax.store import workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents
from fabricjax.studies.paper import ablation

STUDY = "soak"
RUNS = 50
PRESET, ROWS, SEEDS = "smoke", ("internal", "proprio"), 2
INSTALL_CHECK = ["-m", "experiments.ablation", f"--preset={PRESET}", f"--rows={','.join(ROWS)}", f"--seeds={SEEDS}"]
FROM_RUN = 5  # the runs before it warm caches up (data, features, compiled programs, allocator pools)
FLAT = 0.10  # largest relative change of resident memory from run FROM_RUN to the last
# how long a run's processes get to end after it: multiprocessing's resource tracker ends when its
# parent's pipe closes, just after the parent, and a pool worker within `parallel.PARENT_POLL_S`
LEFT_GRACE_S = 2.0
THREADS_SPARE = 1  # native threads a run may end with beyond run FROM_RUN's: XLA's and BLAS's pools start one lazily
MEASURED = {"processes": "each run's peak", "one process": "kept after each run"}  # what memory means per way


@dataclasses.dataclass(frozen=True)
class Run:
    """One install check: its resident memory [MB], what it left running, its accuracies."""

    rss_mb: float
    left: list[str]  # what was still running after the run, named
    accuracy: dict[str, list[float]]  # {row: per-seed test accuracy}
    native_threads: int | None = None  # in this process: its threads after the run, XLA's included


@dataclasses.dataclass(frozen=True)
class Soak:
    """The runs of one way of running the install check, and whether they hold."""

    way: str  # "processes" or "one process"
    runs: list[Run]

    @property
    def memory_change(self) -> float:
        """Relative change of resident memory from run `FROM_RUN` to the last."""
        first = self.runs[min(FROM_RUN, len(self.runs)) - 1].rss_mb
        return self.runs[-1].rss_mb / first - 1.0

    @property
    def left(self) -> list[str]:
        """What each run left running, as "run k: what"."""
        return [f"run {k}: {x}" for k, r in enumerate(self.runs, 1) for x in r.left]

    @property
    def memory_trend(self) -> float:
        """Least-squares slope of resident memory [MB per run] from run `FROM_RUN` to the last."""
        mb = [r.rss_mb for r in self.runs[FROM_RUN - 1 :]]
        return float(np.polyfit(np.arange(len(mb)), mb, 1)[0]) if len(mb) > 1 else 0.0

    @property
    def native_threads_grew(self) -> bool:
        """The last run ends with more than `THREADS_SPARE` native threads beyond run `FROM_RUN`'s:
        what a thread left per run would show, where a pool that starts one more thread once would not."""
        counts = [r.native_threads for r in self.runs[FROM_RUN - 1 :] if r.native_threads is not None]
        return bool(counts) and counts[-1] > counts[0] + THREADS_SPARE

    @property
    def identical(self) -> bool:
        return all(r.accuracy == self.runs[0].accuracy for r in self.runs)

    @property
    def holds(self) -> bool:
        return abs(self.memory_change) <= FLAT and not self.left and not self.native_threads_grew and self.identical


def soak_root(workdir=None) -> Path:
    """The soak's own workspace: it removes checkpoints between runs, so it never shares one."""
    return workspace.root(workdir) / "soak"


def _accuracies(doc: dict[str, Any]) -> dict[str, list[float]]:
    return {r["name"]: r["accuracy"]["test"]["fabric"] for r in doc["rows"]}


def _processes(where) -> list[str]:
    """Live processes whose /proc stat fields (after "pid (command)": state, ppid, pgrp, session, ...)
    satisfy `where`, as 'pid command'."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        fields = text[text.rindex(")") + 2 :].split()
        if fields[0] != "Z" and where(fields):
            out.append(f"{stat.parent.name} {text[text.index('(') + 1 : text.rindex(')')]}")
    return out


def _session_processes(session: int) -> list[str]:
    """Processes still alive in `session` (a run started as its own session's leader)."""
    return _processes(lambda fields: int(fields[3]) == session)


def _children() -> list[str]:
    """This process's live child processes."""
    me = os.getpid()
    return _processes(lambda fields: int(fields[1]) == me)


def _still_running(alive: Callable[[], list[str]]) -> list[str]:
    """What `alive()` names once `LEFT_GRACE_S` has passed (or as soon as it names nothing)."""
    deadline = time.monotonic() + LEFT_GRACE_S
    while (left := alive()) and time.monotonic() < deadline:
        time.sleep(0.1)
    return left


def _retained_mb() -> float:
    """This process's resident memory [MB] once garbage is collected and the allocator has handed
    its free pages back: what a run keeps, not when Python's collector or glibc last ran."""
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: the resident set as it is
        pass
    return _status("VmRSS") / 1024


def _status(field: str) -> int:
    """A field of /proc/self/status (kB for memory fields)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(f"{field}:"):
            return int(line.split()[1])
    raise KeyError(field)


def as_processes(runs: int, root: Path, progress: bool = True) -> Soak:
    """The install check as `runs` processes, one after the other, each its own session."""
    out = []
    for i in tqdm(range(runs), desc="soak: processes", unit="run", disable=not progress):
        shutil.rmtree(workspace.checkpoints_dir(ablation.STUDY.name, root), ignore_errors=True)
        results = root / "runs" / f"process{i + 1}"
        with open(root / "runs" / f"process{i + 1}.log", "w") as log:
            proc = subprocess.Popen(
                [sys.executable, *INSTALL_CHECK, f"--workdir={root}", f"--results={results}"],
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
            _, status, usage = os.wait4(proc.pid, 0)
            proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise RuntimeError(f"run {i + 1} of the install check failed: see {workspace.shown(log.name)}")
        doc = json.loads((results / f"{ablation.STUDY.name}.json").read_text())
        out.append(Run(usage.ru_maxrss / 1024, _still_running(lambda: _session_processes(proc.pid)), _accuracies(doc)))
    return Soak("processes", out)


def in_one_process(runs: int, root: Path, progress: bool = True) -> Soak:
    """The install check `runs` times in this process through the library function."""
    out = []
    verbosity = logging.get_verbosity()
    for i in tqdm(range(runs), desc="soak: one process", unit="run", disable=not progress):
        shutil.rmtree(workspace.checkpoints_dir(ablation.STUDY.name, root), ignore_errors=True)
        threads = set(threading.enumerate())
        where = Location(workdir=root, results=root / "runs" / f"one_process{i + 1}")
        with open(root / "runs" / f"one_process{i + 1}.log", "w") as log:
            logging.set_verbosity(logging.WARNING)
            try:
                with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
                    doc = ablation.STUDY.run(n_seeds=SEEDS, preset=PRESET, rows=list(ROWS), where=where)
            finally:
                logging.set_verbosity(verbosity)
        left = _still_running(
            lambda: (
                [f"thread {t.name}" for t in set(threading.enumerate()) - threads if t.is_alive()]
                + [f"process {p}" for p in _children()]
            )
        )
        out.append(Run(_retained_mb(), left, _accuracies(doc), _status("Threads")))
    return Soak("one process", out)


def run(*, runs: int = RUNS, where: Location = Location(), progress: bool = True) -> dict[str, Any]:
    """Both soaks; writes results/soak.{md,json} and soak.png."""
    root = soak_root(where.workdir)
    (root / "runs").mkdir(parents=True, exist_ok=True)
    soaks = [as_processes(runs, root, progress), in_one_process(runs, root, progress)]
    folder = where.results_dir()
    figure = plots.plot_soak(
        folder / f"{STUDY}.png",
        [(f"{s.way}: {MEASURED[s.way]}", [r.rss_mb for r in s.runs]) for s in soaks],
        FROM_RUN,
        FLAT,
    )
    doc = {
        **documents.header(
            STUDY,
            module=__name__,
            command=where.command,
            install_check="python " + " ".join(INSTALL_CHECK),
            runs=runs,
            from_run=FROM_RUN,
            flat=FLAT,
        ),
        "ways_agree": all(s.runs[0].accuracy == soaks[0].runs[0].accuracy for s in soaks),
        "soaks": [
            {
                "way": s.way,
                "runs": [dataclasses.asdict(r) for r in s.runs],
                "memory_change": s.memory_change,
                "memory_trend_mb_per_run": s.memory_trend,
                "left": s.left,
                "native_threads_grew": s.native_threads_grew,
                "identical": s.identical,
                "holds": s.holds,
            }
            for s in soaks
        ],
    }
    return results_files.write(folder, doc, markdown, figures=[figure])


def markdown(doc: dict[str, Any]) -> str:
    first, flat = doc["from_run"], doc["flat"]
    rows = []
    for s in doc["soaks"]:
        rss = [r["rss_mb"] for r in s["runs"]]
        threads = [r["native_threads"] for r in s["runs"] if r["native_threads"] is not None]
        rows.append(
            [
                s["way"],
                len(s["runs"]),
                f"{rss[0]:.0f}",
                f"{rss[min(first, len(rss)) - 1]:.0f}",
                f"{rss[-1]:.0f}",
                f"{100 * s['memory_change']:+.1f} %",
                f"{s['memory_trend_mb_per_run']:+.2f}",
                ", ".join(s["left"]) or "nothing",
                f"{min(threads[1:])}-{max(threads[1:])}" if len(threads) > 1 else "-",
                "yes" if s["identical"] else "no",
                "yes" if s["holds"] else "**no**",
            ]
        )
    accuracy = doc["soaks"][0]["runs"][0]["accuracy"]
    agree = "the same in both ways" if doc["ways_agree"] else "**not the same in both ways**"
    lines = [
        "# The install check, back to back",
        "",
        documents.header_markdown(doc),
        "",
        f"The install check (`{doc['install_check']}`) ran {doc['runs']} times as processes of their own, then "
        f"{doc['runs']} times inside one process through the library function (`ablation.STUDY.run`), in a "
        "workspace of its own; every run trained both rows (their checkpoints removed before it). Memory: a "
        "process's peak resident set; in one process, its resident set after the run, once garbage is collected "
        "and freed pages returned. Left running (after a grace of a few seconds): processes "
        "in a run's session; in one process, Python threads started by a run and child processes alive after it. "
        f"It holds when memory from run {first} to the last changes by at most {100 * flat:.0f} %, nothing is "
        f"left running, native threads end at most one above run {first}'s (pools start a thread lazily), and "
        f"every run's accuracies are identical. The trend is the least-squares slope of memory from run {first} on.",
        "",
        results_files.markdown_table(
            [
                "Runs",
                "n",
                "memory, run 1 [MB]",
                f"run {first} [MB]",
                "last [MB]",
                f"change from run {first}",
                "trend [MB per run]",
                "left running",
                "native threads after runs 2..n",
                "identical accuracies",
                "holds",
            ],
            rows,
        ),
        "",
        "The first run's test accuracy per seed: "
        + "; ".join(f"{row} {', '.join(f'{100 * a:.2f} %' for a in accs)}" for row, accs in accuracy.items())
        + f"; {agree}.",
        "",
        f"![resident memory per run]({doc['figures'][0]})",
        "",
    ]
    return "\n".join(lines)
