"""Welch power spectral density of each microphone window, as a thin jitted rfft.

Parameters (`scipy.signal.welch` with the same arguments gives the same numbers):
    fs = 48 kHz, window = periodic Hann (scipy's 'hann'), nperseg = nfft = 1022, noverlap = 511,
    detrend = 'constant' (each segment's mean is removed), scaling = 'density' (power per Hz,
    one-sided), average = 'mean'.
A 2048-sample window then holds 3 segments starting at 0, 511 and 1022 (the last 4 samples are
unused) and the density has nperseg // 2 + 1 = 512 bins at k * 48000 / 1022 Hz (46.97 Hz apart,
bin 511 is Nyquist, 24 kHz): the paper's 512 bins without dropping one. The sample rate, the
window and the word format are the archive's (`fabricjax.archive`: AUDIO_RATE, WINDOW, VALID_BITS,
SAMPLE_SHIFT, FULL_SCALE).

Raw SPH0645 I2S words (int32) carry 18 valid bits in bits 31..14: an arithmetic shift right by 14
gives the signed sample, divided by 2**17 it is in units of full scale (+-1). Float input is taken
to be in full-scale units already. The microphone's large DC offset is removed by the per-segment
detrend.

Another rig's microphone keeps the same 2048-sample window and segments at its own rate `rate`
(the archive's `meta.streams.mics[k].rate`): bins then lie at k * rate / 1022 Hz, up to its Nyquist
rate / 2, and the density is per Hz at that rate. Nothing is resampled.

Bandwidth truncation keeps the bins whose centre frequency is <= the bandwidth:
    n_bins = floor(bandwidth * nperseg / fs) + 1  ->  2.5 kHz: 54, 10 kHz: 213, 15 kHz: 320, 24 kHz: 512
at 48 kHz; a bandwidth at or above the microphone's Nyquist keeps all 512 bins (the cap: there is
no content above Nyquist to keep).

Accuracy against scipy in float64: <= 1e-5 relative in float32 on every bin holding >= 1e-4 of
the window's power (FFT rounding scales with the window's energy, so no float32 FFT does better
on weaker bins); <= 1e-10 on all non-zero bins with x64. Integer input is detrended exactly in
integers, so the SPH0645's DC offset leaves no float32 residue in the lowest bins (scipy run in
float32 is off by ~3e-3 there).

The framing uses a reshape (the hop, 511, divides the 3 segments' span 2044 into 4 blocks), so no
gather is needed; `fabricjax.features.timing` times it against `jax.scipy.signal.welch`.
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from fabricjax.archive import AUDIO_RATE, FULL_SCALE, NYQUIST_KHZ, SAMPLE_SHIFT, WINDOW

NPERSEG = 1022
NOVERLAP = 511
N_BINS = NPERSEG // 2 + 1
N_SEGMENTS = (WINDOW - NOVERLAP) // (NPERSEG - NOVERLAP)
# 1e-20 full-scale^2/Hz lies ~40 dB below the 18-bit quantisation noise density (~2e-16), so only
# exact digital silence reaches it.
LOG_FLOOR = 1e-20
SCIPY_KWARGS = dict(
    fs=AUDIO_RATE, window="hann", nperseg=NPERSEG, noverlap=NOVERLAP, detrend="constant", scaling="density", average="mean"
)


def n_bins(bandwidth_khz: float, rate: int = AUDIO_RATE) -> int:
    """Bins kept when the PSD of a microphone at `rate` Hz is truncated at `bandwidth_khz` (centre
    frequency <= bandwidth), capped at its Nyquist (all bins)."""
    return min(N_BINS, math.floor(bandwidth_khz * 1000 * NPERSEG / rate) + 1)


def frequencies(bandwidth_khz: float = NYQUIST_KHZ, rate: int = AUDIO_RATE) -> np.ndarray:
    return np.arange(n_bins(bandwidth_khz, rate)) * rate / NPERSEG


def _float():
    return jax.dtypes.canonicalize_dtype(jnp.float64)  # float32 unless x64 is enabled


def to_full_scale(words: jax.Array) -> jax.Array:
    """SPH0645 int32 I2S words -> signed 18-bit samples in units of full scale (exact in float32)."""
    return jnp.right_shift(jnp.asarray(words), SAMPLE_SHIFT).astype(_float()) / FULL_SCALE


def _segments(x: jax.Array) -> jax.Array:
    """(..., 2048) -> (..., 3, 1022) Welch segments; the hop divides the span into 4 blocks."""
    hop = NPERSEG - NOVERLAP
    blocks = x[..., : hop * (N_SEGMENTS + 1)].reshape(*x.shape[:-1], N_SEGMENTS + 1, hop)
    return jnp.concatenate([blocks[..., :-1, :], blocks[..., 1:, :]], axis=-1)


_HANN = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(NPERSEG) / NPERSEG)  # float64, as scipy builds it


def _scale(rate: int) -> np.ndarray:
    """Density scaling per bin: 1 / (fs * sum(w^2)), doubled except at DC and Nyquist (even nfft)."""
    return np.where((np.arange(N_BINS) == 0) | (np.arange(N_BINS) == N_BINS - 1), 1.0, 2.0) / (rate * np.sum(_HANN**2))


@partial(jax.jit, static_argnames=("bandwidth_khz", "log", "floor", "rate"))
def welch_psd(
    windows: jax.Array, *, bandwidth_khz: float = 15.0, log: bool = True, floor: float = LOG_FLOOR, rate: int = AUDIO_RATE
) -> jax.Array:
    """(..., 2048) windows of a microphone at `rate` Hz -> (..., n_bins(bandwidth_khz, rate)) PSD,
    or log10 of it.

    Integer input is converted from SPH0645 words; float input is in full-scale units. Computes
    in float32, or float64 when x64 is enabled (int or float64 input). With `log`, values below
    `floor` are raised to it, so silence maps to log10(floor) instead of -inf.
    """
    if windows.shape[-1] != WINDOW:
        raise ValueError(f"windows must have {WINDOW} samples on the last axis, got shape {windows.shape}")
    if jnp.issubdtype(windows.dtype, jnp.integer):
        # Detrend exactly in integers (|n*q - sum q| < 2**31), then scale: a float32 mean of a
        # large DC offset would leave a rounding residue that dominates the lowest bins.
        q = _segments(jnp.right_shift(windows.astype(jnp.int32), SAMPLE_SHIFT))
        x = (q * NPERSEG - q.sum(axis=-1, keepdims=True)).astype(_float()) / (NPERSEG * FULL_SCALE)
    else:
        x = _segments(windows)
        x = x - x.mean(axis=-1, keepdims=True)
    spec = jnp.fft.rfft(x * _HANN.astype(x.dtype), axis=-1)
    k = n_bins(bandwidth_khz, rate)
    spec = spec[..., :k]
    psd = (spec.real**2 + spec.imag**2).mean(axis=-2) * _scale(rate)[:k].astype(x.dtype)
    return jnp.log10(jnp.maximum(psd, floor)) if log else psd
