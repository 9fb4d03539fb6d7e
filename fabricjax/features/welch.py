"""Welch power spectral density of each microphone window, as a thin jitted rfft.

Parameters (`scipy.signal.welch` with the same arguments gives the same numbers):
    fs = 48 kHz, window = periodic Hann (scipy's 'hann'), nperseg = nfft = 1022, noverlap = 511,
    detrend = 'constant' (each segment's mean is removed), scaling = 'density' (power per Hz,
    one-sided), average = 'mean'.
A 2048-sample window then holds 3 segments starting at 0, 511 and 1022 (the last 4 samples are
unused) and the density has nperseg // 2 + 1 = 512 bins at k * 48000 / 1022 Hz (46.97 Hz apart,
bin 511 is Nyquist, 24 kHz): the paper's 512 bins without dropping one. The sample rate, the
window and the word format are the archive's (`fabricjax.store.archive`: AUDIO_RATE, WINDOW, VALID_BITS,
SAMPLE_SHIFT, FULL_SCALE).

Raw SPH0645 I2S words (int32) carry 18 valid bits in bits 31..14: an arithmetic shift right by 14
gives the signed sample, divided by 2**17 it is in units of full scale (+-1). Float input is taken
to be in full-scale units already. The microphone's large DC offset is removed by the per-segment
detrend.

Each step's window is a duration, the same at every rate (`window_samples`): the paper's 2048
samples at 48 kHz, 42.67 ms, unless the data (a rig file) or a config chooses another
(`data.step_window_s`, `Config.mic_window_s`). At another
rate `rate` it is round(duration * rate) samples, and the Welch segment follows it: the hop is
floor(W * 511 / 2048) (511 for the paper's 2048), segments of twice the hop, 3 of them, so the
bins lie ~47 Hz apart at any rate, up to the microphone's Nyquist rate / 2, and the density is per
Hz at that rate. Nothing is resampled. A short window at a low rate gives few bins (94 samples at
2.2 kHz: 24 bins); `data.load_sequences` says so (`USEFUL_BINS`).

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
gather is needed; `fabricjax.bench.feature_timing` times it against `jax.scipy.signal.welch`.
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from fabricjax.store.archive import AUDIO_RATE, FULL_SCALE, NYQUIST_KHZ, SAMPLE_SHIFT, WINDOW

NPERSEG = 1022
NOVERLAP = 511
N_BINS = NPERSEG // 2 + 1
N_SEGMENTS = (WINDOW - NOVERLAP) // (NPERSEG - NOVERLAP)
MIN_HOP = 2  # the shortest hop whose segments still give a spectrum (3 bins) ...
MIN_WINDOW = -(-MIN_HOP * WINDOW // NOVERLAP)  # ... which a window of 9 samples has
USEFUL_BINS = 32  # fewer bins than this over a microphone's band are a coarse spectrum, said once when loading
# 1e-20 full-scale^2/Hz lies ~40 dB below the 18-bit quantisation noise density (~2e-16), so only
# exact digital silence reaches it.
LOG_FLOOR = 1e-20
SCIPY_KWARGS = dict(
    fs=AUDIO_RATE,
    window="hann",
    nperseg=NPERSEG,
    noverlap=NOVERLAP,
    detrend="constant",
    scaling="density",
    average="mean",
)


def window_samples(seconds: float, rate: int) -> int:
    """The samples of a `seconds`-long step window at `rate` Hz (2048 for the paper's at 48 kHz)."""
    return int(round(seconds * rate))


def hop(window: int = WINDOW) -> int:
    """The Welch hop (half a segment) for a `window`-sample window: 511 for the paper's 2048."""
    return window * NOVERLAP // WINDOW


def nperseg(window: int = WINDOW) -> int:
    return 2 * hop(window)


def full_bins(window: int = WINDOW) -> int:
    """Bins from 0 to Nyquist of a `window`-sample window's PSD: 512 for the paper's 2048."""
    return hop(window) + 1


def n_bins(bandwidth_khz: float, rate: int = AUDIO_RATE, window: int = WINDOW) -> int:
    """Bins kept when the PSD of a microphone at `rate` Hz (`window`-sample windows) is truncated
    at `bandwidth_khz` (centre frequency <= bandwidth), capped at its Nyquist (all bins)."""
    return min(full_bins(window), math.floor(bandwidth_khz * 1000 * nperseg(window) / rate) + 1)


def frequencies(bandwidth_khz: float = NYQUIST_KHZ, rate: int = AUDIO_RATE, window: int = WINDOW) -> np.ndarray:
    return np.arange(n_bins(bandwidth_khz, rate, window)) * rate / nperseg(window)


def scipy_kwargs(window: int = WINDOW, rate: int = AUDIO_RATE) -> dict:
    """`scipy.signal.welch`'s arguments for `window`-sample windows at `rate` Hz (`SCIPY_KWARGS`
    for the paper's)."""
    return {**SCIPY_KWARGS, "fs": rate, "nperseg": nperseg(window), "noverlap": hop(window)}


def _float():
    return jax.dtypes.canonicalize_dtype(jnp.float64)  # float32 unless x64 is enabled


def to_full_scale(words: jax.Array) -> jax.Array:
    """SPH0645 int32 I2S words -> signed 18-bit samples in units of full scale (exact in float32)."""
    return jnp.right_shift(jnp.asarray(words), SAMPLE_SHIFT).astype(_float()) / FULL_SCALE


def _segments(x: jax.Array) -> jax.Array:
    """(..., W) -> (..., 3, 2 hop) Welch segments (2048 -> 3 x 1022); the hop divides the span into 4 blocks."""
    h = hop(x.shape[-1])
    blocks = x[..., : h * (N_SEGMENTS + 1)].reshape(*x.shape[:-1], N_SEGMENTS + 1, h)
    return jnp.concatenate([blocks[..., :-1, :], blocks[..., 1:, :]], axis=-1)


def _hann(n: int) -> np.ndarray:
    return 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)  # periodic, float64, as scipy builds it


