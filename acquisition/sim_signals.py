"""The signals the simulated devices serve: one trial of a fabric, step by step.

A small, physically plausible source that follows the same procedure the recorder commands, so
the simulated hand closes and rubs exactly as told:

* motion: the servos track the procedure's goals (closing at `close_rate`, rubbing cycles); contact
  comes earlier for thicker fabric (the gap closes sooner), then the force rises linearly with
  indentation until the recorder stops closing at 0.1 N, and during rubbing varies with friction.
* current: a no-load draw plus a load term from friction x normal force while sliding.
* Minsight images: a smooth random texture of the shell's interior (fixed per hand), darkened where the tip is indented (proportional to force) and shifted by shear along the rubbing.
* audio: texture vibration at f = v / weave period (with harmonics), broadband roughness noise and
  fuzz scratches scaled by sliding speed, servo whine in both mics, ambient noise mostly in the
  palm mic; then the SPH0645: DC offset, self-noise, 18 valid bits in the top of a 32-bit word.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from acquisition import camera as camera_mod
from acquisition import procedure as proc_mod
from acquisition import wire
from acquisition.simulated import SimulatedSignals
from fabricjax import catalog

STEP = 0.02
TIP_RADIUS_M = 0.04  # thumb base -> fingertip: converts joint speed to sliding speed
FULL_SCALE = 2.0**17  # SPH0645 18-bit full scale


def shell_texture(seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    h, w = camera_mod.IMAGE_SIZE
    base = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), 4)
    base = cv2.normalize(base, None, 40, 215, cv2.NORM_MINMAX)
    return np.stack([base * 0.9, base, base * 0.8], axis=-1).astype(np.uint8)  # warm LED tint


def _indent_profile() -> np.ndarray:
    h, w = camera_mod.IMAGE_SIZE
    yy, xx = np.mgrid[:h, :w]
    return np.exp(-(((yy - h / 2) / (h / 4)) ** 2 + ((xx - w / 2) / (w / 4)) ** 2)).astype(np.float32)[..., None]


INDENT = _indent_profile()


def render_image(texture: np.ndarray, force: float, shear_px: float) -> np.ndarray:
    h, w = camera_mod.IMAGE_SIZE
    shifted = cv2.warpAffine(texture, np.float32([[1, 0, shear_px], [0, 1, 0]]), (w, h), borderMode=cv2.BORDER_REFLECT)
    dim = 1.0 - min(force, 0.4) * 2.0 * INDENT
    return np.clip(shifted * dim, 0, 255).astype(np.uint8)


def trial_signals(
    fabric_id: int,
    day: int = 1,
    trial: int = 0,
    *,
    n_cycles: int = 50,
    condition: str = "lab",
    procedure: proc_mod.ExploratoryProcedure | None = None,
    margin_s: float = 1.5,
) -> SimulatedSignals:
    """Streams for the whole procedure plus `margin_s` of holding (the recorder's loop may trail)."""
    fab = catalog.fabric(fabric_id)
    proc = procedure or proc_mod.ExploratoryProcedure(n_cycles=n_cycles)
    rng = np.random.default_rng([fabric_id, day, trial, condition == "cafe"])
    contact_s = 0.35 + 0.25 * (1 - min(fab.thickness_mm, 2.5) / 2.5) + rng.uniform(-0.03, 0.03)  # grasp variation
    close_s = contact_s + 0.12 * (1 + fab.compressibility)  # softer stacks take longer to reach 0.1 N
    total_s = close_s + proc.n_cycles * proc.cycle_s + margin_s
    t = np.arange(int(total_s / STEP)) * STEP

    # motion and force per step
    rub_t = np.clip(t - close_s, 0, None)
    swing = np.where(t > close_s, np.sin(2 * np.pi * rub_t / proc.cycle_s), 0.0) * proc.rub_amplitude
    closing = np.minimum(t, close_s) * proc.close_rate
    goals = np.add(proc_mod.OPEN_POSE, np.multiply(proc_mod.CLOSE_DIRECTION, closing[:, None]))
    goals = goals + np.multiply(proc_mod.RUB_DIRECTION, swing[:, None])
    angles = np.empty_like(goals)
    angles[0] = goals[0]
    for k in range(1, len(t)):  # the servo's own position loop: first-order lag of ~40 ms
        angles[k] = angles[k - 1] + (goals[k] - angles[k - 1]) * (1 - math.exp(-STEP / 0.04))
    velocity = np.gradient(angles, STEP, axis=0)
    slide = np.abs(velocity[:, 0]) * TIP_RADIUS_M  # m/s at the fingertip
    force = np.where(t < contact_s, 0.0, 0.1 * np.clip((t - contact_s) / (close_s - contact_s), 0, 1))
    force = force * (1 + 0.3 * fab.friction * np.abs(swing) * (t > close_s))
    current = 0.12 + 0.02 * np.abs(velocity) + (fab.friction * force * 2.0)[:, None] * np.array([1, 0.5, 0.5, 0.8, 0.8, 0])
    current += rng.normal(0, 0.004, current.shape)
    joints = np.stack([angles, velocity, current], axis=-1).astype(np.float32)

    texture = shell_texture()
    shear = 12 * fab.friction * swing
    images = np.stack([render_image(texture, f, s) for f, s in zip(force, shear)])
    images = cv2.add(images, rng.integers(0, 3, images.shape, dtype=np.uint8))  # sensor noise: no two frames alike

    # audio at 48 kHz
    n_audio = len(t) * 960 + 2048
    ta = np.arange(n_audio) / wire.RATE
    v = np.interp(ta, t, slide)
    f_texture = v / max(fab.weave_period_mm * 1e-3, 1e-5)
    phase = 2 * np.pi * np.cumsum(f_texture) / wire.RATE
    tone = sum(np.sin(h * phase) / h**fab.spectral_slope for h in (1, 2, 3))
    noise = np.fft.irfft(np.fft.rfft(rng.normal(size=n_audio)) / np.maximum(np.fft.rfftfreq(n_audio, 1 / wire.RATE), 50) ** (fab.spectral_slope / 4), n_audio)
    noise /= noise.std() + 1e-12
    scratch = fab.fuzz * (rng.random(n_audio) < 0.002) * rng.normal(size=n_audio) * 6
    in_contact = np.interp(ta, t, force) > 0
    contact = in_contact * v * (0.6 * tone * (0.3 + fab.roughness_um / 50) + (fab.roughness_um / 30) * noise + scratch) * 2e4
    servo = 30 * np.sin(2 * np.pi * 2300 * ta) * np.interp(ta, t, np.abs(velocity).sum(axis=1))
    level = {"lab": 30.0, "cafe": 900.0}[condition] * (1 + 0.1 * day)
    ambient = level * rng.normal(size=n_audio)
    internal = contact + servo + 0.05 * ambient
    external = 0.03 * contact + 0.5 * servo + ambient
    words = [np.clip(np.round(x + 6000 + rng.normal(0, 25, n_audio)), -FULL_SCALE, FULL_SCALE - 1) for x in (internal, external)]
    audio = (np.stack(words).astype(np.int64) << 14).astype(np.int32)

    return SimulatedSignals(
        joints=joints,
        images=images,
        force=force.astype(np.float32),
        audio=audio,
        reference=render_image(texture, 0.0, 0.0),
        source={"signals": "acquisition.sim_signals", "fabric_id": fabric_id, "day": day, "trial": trial, "condition": condition},
    )
