"""Patch-pooled optical flow between consecutive Minsight frames.

Two stages:
  1. Dense Farneback flow between frame t-1 and frame t, on grayscale full-resolution frames
     (frames are taken as RGB), by one of two implementations (`METHODS`, chosen by
     `Config.flow_method`):
       opencv  OpenCV's, on the host, in C++, one frame pair at a time; OpenCV releases the GIL,
               so trials run in parallel threads. The default and the reference.
       jax     the same algorithm in JAX (farneback.py), a chunk's frame pairs as one batch on
               JAX's devices; results/flow_agreement.md measures how closely it matches.
     Step 0 has no predecessor and gets zero flow.
  2. In JAX (jitted): sparsify, then pool 3x3 patches.

Sparsify ("filter for the top 0.1 percentile according to magnitude"), two readings (`SPARSIFY`,
chosen by `Config.flow_sparsify`), both over the k = ceil(0.001 * H * W) vectors of largest
magnitude per frame (ties at the k-th magnitude count as among them):

    keep_top   keep those k vectors, zero every other one (the default). "Filter for X" selects X,
               and the paper presents the step as the one that extracts the informative motion.
               It leaves 5 of 4800 vectors per 60x80 frame and 127 of 126280 at 308x410.
    drop_top   zero those k vectors and keep the other 99.9 %: the strongest vectors as outliers
               (Farneback's largest vectors sit at specular highlights and the image border, while
               the shell's shear under a rubbing fingertip is a smooth field over the whole contact
               patch, which covers much of the frame). Published as a labelled variant.

Pooling: mean over 3x3 patches. The paper's 2x102x137 for 308x410 frames is floor(308 / 3) rows
and ceil(410 / 3) columns, so that is the rule for any size: the incomplete band of bottom rows
(H mod 3) is dropped and the incomplete band of right columns (W mod 3) is averaged over the
pixels it has. 308x410 -> 102x137, 154x205 -> 51x69, 77x103 -> 25x35.
"""

from __future__ import annotations

import functools
import math

import cv2
import jax
import jax.numpy as jnp
import numpy as np

from fabricjax.config import FLOW_METHODS as METHODS
from fabricjax.config import FLOW_SPARSIFY as SPARSIFY
from fabricjax.features import farneback as jax_farneback
from fabricjax.features.farneback import FARNEBACK

PATCH = 3
TOP_FRACTION = 0.001


def pooled_shape(height: int, width: int) -> tuple[int, int]:
    return height // PATCH, -(-width // PATCH)


def farneback(frames: np.ndarray, previous: np.ndarray | None = None, method: str = "opencv") -> np.ndarray | jax.Array:
    """(T, H, W, 3) uint8 frames -> (T, H, W, 2) float32 flow from each frame's predecessor, by
    `method` (`METHODS`; "jax" returns it on JAX's device).

    `previous` is the frame before `frames[0]` (for processing a trial in chunks); without it
    the first flow is zero.
    """
    if method not in METHODS:
        raise ValueError(f"flow method must be one of {METHODS}, got {method!r}")
    gray = np.stack([cv2.cvtColor(f, cv2.COLOR_RGB2GRAY) for f in frames])
    if method == "jax":
        before = np.concatenate(
            [gray[:1] if previous is None else cv2.cvtColor(previous, cv2.COLOR_RGB2GRAY)[None], gray[:-1]]
        )
        dense = jax_farneback.farneback(before, gray)
        return dense if previous is not None else dense.at[0].set(0.0)
    prev = None if previous is None else cv2.cvtColor(previous, cv2.COLOR_RGB2GRAY)
    out = np.zeros((len(frames), *frames.shape[1:3], 2), np.float32)
    for t, g in enumerate(gray):
        if prev is not None:
            out[t] = cv2.calcOpticalFlowFarneback(prev, g, None, **FARNEBACK)
        prev = g
    return out


