"""The 50 Hz recorder: one step = one Minsight frame, one sync read of the six servos, the end index
of the latest 2048-sample window of each microphone, and the goal positions of the procedure.

A trial ends in exactly one of three ways, and each leaves a valid archive (written atomically by
`archive.write_archive`): the procedure finishes (complete=True); a device fails (a clear error
is stored in meta.failure, complete=False); Ctrl-C (complete=False, then KeyboardInterrupt goes on
to the caller). Only a failure before the first step writes nothing: there is nothing to keep.
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from acquisition import camera as camera_mod
from acquisition.camera import Camera, CameraError, Reference
from acquisition.mics import MicError, MicReceiver
from acquisition.procedure import ExploratoryProcedure, ProcedureError
from acquisition.servos import ServoBus, ServoError
from fabricjax import catalog
from fabricjax.force_proxy import ForceProxy
from fabricjax.reporting import stats
from fabricjax.store import archive

PERIOD = 1 / archive.STEP_RATE  # s: one step per Minsight frame (0.02)
DEVICE_ERRORS = (ServoError, CameraError, MicError, ProcedureError)


class RecordingError(RuntimeError):
    """The trial failed before its first step: no archive was written."""


@dataclasses.dataclass
class Rig:
    """The devices of one hand, opened. `source` goes into meta.source."""

    bus: ServoBus
    camera: Camera
    mics: MicReceiver
    force: ForceProxy
    source: dict[str, Any]
    reference: Reference  # the session's no-contact frames (`camera.take_reference`)

    def close(self) -> None:
        for close in (self.bus.close, self.camera.close, self.mics.close):
            try:
                close()
            except Exception:  # closing is best effort: the devices may be the reason we stop
                pass


@dataclasses.dataclass
class Recording:
    path: Path
    archive: archive.TrialArchive
    failure: str | None


def step_statistics(durations: np.ndarray, lateness: np.ndarray, missed: int, period: float = PERIOD) -> dict:
    """Work time per step and start lateness (ms); a missed deadline is a step that ended after its slot."""
    n = len(durations)
    work = stats.percentiles_ms(durations) if n else {"p50_ms": 0.0, "p99_ms": 0.0}
    return {
        "period_ms": period * 1e3,
        "steps": n,
        "p50_ms": round(work["p50_ms"], 3),
        "p99_ms": round(work["p99_ms"], 3),
        "max_ms": round(float(durations.max()) * 1e3, 3) if n else 0.0,
        "start_late_p99_ms": round(stats.percentiles_ms(lateness)["p99_ms"], 3) if len(lateness) else 0.0,
        "missed_deadlines": int(missed),
        "missed_fraction": round(missed / n, 5) if n else 0.0,
    }


def record_trial(
    rig: Rig,
    procedure: ExploratoryProcedure,
    *,
    fabric_id: int,
    day: int,
    trial: int,
    out_dir: str | Path,
    condition: str = "lab",
    period: float = PERIOD,
    write: bool = True,
    on_step: Callable[..., None] | None = None,
) -> Recording:
    """Run the procedure on `rig` and write the trial archive into `out_dir`.

    `on_step` sees each step's data as it is recorded, as the keyword arguments of
    `fabricjax.inference.view.Step` (`acquisition.record --view`); it runs after the step's timed work, so
    its time shows as lateness of the next step, not as step time."""
    cap = procedure.max_steps(period)
    images = np.empty((cap, *camera_mod.IMAGE_SIZE, 3), np.uint8)
    joints = np.empty((cap, archive.N_JOINTS, archive.N_JOINT_FIELDS), np.float32)
    force = np.empty(cap, np.float32)
    stamps = np.empty(cap, np.float64)
    ends = np.empty(cap, np.int64)
    durations, lateness = np.empty(cap), np.empty(cap)
    n = missed = 0
    failure, interrupted, closing = None, False, None

    rig.mics.wait_for(archive.WINDOW)
    start_index = rig.mics.start_recording()
    t0 = time.perf_counter()
    slot = 0
    try:
        while n < cap:
            deadline = t0 + slot * period
            delay = deadline - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            ts = time.perf_counter()
            images[n] = rig.camera.read()
            joints[n] = rig.bus.read_state()
            windows, ends[n] = rig.mics.latest()
            force[n] = rig.force(images[n])
            goals = procedure.goals(ts - t0, float(force[n]))
            if goals is None:
                break
            if closing is None and procedure.closed_at is not None:
                closing = n  # steps recorded before the first rubbing step
            rig.bus.write_goals(goals)
            stamps[n] = ts - t0
            te = time.perf_counter()
            durations[n], lateness[n] = te - ts, ts - deadline
            if te > deadline + period:
                missed += 1
            if on_step is not None:
                new = archive.WINDOW if n == 0 else int(min(max(ends[n] - ends[n - 1], 0), archive.WINDOW))
                on_step(
                    index=n,
                    time_s=float(stamps[n] - stamps[0]),
                    windows=windows,
                    new_samples=new,
                    joints=joints[n],
                    force=float(force[n]),
                    frame=images[n],
                )
            n += 1
            slot = max(slot + 1, math.ceil((te - t0) / period))  # a late step skips slots, never bunches up
        else:
            failure = f"procedure did not finish within {cap} steps"
    except KeyboardInterrupt:
        failure, interrupted = "interrupted (Ctrl-C)", True
    except DEVICE_ERRORS as e:
        failure = f"{type(e).__name__}: {e}"
    finally:
        audio = rig.mics.stop_recording()
    if n == 0:
        raise RecordingError(f"fabric {fabric_id} day {day} trial {trial}: failed before the first step: {failure}")

    fab = catalog.fabric(fabric_id)
    meta = archive.make_meta(
        fabric_id=fabric_id,
        properties=fab.properties,
        day=day,
        trial=trial,
        condition=condition,
        source=rig.source,
        image_size=camera_mod.IMAGE_SIZE,
        complete=failure is None,
        failure=failure,
        closing_steps=closing if closing is not None else n,
        procedure=dataclasses.asdict(procedure),
        step_time=step_statistics(durations[:n], lateness[:n], missed, period),
        mic_stream=rig.mics.stats() | {"start_index": int(start_index)},
        servo_retries=rig.bus.retried,
        camera_dropped_frames=rig.camera.dropped,
        force_proxy={"gain": rig.force.gain, "deadband": rig.force.deadband},
        reference=rig.reference.meta(t0),
    )
    trial_archive = archive.TrialArchive(
        meta=meta,
        timestamps=stamps[:n].copy(),
        window_end=np.repeat((ends[:n] - start_index)[:, None], 2, axis=1),
        joints=joints[:n],
        force=force[:n],
        audio=audio,
        images=images[:n],
        reference=rig.reference.frames,
    )
    path = Path(out_dir) / archive.trial_filename(meta)
    if write:
        archive.write_archive(path, trial_archive)
    if interrupted:
        raise KeyboardInterrupt(f"recording interrupted; {n} steps kept in {path} (complete=False)")
    return Recording(path, trial_archive, failure)
