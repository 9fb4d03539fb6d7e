"""One way to run independent per-trial jobs on every core (the simulator and the feature cache),
and to read ahead of a consumer in threads.

Jobs run in spawned processes through `concurrent.futures` (not `multiprocessing.Pool`): a worker
that dies raises `BrokenProcessPool` in the caller instead of hanging the run, and its workers are
not daemonic, so a job may start processes of its own. One worker runs the jobs in this process. Every worker watches
its parent
(`_exit_with_parent`): killing the parent (kill -9 included) ends its workers too.
"""

from __future__ import annotations

import collections
import functools
import itertools
import multiprocessing
import os
import threading
import time
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from typing import Callable, Iterator, Sequence, TypeVar

T = TypeVar("T")
R = TypeVar("R")

PARENT_POLL_S = 0.5  # how soon a worker notices its parent is gone


def run_jobs(
    fn: Callable,
    jobs: Sequence,
    workers: int,
    on_done: Callable[[], None],
    initializer: Callable[[], None] | None = None,
) -> None:
    """Call `fn(job)` for every job (results dropped: jobs write their own outputs), calling
    `on_done()` after each, in `min(workers, len(jobs))` processes; the first failing job's
    exception (in job order, whichever finished first) reaches the caller."""
    workers = min(workers, len(jobs))
    if workers <= 1:
        for job in jobs:
            fn(job)
            on_done()
        return
    start = functools.partial(_start_worker, os.getpid(), initializer)
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"), initializer=start)
    try:
        for done in [pool.submit(fn, job) for job in jobs]:  # in job order: the first failing job's error is raised
            done.result()
            on_done()
    finally:  # on an error too: the jobs not yet started are dropped, not run before the error is raised
        pool.shutdown(wait=True, cancel_futures=True)


def ordered_ahead(pool: Executor, fn: Callable[[T], R], items: Sequence[T], ahead: int) -> Iterator[R]:
    """`fn(item)` for each item in order, computed in `pool` at most `ahead` items before the one
    consumed (`Executor.map` submits every item at once, so its results pile up in memory when the
    consumer is the slower side). The pool belongs to the caller, who shuts it down: an iterator
    left unfinished then holds nothing that must be joined."""
    pending: collections.deque[Future[R]] = collections.deque()
    rest = iter(items)
    for item in itertools.islice(rest, ahead):
        pending.append(pool.submit(fn, item))
    while pending:
        result = pending.popleft().result()
        for item in itertools.islice(rest, 1):
            pending.append(pool.submit(fn, item))
        yield result


def _start_worker(parent: int, initializer: Callable[[], None] | None) -> None:
    _exit_with_parent(parent)
    if initializer is not None:
        initializer()


def _exit_with_parent(parent: int) -> None:
    """The worker ends when the process `parent` that started the pool is gone (killed), rather
    than waiting for jobs forever as an orphan. The parent's pid comes from the parent itself: a
    worker still starting when the parent is killed would otherwise take its new parent for it."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
