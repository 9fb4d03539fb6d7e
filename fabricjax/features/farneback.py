"""Farneback dense optical flow in JAX: OpenCV's `calcOpticalFlowFarneback`, step by step.

OpenCV computes flow one frame pair at a time on the host. Written as one jitted, vmapped JAX
program, the flow of a batch of frame pairs runs on whatever devices JAX has (many CPU cores, or
an accelerator next to the model), with no copy of dense flow back to the host before it is
sparsified and pooled.

It follows OpenCV's C++ path (modules/video/src/optflowgf.cpp) for our parameters (`FARNEBACK`,
flags 0: no initial flow, box-filter averaging), in float32 as OpenCV stores its arrays:

  levels      the pyramid is as deep as `levels` allows while both sides of the coarsest level
              stay >= `MIN_SIZE` (so a 60x80 frame has only its own level, 308x410 has four);
  pyramid     from the coarsest level: each frame Gaussian-blurred at full resolution with
              sigma = (1/scale - 1) / 2 and ksize = max(round(5 sigma) | 1, 3) (sigma 0 at level 0:
              OpenCV's fixed 3-tap kernel), borders reflected (BORDER_REFLECT_101), then resized
              bilinearly (INTER_LINEAR) to round(size * scale); the flow of the coarser level is
              resized bilinearly and multiplied by 1 / pyr_scale;
  expansion   `FarnebackPolyExp`: separable Gaussian-weighted fits (poly_n, poly_sigma) of a
              quadratic polynomial per pixel, borders replicated, scaled by the inverse of the
              fit's Gram matrix (`FarnebackPrepareGaussian`);
  matrices    `FarnebackUpdateMatrices`: the second frame's expansion sampled bilinearly where the
              current flow points (its mean with the first frame's; the first frame's alone where
              the point is off the grid), weighted down over 5 pixels at the borders;
  flow        `FarnebackUpdateFlow_Blur`: the matrices averaged over winsize x winsize (borders
              replicated), solved per pixel with OpenCV's 1e-3 regulariser; `iterations` times,
              the matrices updated from the new flow between iterations.

OpenCV accumulates the expansion's and the box filter's sums in float64; here they are float32
(results/flow_agreement.md measures what that and the summation order leave).
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

# OpenCV's reference parameters for Farneback (pyr_scale, levels, winsize, iterations, poly_n,
# poly_sigma, flags), as in its dense optical flow tutorial; both implementations use them.
FARNEBACK = dict(pyr_scale=0.5, levels=3, winsize=15, iterations=3, poly_n=5, poly_sigma=1.2, flags=0)
MIN_SIZE = 32  # OpenCV's smallest pyramid level side (`min_size` in calc)
BORDER_WEIGHTS = (0.14, 0.14, 0.4472, 0.4472, 0.4472)  # `border[]` of FarnebackUpdateMatrices, outermost first
REGULARISER = 1e-3  # added to the determinant when the averaged system is solved
SMALL_GAUSSIAN = {3: (0.25, 0.5, 0.25)}  # getGaussianKernel's fixed kernel for sigma <= 0 (the one used here)


def pyramid_levels(
    height: int, width: int, pyr_scale: float = FARNEBACK["pyr_scale"], levels: int = FARNEBACK["levels"]
) -> int:
    """Levels below full resolution that OpenCV uses for a frame of this size."""
    scale = 1.0
    for k in range(levels):
        scale *= pyr_scale
        if width * scale < MIN_SIZE or height * scale < MIN_SIZE:
            return k
    return levels


def _cv_round(x: float) -> int:
    """cvRound: to the nearest integer, halves to even (lrint)."""
    return int(np.rint(x))


def gaussian_kernel(ksize: int, sigma: float) -> np.ndarray:
    """cv::getGaussianKernel as float32: normalised in float64, then rounded."""
    if sigma <= 0 and ksize in SMALL_GAUSSIAN:
        return np.asarray(SMALL_GAUSSIAN[ksize], np.float32)
    sigma = sigma if sigma > 0 else ((ksize - 1) * 0.5 - 1) * 0.3 + 0.8
    x = np.arange(ksize) - (ksize - 1) * 0.5
    k = np.exp(-(x**2) / (2 * sigma**2))
    return (k / k.sum()).astype(np.float32)


def _correlate(x: jax.Array, taps: np.ndarray, axis: int, mode: str) -> jax.Array:
    """Centred odd-length correlation of `x` with `taps` along `axis`, borders padded by `mode`
    (numpy's "reflect" is OpenCV's BORDER_REFLECT_101, "edge" its BORDER_REPLICATE)."""
    r = len(taps) // 2
    pad = [(0, 0)] * x.ndim
    pad[axis] = (r, r)
    p = jnp.pad(x, pad, mode=mode)
    n = x.shape[axis]
    out = taps[r] * x
    for k in range(1, r + 1):
        lo = jax.lax.slice_in_dim(p, r - k, r - k + n, axis=axis)
        hi = jax.lax.slice_in_dim(p, r + k, r + k + n, axis=axis)
        out = out + taps[r - k] * lo + taps[r + k] * hi
    return out


def _linear_taps(src: int, dst: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """cv::resize INTER_LINEAR along one axis: for each output index, the two source indices and
    the second one's weight (float32, as OpenCV computes it; clamped to the edge pixel outside)."""
    scale = src / dst
    f = ((np.arange(dst) + 0.5) * scale - 0.5).astype(np.float32)
    i0 = np.floor(f).astype(np.int64)
    w = (f - i0).astype(np.float32)
    w = np.where((i0 < 0) | (i0 >= src - 1), np.float32(0), w)
    i0 = np.clip(i0, 0, src - 1)
    return i0, np.minimum(i0 + 1, src - 1), w


