"""Finger motion: the paper's exploratory procedure, as kinematics and contact mechanics.

[paper, Finger Movement] Force-controlled closing of thumb and middle finger until Minsight's
force estimate reaches 0.1 N (the estimate, not the force: its day's bias and the silicone's
stiffness of the day, which the estimate reads as deformation, move where the closing stops), then a preprogrammed
rubbing motion of `cycles` back-and-forth
strokes with the same commanded speed for every fabric; "the fingers move more slowly when
finger-fabric friction is high", so trial length varies with friction.

Mechanics, all per fingertip:
* Closing: the gap shrinks at constant speed; after contact the folded two-layer stack and the two
  shells compress in series. The force is checked once per camera frame, so the grasp overshoots
  0.1 N by a random amount. The closing angle therefore encodes thickness and compressibility.
* Rubbing: the fingertips follow opposite sinusoids (fabric between them stays put; with no fabric
  the thumb slides over the moving middle finger, twice the relative travel). The skin sticks to
  the cloth until the tangential load reaches mu * F_n: Coulomb friction through an elastic
  element (shell shear in series with the cloth's stretch) is a play (backlash) operator of width
  delta = mu * F_n / k. The slide position drives the texture, the elastic load drives the joints.
* Speed droop: a position-controlled servo slows under load, speed / (1 + c * mu * F_n).
Friction and the shells' stiffness are the catalog's scaled by the day's climate (`Nuisance`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fabricjax import catalog
from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import Nuisance
from fabricjax.store import archive


@dataclasses.dataclass(frozen=True)
class Motion:
    t: np.ndarray  # control grid, s from the start of closing
    finger_mm: np.ndarray  # lateral thumb displacement (the middle finger mirrors it)
    slide_mm: np.ndarray  # thumb skin position on the counter-surface (cloth or middle finger)
    normal_n: np.ndarray  # normal force (0 before contact)
    shear_n: np.ndarray  # signed tangential load through the elastic contact
    closing_mm: np.ndarray  # fingertip closing travel (both fingers together)
    duration_s: float
    rubbing_start_s: float
    slip_width_mm: float  # mean delta of the play operator (stick length at each reversal)
    contact_stiffness_n_mm: float  # normal stiffness of shells + stack
    friction: float  # the trial's Coulomb coefficient (the fabric's, scaled by the day's climate)
    grasp_n: float  # normal force where the closing stopped
    force_reading: float  # Minsight's force estimate per newton of true force (1 / shell stiffness scale)


def stack_stiffness(fabric: catalog.Fabric, thickness_mm: float, silicone: float = 1.0) -> float:
    """Normal stiffness of the shells (nominal x `silicone`) in series with the fabric stack
    (linearised at 0.1 N)."""
    k_shell = cal.SHELL_NORMAL_STIFFNESS_N_MM * silicone
    if not fabric.is_fabric:
        return k_shell
    k_stack = cal.GRASP_FORCE_N / max(fabric.compressibility * thickness_mm, 1e-3)
    return 1.0 / (1.0 / k_shell + 1.0 / k_stack)


def shear_stiffness(fabric: catalog.Fabric, silicone: float = 1.0) -> float:
    """Tangential stiffness between finger bone and sliding interface: shell shear (nominal x
    `silicone`), cloth stretch."""
    k_shell = cal.SHELL_SHEAR_STIFFNESS_N_MM * silicone
    if not fabric.is_fabric:
        return k_shell / 2  # two shells
    return 1.0 / (1.0 / k_shell + 1.0 / fabric.stretch_stiffness)


def play(x: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """Play operator: the stuck contact follows x only once |x - out| exceeds delta (Coulomb stick-slip
    through a spring). Exact for piecewise-monotone input; loops over monotone segments only."""
    v = np.diff(x, prepend=x[0])
    sign = np.sign(v)
    sign[sign == 0] = 1.0
    cuts = np.flatnonzero(np.diff(sign) != 0) + 1
    out = np.empty_like(x)
    prev = x[0]
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(x)]):
        if sign[a] > 0:
            seg = np.maximum.accumulate(np.maximum(prev, x[a:b] - delta[a:b]))
        else:
            seg = np.minimum.accumulate(np.minimum(prev, x[a:b] + delta[a:b]))
        out[a:b] = seg
        prev = seg[-1]
    return out


def finger_motion(fabric: catalog.Fabric, cycles: int, nz: Nuisance, rng: np.random.Generator) -> Motion:
    dt = 1.0 / cal.CONTROL_HZ
    thickness = 2.0 * fabric.thickness_mm * nz.fold  # folded: the hand grips two layers
    k_n = stack_stiffness(fabric, thickness, nz.silicone_scale)
    # closing, checked once per camera frame, until the estimate (force / silicone scale + the
    # day's bias) reaches the threshold
    target_n = max(cal.GRASP_FORCE_N - nz.force_bias_n, 0.0) * nz.silicone_scale
    t_contact = (cal.OPEN_GAP_MM - thickness) / cal.CLOSING_SPEED_MM_S
    t_reach = t_contact + target_n / (k_n * cal.CLOSING_SPEED_MM_S)
    frame = 1.0 / archive.STEP_RATE
    t_stop = nz.frame_phase_s + frame * np.ceil((t_reach - nz.frame_phase_s) / frame)
    grasp_force = k_n * cal.CLOSING_SPEED_MM_S * (t_stop - t_contact)
    # rubbing
    mu = fabric.friction * nz.friction_scale
    rate = cal.CYCLE_HZ * nz.speed / (1.0 + cal.SPEED_DROOP_PER_N * mu * grasp_force)
    t_rub = t_stop + cal.SETTLE_S
    n_rub = int(np.ceil(cycles / rate * 1.1 * cal.CONTROL_HZ))  # [numerics] headroom for the wander (trimmed below)
    knot = round(cal.CYCLE_WANDER_S * cal.CONTROL_HZ)  # control samples per step of the wander's random walk
    wander = np.cumsum(rng.normal(0.0, 1.0, n_rub // knot + 2))
    wander = np.interp(np.arange(n_rub) / knot, np.arange(len(wander)), wander)
    wander = cal.CYCLE_PHASE_JITTER * (wander - wander.mean()) / max(wander.std(), 1e-9)
    phase = np.cumsum(rate * (1.0 + wander) * dt)
    n_rub = int(np.searchsorted(phase, cycles)) + 1
    phase = np.minimum(phase[:n_rub], cycles)
    n_pre = int(np.ceil(t_rub * cal.CONTROL_HZ))
    n_post = int(cal.STOP_S * cal.CONTROL_HZ)
    t = np.arange(n_pre + n_rub + n_post) * dt
    finger = np.zeros_like(t)
    ramp = np.minimum(1.0, phase / cal.RUB_RAMP_CYCLES)  # the first strokes accelerate
    finger[n_pre : n_pre + n_rub] = cal.RUB_AMPLITUDE_MM * ramp * np.sin(2 * np.pi * phase)
    closing = np.clip(t, 0.0, t_stop) * cal.CLOSING_SPEED_MM_S
    compression = np.clip(closing - (cal.OPEN_GAP_MM - thickness), 0.0, None)
    normal = k_n * compression + k_n * cal.ARC_MM * (finger / cal.RUB_AMPLITUDE_MM) ** 2 * (t >= t_rub)
    relative = finger * (1.0 if fabric.is_fabric else 2.0)
    k_t = shear_stiffness(fabric, nz.silicone_scale)
    delta = mu * normal / k_t
    slide = play(relative, delta)
    return Motion(
        t=t,
        finger_mm=finger,
        slide_mm=slide,
        normal_n=normal,
        shear_n=k_t * (relative - slide),
        closing_mm=closing,
        duration_s=float(t[-1]),
        rubbing_start_s=float(t_rub),
        slip_width_mm=float(mu * grasp_force / k_t),
        contact_stiffness_n_mm=float(k_n),
        friction=float(mu),
        grasp_n=float(grasp_force),
        force_reading=1.0 / nz.silicone_scale,
    )
