"""Simulator throughput: simulated seconds per wall second for audio + proprioception trials."""

from __future__ import annotations

import time

from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import Scene
from fabricjax.sim.trial import simulate


def bench_throughput(
    seconds: float = 30.0, fabrics: tuple[int, ...] = (0, 6, 12), streams=("audio", "proprio")
) -> dict:
    """Simulate one trial of ~`seconds` per fabric (after a short warm-up) in this process."""
    cycles = max(1, round(seconds * cal.CYCLE_HZ * 0.9))
    for fid in fabrics:
        simulate(Scene(fid, cycles=1, streams=tuple(streams)))  # fills the per-fabric profile cache
    start = time.perf_counter()
    simulated = sum(simulate(Scene(fid, cycles=cycles, streams=tuple(streams))).timestamps[-1] for fid in fabrics)
    wall = time.perf_counter() - start
    return {
        "simulated_s": float(simulated),
        "wall_s": wall,
        "realtime_factor": float(simulated / wall),
        "trials": len(fabrics),
        "streams": list(streams),
    }
