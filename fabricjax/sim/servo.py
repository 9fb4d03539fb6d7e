"""Servo noise, heard by both microphones and present in every class (class 0 included).

[estimates: calibration, "servo noise"] A geared servo sings at its gear-mesh frequency, motor rev/s x pinion teeth =
|joint speed| x gear ratio / 2 pi x teeth (a few hundred Hz at rubbing speeds), with harmonics,
plus broadband motor/gear noise growing with speed and with the transmitted torque; servos
holding position still hum (PWM). The sound reaches Minsound through the aluminium skeleton
(structure-borne, band-limited) and the palm microphone through the air (the servos sit in the
palm). Load dependence makes the servo sound carry a little friction information, as
proprioception does.
"""

from __future__ import annotations

import numpy as np

from fabricjax.sim import acoustics
from fabricjax.sim import calibration as cal
from fabricjax.sim.motion import Motion
from fabricjax.store import archive


def joint_speed(motion: Motion) -> np.ndarray:
    """|rad/s| of the rubbing joints (thumb base, middle base) on the control grid."""
    return np.abs(np.gradient(motion.finger_mm, motion.t)) / cal.FINGER_LEVER_MM


def source(motion: Motion, grid: acoustics.Grid, rng: np.random.Generator) -> np.ndarray:
    """Spectrum (Pa, as heard structure-borne inside the shell) of the servo noise."""
    t = grid.t
    speed = np.interp(t, motion.t, joint_speed(motion), left=0.0, right=0.0)
    torque = np.abs(np.interp(t, motion.t, motion.shear_n, left=0.0, right=0.0)) * cal.FINGER_LEVER_MM * 1e-3
    load = 1.0 + torque / cal.SERVO_LOAD_REF_NM
    mesh_hz = speed * cal.GEAR_RATIO / (2 * np.pi) * cal.GEAR_TEETH
    phase = 2 * np.pi * np.cumsum(mesh_hz) / archive.AUDIO_RATE + rng.uniform(0, 2 * np.pi)
    sin, cos = np.sin(phase), np.cos(phase)
    h2, h3 = cal.SERVO_HARMONICS
    tone = (
        sin + 2 * h2 * sin * cos + h3 * sin * (3.0 - 4.0 * sin * sin)
    )  # harmonics 1, 2 (sin 2x = 2 sin cos), 3 (sin 3x = 3 sin - 4 sin^3)
    x = cal.SERVO_TONE_PA * speed * load * tone
    x += (cal.SERVO_BROADBAND_PA * speed * load) * rng.standard_normal(grid.n, dtype=np.float32)
    spec = grid.rfft(x)
    hold = acoustics.noise_spectrum(rng, grid, np.ones(len(grid.f), np.float32))
    return spec + hold * (cal.SERVO_HOLD_PA / acoustics.rms_of_spectrum(hold, grid))


def internal_transfer(f: np.ndarray) -> np.ndarray:
    lo, hi = cal.SERVO_STRUCTURE_BAND_HZ
    return acoustics.highpass2(f, lo) * acoustics.lowpass2(f, hi)


def palm_transfer(f: np.ndarray) -> np.ndarray:
    return 10 ** (cal.SERVO_PALM_GAIN_DB / 20) * acoustics.highpass2(f, cal.SERVO_STRUCTURE_BAND_HZ[0])
