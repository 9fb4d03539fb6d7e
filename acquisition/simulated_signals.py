"""The signals the simulated devices serve: one trial of the scene simulator (`fabricjax.sim`).

`fabricjax.sim.simulate` computes the trial with every effect and all three streams; the
simulated devices then replay it step by step through the real driver paths: step k's joint state
answers the k-th servo sync read, frame k (the simulator's Minsight frame, `sim.minsight.render`)
is the camera's k-th frame, and the audio words stream from the Pi sender in real time. The
simulated motion follows the same commanded procedure (closing to 0.1 N at a fixed speed, then
rubbing at `calibration.CYCLE_HZ`, slowed by friction), so the recorder's procedure runs against it
with `cycle_s = 1 / CYCLE_HZ`. The simulated servos do not re-plan the motion from the received
goal positions: the goals are checked and counted only.

`bench_acquisition` times the recorder's 50 Hz loop against these devices.
"""

from __future__ import annotations

from acquisition import camera as camera_mod
from acquisition import recorder, simulated_devices
from acquisition.procedure import ExploratoryProcedure
from acquisition.simulated_devices import SimulatedSignals
from fabricjax import sim
from fabricjax.sim import calibration


def procedure(n_cycles: int = 50) -> ExploratoryProcedure:
    """The procedure whose commands the simulator's motion follows."""
    return ExploratoryProcedure(n_cycles=n_cycles, cycle_s=1.0 / calibration.CYCLE_HZ)


def trial_signals(
    fabric_id: int, day: int = 1, trial: int = 0, *, n_cycles: int = 50, condition: str = "lab", seed: int = 0
) -> SimulatedSignals:
    """Simulate the trial with every effect and all streams, and package it for the devices."""
    scene = sim.Scene(
        fabric_id=fabric_id,
        day=day,
        trial=trial,
        condition=condition,
        streams=sim.STREAMS,
        image_size=camera_mod.IMAGE_SIZE,
        cycles=n_cycles,
        seed=seed,
    )
    trial_archive = sim.simulate(scene)
    return SimulatedSignals(
        joints=trial_archive.joints,
        images=trial_archive.images,
        force=trial_archive.force,
        audio=trial_archive.audio,
        reference=trial_archive.reference[0],
        source={"signals": "fabricjax.sim.simulate", "scene": scene.to_json()},
    )


def bench_acquisition(seconds: float = 10.0, fabric_id: int = 12) -> dict:
    """Step-time distribution of the 50 Hz loop against the simulated devices (nothing written)."""
    cycles = max(1, round(seconds * calibration.CYCLE_HZ))
    signals = trial_signals(fabric_id, n_cycles=cycles)
    with simulated_devices.simulated_rig(signals) as rig:
        rec = recorder.record_trial(
            rig, procedure(cycles), fabric_id=fabric_id, day=1, trial=0, out_dir=".", write=False
        )
    return rec.archive.meta["step_time"] | {"mic_stream": rec.archive.meta["mic_stream"], "failure": rec.failure}