def resize_linear(x: jax.Array, height: int, width: int) -> jax.Array:
    """cv::resize(..., INTER_LINEAR) of (H, W) or (H, W, C) `x`: along rows first, then columns."""
    if x.shape[:2] == (height, width):
        return x  # OpenCV copies
    c0, c1, cw = _linear_taps(x.shape[1], width)
    cw = cw.reshape(1, width, *([1] * (x.ndim - 2)))
    x = x[:, c0] * (1 - cw) + x[:, c1] * cw
    r0, r1, rw = _linear_taps(x.shape[0], height)
    rw = rw.reshape(height, 1, *([1] * (x.ndim - 2)))
    return x[r0] * (1 - rw) + x[r1] * rw


@functools.lru_cache(maxsize=None)
def expansion_constants(
    n: int, sigma: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float, float, float]]:
    """FarnebackPrepareGaussian: the Gaussian g, x g and x^2 g over -n..n (float32) and the four
    entries of the inverse Gram matrix the fit needs (ig11, ig03, ig33, ig55)."""
    x = np.arange(-n, n + 1)
    g = np.exp(-(x**2) / (2 * sigma * sigma)).astype(np.float32)
    g = (g * (1.0 / g.astype(np.float64).sum())).astype(np.float32)
    xg, xxg = (x * g).astype(np.float32), (x * x * g).astype(np.float32)
    gy, gx = g[:, None], g[None, :]
    xx, yy = np.float32(x)[None, :], np.float32(x)[:, None]
    G = np.zeros((6, 6))
    G[0, 0] = np.sum((gy * gx).astype(np.float64))
    G[1, 1] = np.sum((gy * gx * xx * xx).astype(np.float64))
    G[3, 3] = np.sum((gy * gx * xx * xx * xx * xx).astype(np.float64))
    G[5, 5] = np.sum((gy * gx * xx * xx * yy * yy).astype(np.float64))
    G[2, 2] = G[0, 3] = G[0, 4] = G[3, 0] = G[4, 0] = G[1, 1]
    G[4, 4] = G[3, 3]
    G[3, 4] = G[4, 3] = G[5, 5]
    ig = np.linalg.inv(G)
    return g, xg, xxg, (ig[1, 1], ig[0, 3], ig[3, 3], ig[5, 5])


