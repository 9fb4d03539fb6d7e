"""Minsight frames as model input: the 60x80 downsample and the rotation augmentation.

Downsampling runs on the host with OpenCV's area interpolation (pixel-area averaging, the
standard choice for shrinking, and what Minsight's own pipeline uses to resize), once per trial
before caching. "full" rows use the archive's frames unchanged.

The augmentation rotates every frame of a sequence by one angle drawn uniformly from
[-90, 90] degrees, about the image centre, with bilinear interpolation; it is a pure jitted
function of a PRNG key, so it runs inside the training step. The model applies it to its own
input, the frame minus the reference (`model.FabricNet.standardise`), where 0 means "no
deformation": that is what a rotated frame shows where its source lies outside the frame.
"""

from __future__ import annotations

from functools import partial

import cv2
import jax
import jax.numpy as jnp
import numpy as np

DOWN_SIZE = (60, 80)
MAX_DEGREES = 90.0


def downsample(frames: np.ndarray, size: tuple[int, int] = DOWN_SIZE) -> np.ndarray:
    """(T, H, W, 3) uint8 -> (T, *size, 3) uint8 by area interpolation."""
    h, w = size
    return np.stack([cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA) for f in frames])


def rotate(frames: jax.Array, degrees: jax.Array) -> jax.Array:
    """Rotate (N, H, W, C) frames by `degrees` about the centre; positive turns the picture
    clockwise as displayed (90 equals `np.rot90(frames, -1, axes=(1, 2))` on a square frame).

    Returns float32; pixels whose source lies outside the frame are 0, blended bilinearly at the
    frame's edge.
    """
    n, h, w, c = frames.shape
    theta = jnp.deg2rad(degrees)
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    yy, xx = jnp.meshgrid(jnp.arange(h, dtype=jnp.float32) - cy, jnp.arange(w, dtype=jnp.float32) - cx, indexing="ij")
    cos, sin = jnp.cos(theta), jnp.sin(theta)
    # inverse map: each output pixel samples the source at its position rotated by -theta
    sy = cos * yy - sin * xx + cy
    sx = sin * yy + cos * xx + cx
    y0, x0 = jnp.floor(sy), jnp.floor(sx)
    fy, fx = sy - y0, sx - x0
    x = frames.astype(jnp.float32)
    out = jnp.zeros((n, h, w, c), jnp.float32)
    for dy, dx, weight in ((0, 0, (1 - fy) * (1 - fx)), (0, 1, (1 - fy) * fx), (1, 0, fy * (1 - fx)), (1, 1, fy * fx)):
        yi, xi = (y0 + dy).astype(jnp.int32), (x0 + dx).astype(jnp.int32)
        inside = (yi >= 0) & (yi < h) & (xi >= 0) & (xi < w)
        pixels = x[:, jnp.clip(yi, 0, h - 1), jnp.clip(xi, 0, w - 1)]
        out = out + jnp.where(inside, weight, 0.0)[None, :, :, None] * pixels
    return out


@partial(jax.jit, static_argnames=("max_degrees",))
def rotate_sequence(key: jax.Array, frames: jax.Array, max_degrees: float = MAX_DEGREES) -> jax.Array:
    """One random angle in [-max_degrees, max_degrees] for the whole (N, H, W, C) sequence."""
    return rotate(frames, jax.random.uniform(key, (), minval=-max_degrees, maxval=max_degrees))


@partial(jax.jit, static_argnames=("max_degrees",))
def rotate_batch(key: jax.Array, frames: jax.Array, max_degrees: float = MAX_DEGREES) -> jax.Array:
    """(B, N, H, W, C): an independent angle per sequence, shared by its frames."""
    keys = jax.random.split(key, frames.shape[0])
    return jax.vmap(lambda k, f: rotate_sequence(k, f, max_degrees))(keys, frames)
