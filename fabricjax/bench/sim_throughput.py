"""Simulator throughput: simulated seconds per wall second for audio + proprioception trials, and
what a trial's camera data (its frames rendered, their optical flow) costs at each frame size."""

from __future__ import annotations

import time

import cv2

from fabricjax import presets, runtime
from fabricjax.features import flow
from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import STREAMS, Scene
from fabricjax.sim.trial import procedure, simulate
from fabricjax.store import archive


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


def bench_frame_scale(
    preset: str = "default", sizes=None, cycles: int = 5, fabric: int = 1, cores: int | None = None
) -> dict:
    """What one of `preset`'s trials costs to simulate with Minsight frames and to turn into
    optical flow, at its own frame size and at the paper's 308x410 (`sizes`), on one core. Per size
    one trial of `cycles` rubbing cycles is timed after a one-cycle warm-up: its rendering is the
    difference to the same trial simulated without frames, its flow OpenCV's Farneback with one
    thread (a dataset's trials are simulated one per process, their flow one per thread). Both are
    scaled per frame to the preset's trials (their frame count from the motion alone) and spread
    over `cores` (default: the cores this process may run on): what the preset's camera data would
    cost at each size."""
    spec = presets.get(preset).dataset
    sizes = tuple(sizes or (spec.image_size, archive.MINSIGHT_SIZE))
    cores = cores or runtime.available_cores()
    n_trials = len(spec.trials())
    trial_frames = len(procedure(Scene(fabric, cycles=spec.cycles_per_trial)).frame_times)
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    out = {"preset": preset, "trials": n_trials, "frames_per_trial": trial_frames, "cycles_timed": cycles}
    out |= {"cores": cores, "fabric": fabric, "sizes": {}}
    try:
        simulate(Scene(fabric, cycles=1))
        t = time.perf_counter()
        simulate(Scene(fabric, cycles=cycles))
        without = time.perf_counter() - t
        for size in sizes:
            simulate(Scene(fabric, cycles=1, image_size=tuple(size), streams=STREAMS))
            t = time.perf_counter()
            frames = simulate(Scene(fabric, cycles=cycles, image_size=tuple(size), streams=STREAMS)).images
            rendered = max(time.perf_counter() - t - without, 0.0)
            t = time.perf_counter()
            flow.farneback(frames)
            flowed = time.perf_counter() - t
            per_frame = trial_frames / len(frames)
            out["sizes"][f"{size[0]}x{size[1]}"] = {
                "frames_timed": len(frames),
                "frame_mb_per_trial": per_frame * frames.nbytes / 1e6,
                "render_s_per_trial": per_frame * rendered,
                "flow_s_per_trial": per_frame * flowed,
                "preset_s": per_frame * (rendered + flowed) * n_trials / cores,
            }
    finally:
        cv2.setNumThreads(before)
    return out
