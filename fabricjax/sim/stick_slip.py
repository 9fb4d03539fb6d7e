"""Stick-slip: frictional micro-slips while sliding and a release at every stroke reversal.

[paper: friction slows the fingers; FACTS: roughness raises broadband power] Under Coulomb friction
with an elastic contact, sliding proceeds in small slips whose count per mm slid grows with the
friction coefficient; each slip releases energy at the scale of the asperities or fibres in
contact (click amplitude ~ mu * F_n * asperity height). At each reversal the contact first sticks
while the shell shears and the cloth stretches by delta = mu * F_n / k, then lets go: a larger
release whose amplitude grows with the stored elastic displacement. Each event rings the skin and
contact: a mass on the contact spring, so stiffer contacts (thin,
incompressible stacks) ring higher, within ~1-3.5 kHz. Returned as the spectrum of the whole click train (one FFT, no
sample loop).
"""

from __future__ import annotations

import numpy as np

from fabricjax.sim import acoustics
from fabricjax.sim import calibration as cal
from fabricjax.sim.motion import Motion
from fabricjax.sim.scene import Scene
from fabricjax.store import archive


def asperity_um(scene: Scene) -> float:
    fab = scene.fabric
    return fab.roughness_um if fab.is_fabric else cal.SHELL_ROUGHNESS_UM


def events(scene: Scene, motion: Motion, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Event times (s) and signed peak pressures (Pa)."""
    mu = motion.friction
    rough = asperity_um(scene) / cal.SLIP_REF_ROUGHNESS_UM
    slid = np.abs(np.diff(motion.slide_mm, prepend=motion.slide_mm[0]))
    expected = np.cumsum(cal.SLIPS_PER_MM * mu * slid)
    count = rng.poisson(expected[-1])
    times = np.interp(np.sort(rng.uniform(0, expected[-1], count)), expected, motion.t)
    load = mu * np.interp(times, motion.t, motion.normal_n) / cal.SLIP_REF_FORCE_N
    amp = cal.SLIP_PA * load * rough * rng.lognormal(0.0, cal.SLIP_SPREAD, count)
    # reversals: the finger turns while the contact is stuck
    v = np.diff(motion.finger_mm)
    rev = np.flatnonzero((np.sign(v[1:]) != np.sign(v[:-1])) & (motion.t[1:-1] > motion.rubbing_start_s)) + 1
    t_rev = motion.t[rev]
    load_rev = mu * motion.normal_n[rev] / cal.SLIP_REF_FORCE_N
    stretch = np.sqrt(motion.slip_width_mm / cal.RELEASE_REF_SLIP_MM)
    amp_rev = cal.RELEASE_PA * load_rev * stretch * min(rough, 1.0) * rng.lognormal(0.0, cal.SLIP_SPREAD, len(rev))
    t_all = np.concatenate([times, t_rev])
    a_all = np.concatenate([amp, amp_rev]) * rng.choice([-1.0, 1.0], len(t_all))
    return t_all, a_all


def spectrum(scene: Scene, motion: Motion, grid: acoustics.Grid, rng: np.random.Generator) -> np.ndarray:
    """Spectrum (Pa) of the click train in the contact, before the shell."""
    times, amps = events(scene, motion, rng)
    lo, hi = cal.SLIP_RING_HZ
    stiffness = motion.contact_stiffness_n_mm / cal.SHELL_NORMAL_STIFFNESS_N_MM  # (0, 1]
    ring = (lo + (hi - lo) * np.sqrt(stiffness)) * rng.uniform(1 - cal.SLIP_RING_SPREAD, 1 + cal.SLIP_RING_SPREAD)
    idx = np.clip(np.round(times * archive.AUDIO_RATE).astype(np.int64) + cal.LEAD_IN, 0, grid.n - 1)
    train = np.zeros(grid.n)
    np.add.at(train, idx, amps)
    return grid.rfft(train) * acoustics.ringing_kernel_spectrum(grid.f, ring, cal.SLIP_DECAY_S)
