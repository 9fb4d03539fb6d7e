"""Minsight's contact force read from its frames: the grasp closes until it reaches 0.1 N, and a
trial archive's `force` stream holds it. The recorder (`acquisition/`) and the importers read it
alike, so it sits here, below both.

Minsight's own force network (reference-difference and gradient images -> 3x40x40 force map) is
not available here, so `ForceProxy` is a calibrated proxy for its scalar normal force: the local
absolute difference to a no-contact reference image, mapped linearly to newtons. It is only meant
to detect the 0.1 N grasp threshold, not to replace the network.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np


@dataclasses.dataclass
class ForceProxy:
    """force = gain * max(0, local|image - reference| - deadband), in newtons.

    A contact changes a patch of the frame, so the proxy reads the largest local change: the
    `PATCH_PERCENTILE`th percentile over pixels of image - reference box-averaged over `PATCH_PX`
    pixels (its magnitude, mean over colours), where the shot noise and the video codec's noise average
    out and the patch's change stays (a whole-frame mean drowns a small patch in them). `deadband`
    absorbs what noise remains; `gain` comes from `calibrate` against known forces (a load cell on
    hardware, the simulator's force for simulated devices)."""

    PATCH_PX = 15  # pixels of 308x410: ~1 mm of the wall, less than the smallest patch
    PATCH_PERCENTILE = 99.9  # ~100 pixels: a patch's core, not one stray pixel

    reference: np.ndarray
    gain: float = 0.05
    deadband: float = 0.5

    def difference(self, image: np.ndarray) -> float:
        change = cv2.blur(image.astype(np.float32) - self.reference.astype(np.float32), (self.PATCH_PX, self.PATCH_PX))
        return float(np.percentile(np.abs(change).mean(-1), self.PATCH_PERCENTILE))

    def __call__(self, image: np.ndarray) -> float:
        return self.gain * max(0.0, self.difference(image) - self.deadband)

    @classmethod
    def calibrate(cls, reference: np.ndarray, images, forces) -> "ForceProxy":
        """Least-squares line force = gain * (difference - deadband) through frames of known force,
        e.g. no-contact frames (0 N) and frames of the closing ramp up to the grasp."""
        d = np.array([cls(reference).difference(im) for im in images])
        f = np.asarray(forces, float)
        if len(np.unique(f)) < 2:
            raise ValueError("calibration needs frames of at least two different known forces")
        slope, intercept = np.polyfit(d, f, 1)
        if slope <= 0:
            raise ValueError(f"calibration failed: force does not grow with the image difference (slope {slope:.3g})")
        return cls(reference=reference, gain=float(slope), deadband=float(-intercept / slope))