def _scale(rate: int, n: int) -> np.ndarray:
    """Density scaling per bin of an `n`-sample segment: 1 / (fs * sum(w^2)), doubled except at DC
    and Nyquist (even nfft)."""
    k = np.arange(n // 2 + 1)
    return np.where((k == 0) | (k == n // 2), 1.0, 2.0) / (rate * np.sum(_hann(n) ** 2))


@partial(jax.jit, static_argnames=("bandwidth_khz", "log", "floor", "rate"))
def welch_psd(
    windows: jax.Array,
    *,
    bandwidth_khz: float = 15.0,
    log: bool = True,
    floor: float = LOG_FLOOR,
    rate: int = AUDIO_RATE,
) -> jax.Array:
    """(..., W) windows of a microphone at `rate` Hz -> (..., n_bins(bandwidth_khz, rate, W)) PSD,
    or log10 of it (W: the paper's 2048, or another duration's samples, `window_samples`).

    Integer input is converted from SPH0645 words; float input is in full-scale units. Computes
    in float32, or float64 when x64 is enabled (int or float64 input). With `log`, values below
    `floor` are raised to it, so silence maps to log10(floor) instead of -inf.
    """
    w = windows.shape[-1]
    if w < MIN_WINDOW:
        raise ValueError(f"windows must have at least {MIN_WINDOW} samples on the last axis, got shape {windows.shape}")
    n = nperseg(w)
    if jnp.issubdtype(windows.dtype, jnp.integer):
        # Detrend exactly in integers (|n*q - sum q| < 2**31), then scale: a float32 mean of a
        # large DC offset would leave a rounding residue that dominates the lowest bins.
        q = _segments(jnp.right_shift(windows.astype(jnp.int32), SAMPLE_SHIFT))
        x = (q * n - q.sum(axis=-1, keepdims=True)).astype(_float()) / (n * FULL_SCALE)
    else:
        x = _segments(windows)
        x = x - x.mean(axis=-1, keepdims=True)
    spec = jnp.fft.rfft(x * _hann(n).astype(x.dtype), axis=-1)
    k = n_bins(bandwidth_khz, rate, w)
    spec = spec[..., :k]
    psd = (spec.real**2 + spec.imag**2).mean(axis=-2) * _scale(rate, n)[:k].astype(x.dtype)
    return jnp.log10(jnp.maximum(psd, floor)) if log else psd