def poly_expansion(img: jax.Array, n: int = FARNEBACK["poly_n"], sigma: float = FARNEBACK["poly_sigma"]) -> jax.Array:
    """FarnebackPolyExp: (H, W) float32 -> (H, W, 5) coefficients in OpenCV's order
    (y, x, yy, xx, xy), the constant term dropped; borders replicated."""
    g, xg, xxg, (ig11, ig03, ig33, ig55) = expansion_constants(n, sigma)
    h, w = img.shape

    def pairs(x, axis):  # (x[i - k], x[i + k]) for k = 1..n, replicated borders
        p = jnp.pad(x, [(n, n) if a == axis else (0, 0) for a in range(x.ndim)], mode="edge")
        size = x.shape[axis]
        return [
            (
                jax.lax.slice_in_dim(p, n - k, n - k + size, axis=axis),
                jax.lax.slice_in_dim(p, n + k, n + k + size, axis=axis),
            )
            for k in range(1, n + 1)
        ]

    # vertical: smoothed, y-weighted and y^2-weighted rows
    row0, row1, row2 = img * g[n], jnp.zeros((h, w), img.dtype), jnp.zeros((h, w), img.dtype)
    for k, (up, down) in enumerate(pairs(img, 0), start=1):
        row0 = row0 + g[n + k] * (up + down)
        row1 = row1 + xg[n + k] * (down - up)
        row2 = row2 + xxg[n + k] * (up + down)
    # horizontal
    b1, b3, b5 = row0 * g[n], row1 * g[n], row2 * g[n]
    b2 = b4 = b6 = jnp.zeros((h, w), img.dtype)
    for k, ((l0, r0), (l1, r1), (l2, r2)) in enumerate(zip(pairs(row0, 1), pairs(row1, 1), pairs(row2, 1)), start=1):
        b1 = b1 + (r0 + l0) * g[n + k]
        b4 = b4 + (r0 + l0) * xxg[n + k]
        b2 = b2 + (r0 - l0) * xg[n + k]
        b3 = b3 + (r1 + l1) * g[n + k]
        b6 = b6 + (r1 - l1) * xg[n + k]
        b5 = b5 + (r2 + l2) * g[n + k]
    f = np.float32
    return jnp.stack(
        [b3 * f(ig11), b2 * f(ig11), b1 * f(ig03) + b5 * f(ig33), b1 * f(ig03) + b4 * f(ig33), b6 * f(ig55)], axis=-1
    )


def border_scale(height: int, width: int) -> np.ndarray:
    """(H, W) float32 weight of FarnebackUpdateMatrices' border: `BORDER_WEIGHTS` by the distance
    to each edge, multiplied in OpenCV's order (left, right, top, bottom); 1 inside."""
    b = len(BORDER_WEIGHTS)
    weights = np.asarray(BORDER_WEIGHTS, np.float32)

    def side(n):
        i = np.arange(n)
        low = np.where(i < b, weights[np.minimum(i, b - 1)], np.float32(1))
        high = np.where(i >= n - b, weights[np.clip(n - i - 1, 0, b - 1)], np.float32(1))
        return low.astype(np.float32), high.astype(np.float32)

    (xl, xh), (yl, yh) = side(width), side(height)
    return ((xl[None, :] * xh[None, :]) * yl[:, None]) * yh[:, None]


