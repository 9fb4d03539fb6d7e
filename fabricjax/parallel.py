"""One way to run independent per-trial jobs on every core: the simulator and the feature cache.

Jobs run in spawned processes through `concurrent.futures` (not `multiprocessing.Pool`): a worker
that dies raises `BrokenProcessPool` in the caller instead of hanging the run, and its workers are
not daemonic, so a job may start processes of its own. One worker runs the jobs in this process.
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Sequence


def run_jobs(fn: Callable, jobs: Sequence, workers: int, on_done: Callable[[], None], initializer: Callable[[], None] | None = None) -> None:
    """Call `fn(job)` for every job (results dropped: jobs write their own outputs), calling
    `on_done()` after each, in `min(workers, len(jobs))` processes; the first failing job's
    exception (in job order, whichever finished first) reaches the caller."""
    workers = min(workers, len(jobs))
    if workers <= 1:
        for job in jobs:
            fn(job)
            on_done()
        return
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"), initializer=initializer) as pool:
        for done in [pool.submit(fn, job) for job in jobs]:  # in job order: the first failing job's error is raised
            done.result()
            on_done()
