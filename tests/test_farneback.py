"""The JAX Farneback (fabricjax/features/farneback.py) against OpenCV's, and the flow_method switch.

Bounds are end-point errors (EPE, pixels) between the two implementations' dense flow, what was
measured on these inputs with a wide margin: both run the same float32 steps, so they differ by
summation order and OpenCV's float64 accumulators only (measured: mean 2e-7, max 4e-6 px on the
moving textures; on identical frames max 3e-7 px at 48x64 and 60x80, 2e-2 px at 72x96, where the
coarse level's tiny border flow is ill-conditioned).
"""

import cv2
import numpy as np
import pytest

from fabricjax.config import Config
from fabricjax.features import cache, extract, farneback, flow

MOVING_MEAN_EPE = 1e-5  # measured <= 2.1e-7
MOVING_MAX_EPE = 1e-4  # measured <= 4.0e-6
SAME_MAX_EPE = 0.1  # measured <= 1.7e-2 (72x96), 3.2e-7 (48x64, 60x80)
SAME_MEAN_FLOW = 0.005  # identical frames, mean flow magnitude by either method: measured <= 0.002
SAME_MAX_FLOW = 0.25  # and at most, at the right and bottom borders: measured <= 0.17
BATCH = 3  # pairs per call in every test: one compiled program per frame size


def _texture(h, w, seed):
    """Blurred uniform noise stretched to 10..245: texture at every scale the flow uses."""
    t = cv2.GaussianBlur(np.random.default_rng(seed).uniform(0, 255, (h, w)).astype(np.float32), (0, 0), 1.5)
    return (t - t.min()) / (t.max() - t.min()) * 235 + 10


def _warp(t, u, v):
    """`t` moved by the flow (u, v): the returned frame at x shows `t` at x - (u, v)."""
    y, x = np.mgrid[: t.shape[0], : t.shape[1]].astype(np.float32)
    return cv2.remap(t, x - u, y - v, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT_101)


def _uint8(x):
    return np.clip(np.rint(x), 0, 255).astype(np.uint8)


def _pairs(h, w, motion):
    """BATCH (first, second) uint8 frame pairs of independent textures moved by `motion(x, y)`."""
    y, x = np.mgrid[:h, :w].astype(np.float32)
    u, v = motion(x / w, y / h)
    textures = [_texture(h, w, seed) for seed in range(BATCH)]
    return np.stack([_uint8(t) for t in textures]), np.stack([_uint8(_warp(t, u, v)) for t in textures])


def _epe(first, second):
    ours = np.asarray(farneback.farneback(first, second))
    theirs = np.stack([cv2.calcOpticalFlowFarneback(a, b, None, **farneback.FARNEBACK) for a, b in zip(first, second)])
    assert ours.shape == theirs.shape == (*first.shape, 2) and ours.dtype == np.float32
    return np.hypot(*np.moveaxis(ours - theirs, -1, 0)), ours, theirs


def _translation(x, y):
    return np.full_like(x, 1.3), np.full_like(x, -0.7)


def _smooth_field(x, y):
    return 1.5 * np.sin(2 * np.pi * x) * np.cos(np.pi * y), np.cos(2 * np.pi * y + 0.5)


@pytest.mark.parametrize("size", [(48, 64), (60, 80)])
@pytest.mark.parametrize("motion", [_translation, _smooth_field])
def test_moving_texture_matches_opencv(size, motion):
    epe, _, theirs = _epe(*_pairs(*size, motion))
    assert epe.mean() < MOVING_MEAN_EPE and epe.max() < MOVING_MAX_EPE, (epe.mean(), epe.max())
    assert np.hypot(*np.moveaxis(theirs, -1, 0)).mean() > 0.5  # the motion is there to be found


def test_identical_frames_match_opencv_with_pyramid():
    """72x96 is the smallest of these sizes with a pyramid level below full resolution."""
    assert (
        farneback.pyramid_levels(60, 80) == 0
        and farneback.pyramid_levels(72, 96) == 1
        and farneback.pyramid_levels(308, 410) == 3
    )
    frames = _pairs(72, 96, _translation)[0]
    epe, ours, _ = _epe(frames, frames)
    assert epe.max() < SAME_MAX_EPE, epe.max()
    # where the second frame's expansion is off the grid (the last row and column), OpenCV's
    # update sees a difference, so a little flow spreads from the right and bottom borders
    magnitude = np.hypot(*np.moveaxis(ours, -1, 0))
    assert magnitude.mean() < SAME_MEAN_FLOW and magnitude.max() < SAME_MAX_FLOW, (magnitude.mean(), magnitude.max())


def test_opencv_building_blocks():
    """The pyramid's blur kernels and bilinear resize are OpenCV's."""
    assert farneback.gaussian_kernel(3, 0.0).tolist() == [0.25, 0.5, 0.25]
    np.testing.assert_allclose(
        farneback.gaussian_kernel(9, 1.5), cv2.getGaussianKernel(9, 1.5, ktype=cv2.CV_32F)[:, 0], rtol=1e-6
    )
    img = _texture(77, 103, 0)
    for h, w in [(38, 51), (154, 205)]:
        np.testing.assert_allclose(
            np.asarray(farneback.resize_linear(img, h, w)),
            cv2.resize(img, (w, h), interpolation=cv2.INTER_LINEAR),
            atol=1e-3,
        )


def test_trial_flow_jax_matches_opencv_features():
    """The pooled features the model reads, by either method, on frames moving 1.5 px a step."""
    scene = cv2.GaussianBlur(np.random.default_rng(0).integers(0, 255, (60, 90, 3), dtype=np.uint8), (0, 0), 2)
    frames = np.stack(
        [
            _uint8(np.stack([_warp(scene[..., c].astype(np.float32), 1.5 * s, 0.0) for c in range(3)], -1))
            for s in range(5)
        ]
    )[:, :48, :64]
    by = {m: flow.trial_flow(frames, "drop_top", chunk=BATCH, method=m) for m in flow.METHODS}
    assert not by["jax"][0].any()  # step 0 has no predecessor
    np.testing.assert_allclose(by["jax"].astype(np.float32), by["opencv"].astype(np.float32), atol=2e-3)
    assert np.abs(by["opencv"][1:, 0]).mean() > 0.5


def test_flow_method_is_its_own_feature_and_opencv_keeps_its_key(tmp_path):
    today = {
        "farneback": dict(pyr_scale=0.5, levels=3, winsize=15, iterations=3, poly_n=5, poly_sigma=1.2, flags=0),
        "top_fraction": 0.001,
        "patch": 3,
    }
    for mode, name, extra in [("keep_top", "flow", {}), ("drop_top", "flow_drop_top", {"sparsify": "drop_top"})]:
        ours = extract.feature_for("flow", flow_sparsify=mode)
        assert (ours.name, ours.params) == (name, {**today, **extra})
        assert extract.feature_for("flow", flow_sparsify=mode, flow_method="opencv").params == ours.params
        jax_feature = extract.feature_for("flow", flow_sparsify=mode, flow_method="jax")
        assert (jax_feature.name, jax_feature.params) == (f"{name}_jax", {**today, **extra, "method": "jax"})
        assert extract.feature_named(jax_feature.name).params == jax_feature.params
        assert cache.folder(tmp_path, tmp_path, jax_feature) != cache.folder(tmp_path, tmp_path, ours)
    assert Config(flow_method="jax").flow_method == "jax"
    with pytest.raises(ValueError, match="flow_method"):
        Config(flow_method="torch")
