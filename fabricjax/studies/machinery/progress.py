"""The progress log of a study's rows: each row's start and end, the elapsed time and an ETA."""

from __future__ import annotations

import time
from typing import Sequence

from absl import logging


class Progress:
    """The progress log of a study's rows: 'row i/n' with the elapsed time and an ETA.

    Each row has a kind (`row_training.row_kind`) and an amount of work (default 1; the sweep's
    rows: their epochs); a row left is expected to take its work times the seconds per unit of
    work of the rows of its kind done so far (of every row done while none of its kind is), so a
    camera row run first does not inflate the estimate for the audio rows after it. The rates are
    this run's own: nothing measured elsewhere."""

    def __init__(
        self, study: str, n_rows: int, kinds: Sequence[str] | None = None, work: Sequence[float] | None = None
    ):
        self.kinds = list(kinds) if kinds is not None else ["other"] * n_rows
        self.work = list(work) if work is not None else [1.0] * n_rows
        if not len(self.kinds) == len(self.work) == n_rows:
            raise ValueError(f"{n_rows} rows but {len(self.kinds)} kinds and {len(self.work)} amounts of work")
        self.study, self.n, self.done, self.t0 = study, n_rows, 0, time.perf_counter()
        self.seconds: list[float] = []

    def start(self, name: str) -> None:
        logging.info("%s: row %d/%d %s ...", self.study, self.done + 1, self.n, name)

    def eta(self) -> float:
        """Seconds left, from the rows done (`finish`)."""
        done = range(self.done)

        def rate(rows) -> float:
            return sum(self.seconds[i] for i in rows) / max(sum(self.work[i] for i in rows), 1e-9)

        by_kind = {k: rate([i for i in done if self.kinds[i] == k]) for k in set(self.kinds[: self.done])}
        overall = rate(done)
        return sum(self.work[i] * by_kind.get(self.kinds[i], overall) for i in range(self.done, self.n))

    def exclude(self, seconds: float) -> None:
        """Leave `seconds` spent on something else (loading a later part's data) out of the
        elapsed time."""
        self.t0 += seconds

    def finish(self, name: str, seconds: float, summary: str) -> None:
        self.done += 1
        self.seconds.append(seconds)
        elapsed = time.perf_counter() - self.t0
        logging.info(
            "%s: row %d/%d %s done in %.1f s: %s (elapsed %s, ETA %s)",
            self.study,
            self.done,
            self.n,
            name,
            seconds,
            summary,
            _hms(elapsed),
            _hms(self.eta()),
        )


def _hms(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}m{s:02d}s"
