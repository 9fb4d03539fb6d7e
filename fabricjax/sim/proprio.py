"""Proprioception: 6 joints x (angle, velocity, current) and Minsight's force estimate per frame.

[paper, Proprioception] thumb (3 joints), middle finger (2) and palm (1), read at each frame.
Kinematics come from the finger motion: the base joints of thumb and middle finger rub in
opposite phase, the other finger joints hold the closing angle (which encodes the stack's
thickness and compressibility), the palm holds still. With the "proprioception" effect the joints
also feel the load and the sensors are real:
* load: the tangential contact load (friction, cloth stretch) loads the rubbing joints and the
  normal force loads the closing joints; a position-controlled servo lags by torque / stiffness
  and draws current torque / k_t, plus gear drag ~ speed;
* sensors: 12-bit absolute position (no calibration drift), noisy velocity, 6.5 mA current
  steps, and Minsight's force proxy: the force as the shell's deformation shows it (the day's
  silicone stiffness, `Motion.force_reading`), plus its per-day bias and frame-to-frame noise.
Without it: ideal kinematics, idle currents, the true normal force.
"""

from __future__ import annotations

import numpy as np

from fabricjax.sim import calibration as cal
from fabricjax.sim.motion import Motion
from fabricjax.sim.scene import Nuisance

# [numerics] which joints rub and in which sense (signs, not magnitudes): thumb base +, middle base - (opposite phase)
RUBBING = np.array([1.0, 0.0, 0.0, -1.0, 0.0, 0.0])
PALM = 5  # [numerics] the palm joint's row: thumb 0-2, middle finger 3-4, palm 5 [paper]


def joints_and_force(motion: Motion, frame_t: np.ndarray, nz: Nuisance, rng: np.random.Generator | None):
    """(joints float32 (T, 6, 3), force float32 (T,)) at the frame times."""
    lever = cal.FINGER_LEVER_MM
    finger = motion.finger_mm / lever  # rad of each rubbing joint
    closing = motion.closing_mm / 2 / lever  # rad of closing per finger
    angle = (
        np.asarray(cal.OPEN_POSE_RAD)[:, None]
        + RUBBING[:, None] * finger
        + np.asarray(cal.CLOSING_SHARE)[:, None] * closing
    )
    current = np.full_like(angle, cal.IDLE_CURRENT_A)
    if rng is not None:
        shear = motion.shear_n * lever * 1e-3  # N m, opposing the stroke
        torque = RUBBING[:, None] * shear + np.asarray(cal.CLOSING_SHARE)[:, None] * motion.normal_n * lever * 1e-3
        torque[PALM] = cal.PALM_REACTION_SHARE * shear  # the palm joint takes part of the reaction
        angle = angle - torque / cal.SERVO_STIFFNESS_NM_RAD
        speed = np.gradient(angle, motion.t, axis=1)
        current = current + (np.abs(torque) + cal.VISCOUS_NM_PER_RAD_S * np.abs(speed)) / cal.TORQUE_PER_AMP_NM
    else:
        speed = np.gradient(angle, motion.t, axis=1)
    t_read = frame_t - cal.READ_LATENCY_S
    pick = lambda y: np.stack([np.interp(t_read, motion.t, row) for row in y], axis=1)  # noqa: E731
    a, v, c = pick(angle), pick(speed), pick(current)
    force = np.interp(frame_t, motion.t, motion.normal_n)
    if rng is not None:
        n = len(frame_t)
        a = np.round(a / cal.ANGLE_LSB_RAD) * cal.ANGLE_LSB_RAD
        v = v + rng.normal(0.0, cal.VELOCITY_NOISE_RAD_S, v.shape)
        c = c + rng.normal(0.0, cal.CURRENT_NOISE_A, c.shape)
        c = np.maximum(np.round(c / cal.CURRENT_LSB_A), 0) * cal.CURRENT_LSB_A
        force = force * motion.force_reading + nz.force_bias_n + rng.normal(0.0, cal.FORCE_NOISE_N, n)
    joints = np.stack([a, v, c], axis=2).astype(np.float32)
    return joints, force.astype(np.float32)
