"""Minsight frames as model input: the 60x80 downsample and the rotation augmentation.

Downsampling runs on the host with OpenCV's area interpolation (pixel-area averaging, the
standard choice for shrinking, and what Minsight's own pipeline uses to resize), once per trial
before caching. "full" rows use the archive's frames unchanged.

The augmentation rotates every frame of a sequence by one angle drawn uniformly from
[-90, 90] degrees, about the image centre, by bilinear or nearest-pixel interpolation
(`Config.rotation_interpolation`); it is a pure function of a PRNG key, so it runs inside the
training step. The model applies it to its own standardised input, the frame minus the reference
(`model.FabricNet.image_features`); what the turn brings in from outside the frame is the training
split's mean input or the input's 0, the no-contact frame under the session reference
(`Config.rotation_fill`). It works on a sequence's pixel rows (`to_rows`), the layout in which one
angle per sequence is cheap to apply.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import cv2
import jax
import jax.numpy as jnp
import numpy as np

from fabricjax import host_arrays, runtime

DOWN_SIZE = (60, 80)
MAX_DEGREES = 90.0
HOST_BLOCK = 64  # sequences per block of `to_rows` on the host (11 MB of the default preset's frames)


# A frame's difference to its session's reference is held in 1/DIFFERENCE_SCALE grey levels: an
# area-downsampled pixel averages about a hundred camera pixels (308x410 -> 30x40), and the contact's
# difference there is below one grey level (results/camera_frames.md), so whole grey levels would
# round it away and give every session's reference its own rounding, a per-pixel offset shared by
# all of that day's trials (results/day_shift.md). |255 x 64| fits int16.
DIFFERENCE_SCALE = 64
# Frames taken to float32 at a time by `session_difference`: a 308x410 trial's frames whole would
# take four times their bytes, twice over.
DIFFERENCE_CHUNK = 64


def downsample(frames: np.ndarray, size: tuple[int, int] = DOWN_SIZE) -> np.ndarray:
    """(T, H, W, 3) frames -> (T, *size, 3) by area interpolation, in their own dtype (uint8
    frames are rounded to whole grey levels)."""
    h, w = size
    return np.stack([cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA) for f in frames])


def session_difference(
    frames: np.ndarray, reference: np.ndarray, size: tuple[int, int] | None = DOWN_SIZE
) -> np.ndarray:
    """(T, H, W, 3) uint8 frames minus the mean of their session's (R, H, W, 3) no-contact
    reference frames, both area-downsampled to `size` in float32 first (None: at the frames' own
    size): (T, h, w, 3) int16 in 1/`DIFFERENCE_SCALE` grey levels (0 is "as without contact")."""
    shrink = (lambda x: x) if size is None else (lambda x: downsample(x, size))
    ref = shrink(reference.astype(np.float32)).mean(0)
    out = np.empty((len(frames), *ref.shape), np.int16)
    for start in range(0, len(frames), DIFFERENCE_CHUNK):
        chunk = shrink(frames[start : start + DIFFERENCE_CHUNK].astype(np.float32))
        out[start : start + len(chunk)] = np.rint((chunk - ref) * DIFFERENCE_SCALE)
    return out


def to_rows(frames, length: int | None = None):
    """(..., N, H, W, C) frames -> (..., H*W, C, N) rows: pixel-major, one row per pixel holding
    its colours in every frame of the sequence. NumPy frames (S, N, H, W, C) can be given a
    `length` >= S: the rows of `length` sequences, those past S zero (an evaluation set padded to
    whole minibatches, in one copy).

    The layout the rotation wants: a sequence's frames share one angle, so rotating it moves whole
    rows (`rotate_rows`), which XLA's CPU backend gathers as contiguous copies; the same bilinear
    gathers of 3-value pixels, frame by frame, were most of a camera row's training step.
    Training holds its set in this layout (`inputs.training_layout`). NumPy frames stay on the
    host and are moved a block of sequences at a time: a whole-array transpose of a camera row's
    GB of frames strides through all of memory for every output row and ran ~7x slower."""
    *lead, n, h, w, c = frames.shape
    if not isinstance(frames, np.ndarray):
        return jnp.moveaxis(jnp.reshape(frames, (*lead, n, h * w, c)), -3, -1)
    sequences = frames.reshape(-1, n, h * w, c)
    if length is not None:
        if len(lead) != 1 or length < lead[0]:
            raise ValueError(
                f"rows of {length} sequences from frames of shape {frames.shape}: one sequence axis, at most that long"
            )
        lead = [length]
    rows = host_arrays.empty(
        (math.prod(lead), h * w, c, n), frames.dtype
    )  # zeroed; placed without a copy on CPU devices

    def block(start: int) -> None:
        part = sequences[start : start + HOST_BLOCK]
        rows[start : start + len(part)] = np.moveaxis(part, 1, -1)

    # NumPy copies without the GIL: blocks go to one thread per core, which shortens a camera row's
    # gigabyte-sized copy where there are cores to spare
    with ThreadPoolExecutor(runtime.available_cores()) as pool:
        list(pool.map(block, range(0, len(sequences), HOST_BLOCK)))
    return rows.reshape(*lead, h * w, c, n)


def patch_pixels(h: int, w: int, p: int) -> np.ndarray:
    """Flat indices of the pixels of an (h, w) frame's top-left (h // p * p, w // p * p) crop in
    patch order: patch row, patch column, then row and column inside the p x p patch. The order
    in which `model.ConvEncoder`'s first layer reads a frame, so rows taken in it (`rotate_rows`)
    reshape into that layer's input without a transpose."""
    ph, pw, py, px = np.meshgrid(np.arange(h // p), np.arange(w // p), np.arange(p), np.arange(p), indexing="ij")
    return ((ph * p + py) * w + (pw * p + px)).reshape(-1).astype(np.int32)


def random_angles(key: jax.Array, n: int, max_degrees: float = MAX_DEGREES) -> jax.Array:
    """(n,) angles, each uniform in [-max_degrees, max_degrees]: one per sequence."""
    keys = jax.random.split(key, n)
    return jax.vmap(lambda k: jax.random.uniform(k, (), minval=-max_degrees, maxval=max_degrees))(keys)


def taps(
    degrees: jax.Array, h: int, w: int, pixels: np.ndarray, interpolation: str = "bilinear"
) -> tuple[jax.Array, jax.Array]:
    """The source pixels and weights of `pixels` (flat indices) of an (h, w) frame turned by
    `degrees` about its centre: (K, P) int32 flat source indices and (K, P) float32 weights, K = 4
    bilinear corners of the source cell, or K = 1, its nearest pixel (`interpolation`). Positive
    degrees turn the picture clockwise as displayed; a source outside the frame has weight 0 (its
    index is clipped to the frame)."""
    theta = jnp.deg2rad(degrees)
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    yy, xx = jnp.meshgrid(jnp.arange(h, dtype=jnp.float32) - cy, jnp.arange(w, dtype=jnp.float32) - cx, indexing="ij")
    yy, xx = yy.reshape(-1)[pixels], xx.reshape(-1)[pixels]
    cos, sin = jnp.cos(theta), jnp.sin(theta)
    # inverse map: each output pixel samples the source at its position rotated by -theta
    sy = cos * yy - sin * xx + cy
    sx = sin * yy + cos * xx + cx
    if interpolation == "nearest":
        corners = ((jnp.round(sy), jnp.round(sx), jnp.ones_like(sy)),)
    else:
        y0, x0 = jnp.floor(sy), jnp.floor(sx)
        fy, fx = sy - y0, sx - x0
        corners = tuple(
            (y0 + dy, x0 + dx, weight)
            for dy, dx, weight in (
                (0, 0, (1 - fy) * (1 - fx)),
                (0, 1, (1 - fy) * fx),
                (1, 0, fy * (1 - fx)),
                (1, 1, fy * fx),
            )
        )
    sources, weights = [], []
    for y, x, weight in corners:
        yi, xi = y.astype(jnp.int32), x.astype(jnp.int32)
        inside = (yi >= 0) & (yi < h) & (xi >= 0) & (xi < w)
        sources.append(jnp.clip(yi, 0, h - 1) * w + jnp.clip(xi, 0, w - 1))
        weights.append(jnp.where(inside, weight, 0.0))
    return jnp.stack(sources), jnp.stack(weights)


def rotate_frames(frames: jax.Array, degrees: jax.Array, interpolation: str = "bilinear", fill=0.0) -> jax.Array:
    """(N, H, W, C) frames of one sequence, all turned by `degrees` as the training augmentation
    turns them (`rotate_rows` on every pixel): (N, H, W, C) float32. What the linear probe reads
    of rotated frames goes through the model's own rotation path."""
    n, h, w, c = frames.shape
    rows = rotate_rows(to_rows(frames), degrees, h, w, np.arange(h * w, dtype=np.int32), interpolation, fill)
    return jnp.moveaxis(rows, -1, 0).reshape(n, h, w, c)


def rotate_rows(
    rows: jax.Array, degrees: jax.Array, h: int, w: int, pixels: np.ndarray, interpolation: str = "bilinear", fill=0.0
) -> jax.Array:
    """`pixels` of a sequence turned by `degrees`, from its rows (`to_rows`: (H*W, ...) float):
    (len(pixels), ...) float32, the sources' rows summed with their weights (`taps`). What the turn
    brings in from outside the frame is `fill` (a scalar, or one value per output pixel and colour
    broadcast against the rows: (len(pixels), C, 1)), blended by the same weights at the frame's edge."""
    sources, weights = taps(degrees, h, w, pixels, interpolation)
    out = jnp.zeros((len(pixels), *rows.shape[1:]), jnp.float32)
    for source, weight in zip(sources, weights):
        out = out + weight.reshape(-1, *[1] * (rows.ndim - 1)) * rows[source].astype(jnp.float32)
    if isinstance(fill, (int, float)) and fill == 0:
        return out
    return out + (1.0 - weights.sum(0)).reshape(-1, *[1] * (rows.ndim - 1)) * fill
