"""The SPH0645 MEMS microphone and its I2S words.

[ds, FACTS] -26 dBFS sensitivity at 94 dB SPL; 65 dB(A) SNR, i.e. 29 dB(A) SPL of self-noise;
usable band 50 Hz-15 kHz (second-order roll-offs at both ends, then the decimator's steep cut);
a large DC offset that drifts from day to day along with the gain; clipping at full scale. The
output is a 24-bit two's complement word in a 32-bit I2S slot with 18 valid bits (31..14): bits
13..8 carry noise, bits 7..0 are zero. Readers shift right by 14.

Without the "sph0645" effect the microphone is ideal (flat, silent, no offset, nominal gain):
only the conversion to 18-bit words, which the archive format requires, remains.
"""

from __future__ import annotations

import functools

import numpy as np

from fabricjax.sim import acoustics
from fabricjax.sim import calibration as cal
from fabricjax.store import archive


def band_transfer(f: np.ndarray) -> np.ndarray:
    lo, hi = cal.BAND_HZ
    decimator = 1.0 / (1.0 + (f / cal.DECIMATION_HZ) ** cal.DECIMATION_ORDER)
    return acoustics.highpass2(f, lo) * acoustics.lowpass2(f, hi) * decimator


@functools.lru_cache(maxsize=2)
def band_on(grid: acoustics.Grid) -> np.ndarray:
    """`band_transfer` on the grid's frequencies, computed once for both microphones of a trial."""
    return band_transfer(grid.f)


def self_noise(grid: acoustics.Grid, rng: np.random.Generator) -> np.ndarray:
    """Spectrum (Pa) of the microphone's equivalent input noise (white, 29 dB(A) SPL)."""
    flat = acoustics.noise_spectrum(rng, grid, np.ones(len(grid.f), np.float32))
    return acoustics.scale_to_db_a(flat, grid, cal.SELF_NOISE_DB_A)


def to_words(counts: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
    """Signed 18-bit samples -> int32 I2S words (clipped at full scale; optional junk bits)."""
    q = np.clip(np.round(counts), -archive.FULL_SCALE, archive.FULL_SCALE - 1).astype(np.int32) << archive.SAMPLE_SHIFT
    if rng is not None:
        q |= rng.integers(0, 2**cal.JUNK_BITS, q.shape, dtype=np.int32) << (
            archive.SAMPLE_SHIFT - cal.JUNK_BITS
        )  # bits 13..8
    return q


def record(
    pressure_spectrum: np.ndarray, grid: acoustics.Grid, mic: int, nuisance, rng: np.random.Generator | None
) -> np.ndarray:
    """One microphone's int32 word stream from the spectrum (Pa) of the sound at its port.

    `rng=None` means the effect is off: ideal microphone."""
    if rng is None:
        return to_words(grid.irfft(pressure_spectrum) * cal.COUNTS_PER_PA, None)
    gain = 10 ** (nuisance.mic_gain_db[mic] / 20) * cal.COUNTS_PER_PA
    spec = (pressure_spectrum + self_noise(grid, rng)) * band_on(grid)
    return to_words(grid.irfft(spec) * gain + nuisance.mic_dc_counts[mic], rng)
