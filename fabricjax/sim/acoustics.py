"""Acoustic units and frequency-domain plumbing shared by the sound effects.

Every microphone signal is built as one spectrum (rfft of the whole trial) and inverted once:
filters are products, sources are sums, so no effect loops over samples. Pressures are in Pa.
Levels follow IEC 61672: SPL re 20 uPa with A-weighting, as a sound meter (the paper's Sauter
SU 130) reports them.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import scipy.fft

from fabricjax.sim import calibration as cal
from fabricjax.store import archive

P_REF = 20e-6  # [cited] the reference sound pressure of SPL, 20 uPa (IEC 61672, ISO 1683)
# [cited] IEC 61672-1, Annex E: the A-weighting's pole frequencies (Hz, rounded as the standard gives
# them) and its gain at 1 kHz (A1000 = -2.0 dB), which the weighting is normalised by
A_WEIGHT_POLES_HZ = (20.6, 107.7, 737.9, 12194.0)
A_WEIGHT_1KHZ_DB = 2.0  # [cited] IEC 61672-1: A1000


@dataclasses.dataclass(frozen=True)
class Grid:
    """Time and frequency grids of one trial's audio (lead-in included)."""

    n: int  # samples
    nfft: int  # FFT length (>= n, fast)

    @classmethod
    def for_samples(cls, n: int) -> "Grid":
        return cls(n, scipy.fft.next_fast_len(n, real=True))

    @functools.cached_property
    def f(self) -> np.ndarray:
        return np.fft.rfftfreq(self.nfft, 1.0 / archive.AUDIO_RATE)

    @functools.cached_property
    def a_weight(self) -> np.ndarray:
        """`a_weighting(f)`, computed once per grid."""
        return a_weighting(self.f)

    @property
    def t(self) -> np.ndarray:
        """Seconds from the start of the procedure (negative during the lead-in)."""
        return (np.arange(self.n) - cal.LEAD_IN) / archive.AUDIO_RATE

    def rfft(self, x: np.ndarray) -> np.ndarray:
        return scipy.fft.rfft(x, self.nfft)

    def irfft(self, spectrum: np.ndarray) -> np.ndarray:
        return scipy.fft.irfft(spectrum, self.nfft)[: self.n]


def db_to_pa(db: float) -> float:
    return P_REF * 10 ** (db / 20)


def a_weighting(f: np.ndarray) -> np.ndarray:
    """IEC 61672 A-weighting as an amplitude factor (1 at 1 kHz)."""
    f1, f2_hz, f3, f4 = A_WEIGHT_POLES_HZ
    f2 = np.asarray(f, float) ** 2
    ra = f4**2 * f2**2 / ((f2 + f1**2) * np.sqrt((f2 + f2_hz**2) * (f2 + f3**2)) * (f2 + f4**2))
    return ra * 10 ** (A_WEIGHT_1KHZ_DB / 20)


def rms_of_spectrum(spectrum: np.ndarray, grid: Grid, weight: np.ndarray | None = None) -> float:
    """RMS over the grid's n samples of the signal whose rfft is `spectrum` (Parseval)."""
    p = np.abs(spectrum if weight is None else spectrum * weight) ** 2
    total = 2.0 * p.sum() - p[0] - (p[-1] if grid.nfft % 2 == 0 else 0.0)
    return float(np.sqrt(total / grid.nfft / grid.n))


def gain_to_db_a(spectrum: np.ndarray, grid: Grid, db_a: float) -> float:
    """The factor that brings `spectrum`'s A-weighted level to `db_a` dB SPL."""
    return db_to_pa(db_a) / max(rms_of_spectrum(spectrum, grid, grid.a_weight), 1e-30)  # [numerics] guards silence


def scale_to_db_a(spectrum: np.ndarray, grid: Grid, db_a: float) -> np.ndarray:
    """Scale `spectrum` so that its A-weighted level is `db_a` dB SPL."""
    return spectrum * gain_to_db_a(spectrum, grid, db_a)


def noise_spectrum(rng: np.random.Generator, grid: Grid, shape: np.ndarray) -> np.ndarray:
    """Spectrum of stationary Gaussian noise with amplitude response `shape` (any scale)."""
    z = rng.standard_normal((2, len(shape)), dtype=np.float32)
    return (z[0] + 1j * z[1]) * shape


def resonance(f: np.ndarray, f0: float, q: float) -> np.ndarray:
    """Second-order low-pass with a resonance (mass-spring-damper), unity at DC."""
    s = 1j * f / f0
    return 1.0 / (1.0 + s / q + s * s)


def highpass2(f: np.ndarray, fc: float) -> np.ndarray:
    s = 1j * f / fc
    return s * s / (1.0 + np.sqrt(2) * s + s * s)


def lowpass2(f: np.ndarray, fc: float) -> np.ndarray:
    s = 1j * f / fc
    return 1.0 / (1.0 + np.sqrt(2) * s + s * s)


def ringing_kernel_spectrum(f: np.ndarray, ring_hz: float, decay_s: float) -> np.ndarray:
    """Spectrum of a unit-amplitude damped sine sin(2 pi f0 t) exp(-t / tau), t >= 0."""
    a = 1.0 / decay_s
    w0 = 2 * np.pi * ring_hz
    s = 2j * np.pi * f
    return w0 / ((s + a) ** 2 + w0**2) * archive.AUDIO_RATE
