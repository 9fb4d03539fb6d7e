"""The exploratory procedure: force-controlled closing until 0.1 N, then rubbing back and forth.

The paper closes thumb and middle finger until Minsight's force estimate reaches 0.1 N, then runs
a preprogrammed rubbing motion with the same commanded speed for every fabric; 50 cycles give the
~1500 steps of a trial at 50 Hz (~1 s of closing + 50 strokes of 0.5 s commanded, slower under friction). Angles are
goal
positions in rad around each servo's mid-range, in `archive.JOINT_NAMES` order.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

OPEN_POSE = (0.20, -0.35, -0.25, -0.20, -0.30, 0.00)
CLOSE_DIRECTION = (0.00, 1.00, 0.70, 1.00, 0.80, 0.00)  # thumb and middle flex toward each other
RUB_DIRECTION = (0.25, 0.00, 0.00, 0.00, 0.00, 0.00)  # thumb base swings across the middle fingertip
# (rad): the middle finger holds its closed pose; the palm joint holds still


class ProcedureError(RuntimeError):
    """The procedure cannot go on (e.g. no contact force where the fabric should be)."""


@dataclasses.dataclass
class ExploratoryProcedure:
    force_threshold: float = 0.1  # N, Minsight force estimate that ends the closing
    n_cycles: int = 50
    cycle_s: float = 0.5  # 2 Hz commanded; friction slows the real stroke
    close_rate: float = 0.5  # rad/s along CLOSE_DIRECTION
    max_close_s: float = 4.0
    rub_amplitude: float = 1.0  # scales RUB_DIRECTION

    def __post_init__(self):
        self.closed_at: float | None = None
        self.closed_pose: np.ndarray | None = None

    @property
    def phase(self) -> str:
        return "closing" if self.closed_at is None else "rubbing"

    def goals(self, t: float, force: float) -> np.ndarray | None:
        """Goal angles for the step at time `t` (s since start) given the latest force (N);
        None once the last rubbing cycle is over."""
        if self.closed_at is None:
            pose = np.add(OPEN_POSE, np.multiply(CLOSE_DIRECTION, self.close_rate * t))
            if force >= self.force_threshold:
                self.closed_at, self.closed_pose = t, pose
            elif t > self.max_close_s:
                raise ProcedureError(
                    f"closing: force {force:.3f} N still below {self.force_threshold} N after {self.max_close_s} s "
                    "(no fabric between the fingers, or a stale no-contact reference image)"
                )
            else:
                return pose
        rub_t = t - self.closed_at
        if rub_t >= self.n_cycles * self.cycle_s:
            return None
        swing = self.rub_amplitude * math.sin(2 * math.pi * rub_t / self.cycle_s)
        return self.closed_pose + np.multiply(RUB_DIRECTION, swing)

    def max_steps(self, period: float) -> int:
        return int(math.ceil((self.max_close_s + self.n_cycles * self.cycle_s) / period)) + 2
