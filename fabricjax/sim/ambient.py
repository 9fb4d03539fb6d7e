"""Ambient sound at the palm microphone: a quiet lab or a cafe.

[paper, Robustness] Lab noise near the external microphone measured 29-31 dB; the cafe-noise test
set 47-55 dB (Sauter SU 130 sound meter, so A-weighted SPL). The level is drawn per recording day
and trial (`scene.nuisance`) and imposed exactly through A-weighted Parseval sums.
* lab: ventilation and building noise, a pink (1/f) spectrum with mains hum at 50/100 Hz;
* cafe: babble of many talkers, whose long-term spectrum peaks near 125-250 Hz [FACTS] and falls
  ~6 dB/octave above 500 Hz, with a residual slow modulation, plus clatter (cups, plates):
  sparse ringing transients at 2-7 kHz.
"""

from __future__ import annotations

import numpy as np

from fabricjax import archive
from fabricjax.sim import acoustics
from fabricjax.sim import calibration as cal


def lab_shape(f: np.ndarray) -> np.ndarray:
    pink = 1.0 / np.sqrt(np.maximum(f, 20.0))
    hum = sum(0.02 * np.exp(-0.5 * ((f - h) / 1.0) ** 2) for h in (50.0, 100.0))
    return (pink + hum).astype(np.float32)


def babble_shape(f: np.ndarray) -> np.ndarray:
    """Long-term average speech spectrum: band-pass peaking at BABBLE_PEAK_HZ."""
    g = np.abs(acoustics.highpass2(f, cal.BABBLE_PEAK_HZ * 0.7) * acoustics.lowpass2(f, cal.BABBLE_PEAK_HZ * 1.4))
    return (g + 0.15 * np.abs(acoustics.lowpass2(f, 500.0)) * (f > 200) * np.sqrt(500.0 / np.maximum(f, 500.0))).astype(np.float32)


def clatter(n: int, rng: np.random.Generator) -> np.ndarray:
    """Sparse impacts (relative to a unit-RMS babble), each three inharmonic partials at 2-7 kHz."""
    out = np.zeros(n)
    tau = cal.CLATTER_DECAY_S
    t = np.arange(int(5 * tau * archive.AUDIO_RATE)) / archive.AUDIO_RATE
    for start in rng.integers(0, n, rng.poisson(cal.CLATTER_PER_S * n / archive.AUDIO_RATE)):
        partials = rng.uniform(*cal.CLATTER_RING_HZ, 3)
        hit = sum(np.sin(2 * np.pi * fp * t + rng.uniform(0, 2 * np.pi)) for fp in partials) / 3
        hit *= np.exp(-t / (tau * rng.uniform(0.5, 1.5))) * rng.lognormal(0.0, 0.5)
        stop = min(n, start + len(t))
        out[start:stop] += hit[: stop - start]
    return out


def spectrum(condition: str, level_db_a: float, grid: acoustics.Grid, rng: np.random.Generator) -> np.ndarray:
    """Spectrum (Pa) of the ambient sound at the palm microphone over the whole trial."""
    f = grid.f
    if condition == "lab":
        return acoustics.scale_to_db_a(acoustics.noise_spectrum(rng, grid, lab_shape(f)), grid, level_db_a)
    babble = grid.irfft(acoustics.noise_spectrum(rng, grid, babble_shape(f)))
    babble /= babble.std()
    n_env = int(grid.n / archive.AUDIO_RATE * 8) + 2  # syllable-rate envelope, 8 knots per second
    env = np.interp(np.linspace(0, n_env - 1, grid.n), np.arange(n_env), rng.standard_normal(n_env))
    x = babble * (1.0 + cal.BABBLE_MODULATION * env)
    x += clatter(grid.n, rng) * 10 ** (cal.CLATTER_PEAK_DB / 20)
    spec = grid.rfft(x)
    return acoustics.scale_to_db_a(spec, grid, level_db_a)
