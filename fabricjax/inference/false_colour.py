"""False-colour images for viewing what is not an image: an optical flow field (hue = direction,
brightness = magnitude) and a 2-D array of values (a spectrogram) through matplotlib's 'magma'."""

from __future__ import annotations

import numpy as np


def flow_rgb(pooled: np.ndarray) -> np.ndarray:
    """(2, h, w) flow -> (h, w, 3) uint8 RGB: hue = direction, brightness = magnitude / the largest."""
    import cv2

    mag, ang = cv2.cartToPolar(pooled[0].astype(np.float32), pooled[1].astype(np.float32))
    hsv = np.zeros((*mag.shape, 3), np.uint8)
    hsv[..., 0] = (ang * 90 / np.pi).astype(np.uint8)
    hsv[..., 1] = 255
    hsv[..., 2] = np.clip(255 * mag / max(float(mag.max()), 1e-12), 0, 255).astype(np.uint8)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


def magma_rgb(values: np.ndarray) -> np.ndarray:
    """(F, K) values, NaN where empty -> (F, K, 3) uint8 'magma' over their own range, empty black."""
    from matplotlib import colormaps

    known = np.isfinite(values)
    lo, hi = (float(values[known].min()), float(values[known].max())) if known.any() else (0.0, 1.0)
    scaled = np.where(known, (values - lo) / max(hi - lo, 1e-12), 0.0)
    rgb = (255 * colormaps["magma"](scaled)[..., :3]).astype(np.uint8)
    rgb[~known] = 0
    return rgb
