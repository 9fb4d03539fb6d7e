"""Texture vibration: the fabric's surface profile read out along the finger's path.

[FACTS, texture vibration] A finger sliding at speed v over a texture of spatial period lambda
vibrates at f = v / lambda; a change of speed scales the whole spectrum; roughness raises the
broadband power; free-exploration spectra fall as 1/f^s. All three follow from reading one
spatial profile h(x) at the slide position x(t): nothing here is written in time-frequency terms.

The profile of a cloth strip (fixed per fabric, the same every day) is the sum of
* the weave: a periodic waveform of period `weave_period_mm` with irregular yarn spacing,
* random roughness with a 1/k^s height spectrum (s = `spectral_slope`),
* fuzz: loose fibre ends, narrow bumps at random places (density ~ `fuzz`),
scaled to `roughness_um` RMS and modulated slowly along the strip, so that the per-trial grasp
position changes the local phase and roughness a little. The fuzz is kept apart so that the
cloth's wear (`Nuisance.fuzz_scale`) can scale it. Class 0 rubs only the silicone skin's
micro-texture. The cavity pressure is proportional to the skin displacement (see calibration:
adiabatic cavity), scaled by the contact force relative to the 0.1 N grasp.
"""

from __future__ import annotations

import functools

import numpy as np

from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import Scene, simulated_fabric


@functools.lru_cache(maxsize=32)  # [numerics]
def surface_profile(fabric_id: int, seed: int) -> tuple[np.ndarray, np.ndarray | None]:
    """Height (um) of the fabric's new cloth strip on a `PROFILE_DX_MM` grid, as (weave and
    roughness, fuzz; None for a fabric without loose fibres): the strip's height is their sum, the
    fuzz scaled by wear (cached: pure in its inputs)."""
    fab = simulated_fabric(fabric_id)
    rng = Scene(fabric_id, seed=seed).rng("surface", "fabric")
    n = int(round(cal.PROFILE_LEN_MM / cal.PROFILE_DX_MM))
    x = np.arange(n) * cal.PROFILE_DX_MM
    k = np.fft.rfftfreq(n, cal.PROFILE_DX_MM)
    rough_um = fab.roughness_um if fab.is_fabric else cal.SHELL_ROUGHNESS_UM
    slope = fab.spectral_slope if fab.is_fabric else cal.SHELL_SPECTRAL_SLOPE
    weave_share = cal.WEAVE_SHARE if fab.weave_period_mm > 0 else 0.0
    # random roughness, 1/k^s height spectrum, flat below ROUGHNESS_K_MIN
    amp = np.maximum(k, cal.ROUGHNESS_K_MIN) ** (-slope / 2)
    amp[0] = 0.0
    z = rng.standard_normal((2, len(k)))
    rough = np.fft.irfft((z[0] + 1j * z[1]) * amp, n)
    h = rough * (np.sqrt(1 - weave_share**2) / rough.std())
    if weave_share:
        lam = fab.weave_period_mm
        warp = np.fft.irfft(rng.standard_normal(len(k)) * (k < 1 / (cal.WEAVE_WANDER_PERIODS * lam)), n)
        xw = x + cal.WEAVE_IRREGULARITY * lam * warp / max(warp.std(), 1e-12)
        harmonics = np.arange(1, cal.WEAVE_HARMONICS + 1)
        spread = cal.WEAVE_HARMONIC_SPREAD
        weights = harmonics ** (-slope / 2) * rng.uniform(1 - spread, 1 + spread, len(harmonics))
        phases = rng.uniform(0, 2 * np.pi, len(harmonics))
        weave = sum(w * np.cos(2 * np.pi * m * xw / lam + p) for m, w, p in zip(harmonics, weights, phases))
        h += weave * (weave_share / weave.std())
    fuzz = None
    if fab.fuzz > 0:
        count = rng.poisson(cal.FUZZ_FIBRES_PER_MM * fab.fuzz * cal.PROFILE_LEN_MM)
        spikes = np.zeros(n)
        np.add.at(spikes, rng.integers(0, n, count), rng.exponential(1.0, count))
        sigma = cal.FUZZ_FIBRE_WIDTH_MM / 2
        bumps = np.fft.irfft(np.fft.rfft(spikes) * np.exp(-0.5 * (2 * np.pi * k * sigma) ** 2), n)
        fuzz = cal.FUZZ_HEIGHT * fab.fuzz * bumps / max(bumps.max(), 1e-12)
    local = np.fft.irfft(rng.standard_normal(len(k)) * (k < 1 / cal.LOCAL_ROUGHNESS_LENGTH_MM), n)
    local = rough_um * (1.0 + cal.LOCAL_ROUGHNESS_SPREAD * local / max(np.abs(local).max(), 1e-12))
    return (h * local).astype(np.float64), None if fuzz is None else (fuzz * local).astype(np.float64)


def sample_profile(profile: np.ndarray, position_mm: np.ndarray) -> np.ndarray:
    """Linear interpolation on the uniform profile grid (clamped to the strip)."""
    u = np.clip(position_mm / cal.PROFILE_DX_MM, 0, len(profile) - 1.000001)  # [numerics] inside the last interval
    i = u.astype(np.int64)
    w = u - i
    return profile[i] * (1 - w) + profile[i + 1] * w


def vibration(
    scene: Scene,
    slide_mm: np.ndarray,
    normal_n: np.ndarray,
    grasp_mm: float,
    rng: np.random.Generator,
    fuzz_scale: float = 1.0,
) -> np.ndarray:
    """Cavity pressure (Pa) from the texture, given the slide position and normal force per sample,
    on the strip whose fuzz the wear has scaled by `fuzz_scale`."""
    base, fuzz = surface_profile(scene.fabric_id, scene.seed)
    profile = base if fuzz is None else base + fuzz_scale * fuzz
    steps = max(int(scene.cycles * 2), 2)
    creep = np.cumsum(rng.normal(0.0, cal.CLOTH_CREEP_MM_PER_CYCLE / np.sqrt(2), steps))
    creep = np.interp(np.linspace(0, steps - 1, len(slide_mm)), np.arange(steps), creep)
    h = sample_profile(profile, grasp_mm + slide_mm + creep)
    return cal.TEXTURE_PA_PER_UM * (normal_n / cal.GRASP_FORCE_N) * (h - h[0])
