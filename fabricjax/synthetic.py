"""Random data sets in the training batch format, for tests and benchmarks (no simulator needed).

Every modality carries a small class-dependent offset so that a model can learn something.
"""

from __future__ import annotations

import numpy as np

from fabricjax import catalog
from fabricjax.config import Config


def data_set(
    config: Config,
    n: int,
    *,
    seq_len: int | None = None,
    psd_bins: int = 24,
    flow_hw: tuple[int, int] = (25, 34),
    image_hw: tuple[int, int] = (60, 80),
    seed: int = 0,
) -> dict[str, dict[str, np.ndarray]]:
    """{"inputs": {modality: (n, N, ...)}, "labels": {fabric, stretchiness, roughness, thickness}}."""
    rng = np.random.default_rng(seed)
    steps = seq_len or config.seq_len
    fabric = rng.integers(0, catalog.N_CLASSES, n)
    shift = (fabric / catalog.N_CLASSES).astype(np.float32)[:, None, None]
    shapes = {
        "internal": (psd_bins,),
        "external": (psd_bins,),
        "proprio": (18,),
        "flow": (2, *flow_hw),
        "image": (*image_hw, 3),
    }
    inputs = {}
    for m in config.modalities:
        x = rng.normal(size=(n, steps, *shapes[m])).astype(np.float32)
        x += shift.reshape(n, 1, *([1] * len(shapes[m])))
        inputs[m] = np.clip(x * 40 + 128, 0, 255).astype(np.uint8) if m == "image" else x
    labels = {"fabric": fabric.astype(np.int32)}
    for prop, levels in catalog.PROPERTY_LEVELS.items():
        labels[prop] = (fabric % levels).astype(np.int32)
    return {"inputs": inputs, "labels": labels}