def update_matrices(r0: jax.Array, r1: jax.Array, flow: jax.Array) -> jax.Array:
    """FarnebackUpdateMatrices: (H, W, 5) expansions and (H, W, 2) flow -> (H, W, 5) per-pixel
    system (G11, G12, G22, h1, h2) before averaging."""
    h, w, _ = r0.shape
    dx, dy = flow[..., 0], flow[..., 1]
    fx = jnp.arange(w, dtype=jnp.float32)[None, :] + dx
    fy = jnp.arange(h, dtype=jnp.float32)[:, None] + dy
    x1, y1 = jnp.floor(fx), jnp.floor(fy)
    fx, fy = (fx - x1)[..., None], (fy - y1)[..., None]
    x1, y1 = x1.astype(jnp.int32), y1.astype(jnp.int32)
    inside = (x1 >= 0) & (x1 < w - 1) & (y1 >= 0) & (y1 < h - 1)
    xc, yc = jnp.clip(x1, 0, w - 2), jnp.clip(y1, 0, h - 2)
    a00, a01, a10, a11 = (1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy
    s = a00 * r1[yc, xc] + a01 * r1[yc, xc + 1] + a10 * r1[yc + 1, xc] + a11 * r1[yc + 1, xc + 1]
    inside = inside[..., None]
    near = jnp.where(inside, s[..., :2], 0.0)
    quad = jnp.where(
        inside,
        (r0[..., 2:] + s[..., 2:]) * jnp.asarray([0.5, 0.5, 0.25], jnp.float32),
        r0[..., 2:] * jnp.asarray([1, 1, 0.5], jnp.float32),
    )
    r2, r3 = (r0[..., 0] - near[..., 0]) * 0.5, (r0[..., 1] - near[..., 1]) * 0.5
    r4, r5, r6 = quad[..., 0], quad[..., 1], quad[..., 2]
    r2 = r2 + r4 * dy + r6 * dx
    r3 = r3 + r6 * dy + r5 * dx
    scale = jnp.asarray(border_scale(h, w))
    r2, r3, r4, r5, r6 = (v * scale for v in (r2, r3, r4, r5, r6))
    return jnp.stack(
        [r4 * r4 + r6 * r6, (r4 + r5) * r6, r5 * r5 + r6 * r6, r4 * r2 + r6 * r3, r6 * r2 + r5 * r3], axis=-1
    )


def solve_flow(m: jax.Array, winsize: int = FARNEBACK["winsize"]) -> jax.Array:
    """FarnebackUpdateFlow_Blur's solve: the (H, W, 5) system box-averaged over winsize x winsize
    (borders replicated), then per pixel G d = h -> (H, W, 2) flow (x, y)."""
    box = np.full(winsize, 1.0, np.float32)
    s = _correlate(_correlate(m, box, 0, "edge"), box, 1, "edge") * np.float32(1.0 / (winsize * winsize))
    g11, g12, g22, h1, h2 = (s[..., i] for i in range(5))
    idet = 1.0 / (g11 * g22 - g12 * g12 + REGULARISER)
    return jnp.stack([(g11 * h2 - g12 * h1) * idet, (g22 * h1 - g12 * h2) * idet], axis=-1)


def _pair(prev: jax.Array, nxt: jax.Array) -> jax.Array:
    """One (H, W) float32 frame pair -> (H, W, 2) flow: OpenCV's calc loop (module docstring)."""
    p = FARNEBACK
    height, width = prev.shape
    flow = None
    for k in range(pyramid_levels(height, width), -1, -1):
        scale = p["pyr_scale"] ** k
        sigma = (1.0 / scale - 1) * 0.5
        taps = gaussian_kernel(max(_cv_round(sigma * 5) | 1, 3), sigma)
        h, w = _cv_round(height * scale), _cv_round(width * scale)
        if flow is None:
            flow = jnp.zeros((h, w, 2), jnp.float32)
        else:
            flow = resize_linear(flow, h, w) * np.float32(1.0 / p["pyr_scale"])
        r0, r1 = (
            poly_expansion(resize_linear(_correlate(_correlate(f, taps, 0, "reflect"), taps, 1, "reflect"), h, w))
            for f in (prev, nxt)
        )
        m = update_matrices(r0, r1, flow)
        for i in range(p["iterations"]):
            flow = solve_flow(m, p["winsize"])
            if i < p["iterations"] - 1:
                m = update_matrices(r0, r1, flow)
    return flow


@jax.jit
def _batch(prev: jax.Array, nxt: jax.Array) -> jax.Array:
    return jax.vmap(_pair)(prev.astype(jnp.float32), nxt.astype(jnp.float32))


def farneback(prev, nxt) -> jax.Array:
    """(B, H, W) grayscale frame pairs (uint8, or float32 on the same 0-255 scale) -> (B, H, W, 2)
    float32 flow (x, y) from each `prev` to its `nxt`, as cv2.calcOpticalFlowFarneback with
    `FARNEBACK`. One compiled program per shape."""
    if np.shape(prev) != np.shape(nxt) or np.ndim(prev) != 3 or math.prod(np.shape(prev)) == 0:
        raise ValueError(f"need two equal (B, H, W) batches of frames, got {np.shape(prev)} and {np.shape(nxt)}")
    return _batch(jnp.asarray(prev), jnp.asarray(nxt))