def _kth_largest_bits(bits: jax.Array, k: int) -> jax.Array:
    """Per row of non-negative int32 `bits`, the k-th largest value, by bisection on the value:
    31 counting passes, exact, and much faster on CPU than `lax.top_k` over a whole frame."""
    lo = jnp.zeros(bits.shape[0], jnp.int32)  # invariant: count(bits >= lo) >= k
    hi = jnp.full(bits.shape[0], jnp.iinfo(jnp.int32).max, jnp.int32)  # count(bits >= hi) < k

    def step(_, bounds):
        lo, hi = bounds
        mid = lo + (hi - lo) // 2
        enough = jnp.sum(bits >= mid[:, None], axis=1) >= k
        return jnp.where(enough, mid, lo), jnp.where(enough, hi, mid)

    return jax.lax.fori_loop(0, 31, step, (lo, hi))[0]


def _sparsify(flow: jax.Array, mode: str) -> jax.Array:
    """Per frame, keep ("keep_top") or zero ("drop_top") the top `TOP_FRACTION` of vectors by
    magnitude and zero (keep) the rest. (T, H, W, 2)."""
    t, h, w, _ = flow.shape
    k = math.ceil(TOP_FRACTION * h * w)
    # squared magnitudes are >= 0, so their float32 bit patterns sort like the values
    bits = jax.lax.bitcast_convert_type(jnp.sum(flow**2, axis=-1), jnp.int32).reshape(t, h * w)
    top = (bits >= _kth_largest_bits(bits, k)[:, None]).reshape(t, h, w, 1)
    if mode not in SPARSIFY:
        raise ValueError(f"flow sparsification must be one of {SPARSIFY}, got {mode!r}")
    return jnp.where(top if mode == "keep_top" else ~top, flow, 0.0)


def _pool(flow: jax.Array) -> jax.Array:
    """(T, H, W, 2) -> (T, 2, h, w) patch means, see the module docstring for the edge rule."""
    t, height, width, _ = flow.shape
    h, w = pooled_shape(height, width)
    x = flow[:, : h * PATCH]
    x = jnp.pad(x, ((0, 0), (0, 0), (0, w * PATCH - width), (0, 0)))
    sums = x.reshape(t, h, PATCH, w, PATCH, 2).sum(axis=(2, 4))
    cols = np.minimum(PATCH, width - PATCH * np.arange(w))  # real columns in each patch
    return (sums / (PATCH * cols)[None, None, :, None]).transpose(0, 3, 1, 2)


@functools.partial(jax.jit, static_argnames=("mode",))
def sparsify_and_pool(flow: jax.Array, mode: str = "keep_top") -> jax.Array:
    """Dense (T, H, W, 2) flow -> (T, 2, h, w): sparsified (`SPARSIFY`), then 3x3 patch means."""
    return _pool(_sparsify(flow, mode))


def trial_flow(frames: np.ndarray, mode: str = "keep_top", chunk: int = 8, method: str = "opencv") -> np.ndarray:
    """One trial's (T, H, W, 3) frames -> (T, 2, h, w) float16 pooled flow, dense flow by `method`.

    Works in chunks of `chunk` steps so the dense full-resolution flow of a whole trial
    (1.5 GB at the paper's scale) never exists at once; the last chunk is padded to keep one
    compiled shape (its dense flow with zeros; for "jax", its frames with its last frame, so the
    batch of frame pairs keeps one shape too).
    """
    n, height, width = frames.shape[:3]
    out = np.empty((n, 2, *pooled_shape(height, width)), np.float16)
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        part = frames[start:stop]
        if method == "jax":
            part = np.concatenate([part, np.repeat(part[-1:], chunk - len(part), axis=0)])
        dense = farneback(part, frames[start - 1] if start else None, method)
        if len(dense) < chunk:
            dense = np.pad(dense, ((0, chunk - len(dense)), (0, 0), (0, 0), (0, 0)))
        out[start:stop] = np.asarray(sparsify_and_pool(dense, mode))[: stop - start]
    return out
