"""The signals the simulated devices serve: one trial of the scene simulator (`fabricjax.sim`).

`fabricjax.sim.simulate` computes the trial with every effect and all three streams; the
simulated devices then replay it step by step through the real driver paths: step k's joint state
answers the k-th servo sync read, frame k is the camera's k-th frame, and the audio words stream
from the Pi sender in real time. The simulated motion follows the same commanded procedure
(closing to 0.1 N at a fixed speed, then rubbing at `calibration.CYCLE_HZ`, slowed by friction), so
the recorder's procedure runs against it with `cycle_s = 1 / CYCLE_HZ`. The simulated servos do not
re-plan the motion from the received goal positions: the goals are checked and counted only.

Minsight frames are rendered here from the simulated force and stroke (the shell interior darkened
where indented, shifted by shear), because the simulator's own image renderer does not run yet
(`minsight.render` fails in `cv2.remap` on float64 maps); switch to `streams=sim.STREAMS` and
`trial_archive.images` once it does.
"""

from __future__ import annotations

import cv2
import numpy as np

from acquisition import camera as camera_mod

from acquisition.procedure import ExploratoryProcedure
from acquisition.simulated import SimulatedSignals
from fabricjax import sim
from fabricjax.sim import calibration


def procedure(n_cycles: int = 50) -> ExploratoryProcedure:
    """The procedure whose commands the simulator's motion follows."""
    return ExploratoryProcedure(n_cycles=n_cycles, cycle_s=1.0 / calibration.CYCLE_HZ)


def _render(texture: np.ndarray, indent: np.ndarray, force: float, shear_px: float) -> np.ndarray:
    h, w = camera_mod.IMAGE_SIZE
    shifted = cv2.warpAffine(texture, np.float32([[1, 0, shear_px], [0, 1, 0]]), (w, h), borderMode=cv2.BORDER_REFLECT)
    return np.clip(shifted * (1.0 - 2.0 * min(force, 0.4) * indent), 0, 255).astype(np.uint8)


def render_images(joints: np.ndarray, force: np.ndarray, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """Frames and the no-contact reference: a smooth speckled interior, darkened in proportion to
    the normal force under the contact and shifted by the stroke (thumb base angle) while in contact."""
    rng = np.random.default_rng(seed)
    h, w = camera_mod.IMAGE_SIZE
    base = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), 4)
    base = cv2.normalize(base, None, 40, 215, cv2.NORM_MINMAX)
    texture = np.stack([base * 0.9, base, base * 0.8], axis=-1)
    yy, xx = np.mgrid[:h, :w]
    indent = np.exp(-(((yy - h / 2) / (h / 4)) ** 2 + ((xx - w / 2) / (w / 4)) ** 2)).astype(np.float32)[..., None]
    stroke = joints[:, 0, 0] - joints[0, 0, 0]
    shear = 40.0 * (stroke - np.median(stroke[force > 0])) * (force > 0)
    images = np.stack([_render(texture, indent, f, s) for f, s in zip(force, shear)])
    images = cv2.add(images, rng.integers(0, 3, images.shape, dtype=np.uint8))  # sensor noise: no two frames alike
    return images, _render(texture, indent, 0.0, 0.0)


def trial_signals(fabric_id: int, day: int = 1, trial: int = 0, *, n_cycles: int = 50, condition: str = "lab", seed: int = 0) -> SimulatedSignals:
    """Simulate the trial with every effect and package it for the devices."""
    scene = sim.Scene(fabric_id=fabric_id, day=day, trial=trial, condition=condition, cycles=n_cycles, seed=seed)
    trial_archive = sim.simulate(scene)
    images, reference = render_images(trial_archive.joints, trial_archive.force)
    return SimulatedSignals(
        joints=trial_archive.joints,
        images=images,
        force=trial_archive.force,
        audio=trial_archive.audio,
        reference=reference,
        source={"signals": "fabricjax.sim.simulate", "scene": scene.to_json()},
    )
