"""Minsight images: the textured shell interior under internal LED light, deformed by the contact.

[paper, Minsight Images] The camera looks at the inside of an opaque silicone shell lit by
coloured LEDs; external light never enters. Contact deforms the shell, and the image shows it as
* indentation: the normal force pushes the patch toward the camera, a radial bulge of the
  texture around the contact centre (grows with F_n; the patch widens on thick, compressible
  stacks) that also darkens as the surface tilts away from the LEDs;
* shear: the tangential load drags the patch along the rubbing direction (stick: shear builds
  up; slip: it stays at mu * F_n), which is what optical flow picks up.
Rendered with one `cv2.remap` of a fixed procedural interior texture per frame (cheap), plus
camera noise. Only called when the scene's streams include "images".
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from fabricjax.sim import calibration as cal
from fabricjax.sim.motion import Motion
from fabricjax.sim.scene import Nuisance, Scene

FULL_WIDTH = 410
RUB_DIRECTION_RAD = 0.35  # the stroke direction as seen by the camera


@functools.lru_cache(maxsize=4)
def interior(seed: int, height: int, width: int) -> np.ndarray:
    """The undeformed interior (float32 HxWx3, 0-255): three coloured LEDs on a speckled shell."""
    rng = Scene(0, seed=seed).rng("minsight_interior", "hardware")
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    x, y = x / width, y / height
    light = np.zeros((height, width, 3), np.float32)
    for (lx, ly), colour in zip([(0.0, 0.2), (1.0, 0.3), (0.5, 1.1)], [(60, 60, 230), (60, 220, 70), (230, 80, 60)]):
        light += np.exp(-((x - lx) ** 2 + (y - ly) ** 2) / 0.35)[..., None] * np.asarray(colour, np.float32)
    small = rng.random((max(height // 3, 4), max(width // 3, 4))).astype(np.float32)
    dots = cv2.resize((small > 0.82).astype(np.float32), (width, height), interpolation=cv2.INTER_LINEAR)
    dots = cv2.GaussianBlur(dots, (0, 0), max(width / 400, 0.6))
    return np.clip(light * (1.0 - 0.55 * dots[..., None]) + 20.0, 0, 255)


def render(scene: Scene, motion: Motion, frame_t: np.ndarray, nz: Nuisance, rng: np.random.Generator) -> np.ndarray:
    """uint8 frames (T, H, W, 3) at the frame times."""
    h, w = scene.image_size
    base = interior(scene.seed, h, w)
    scale = w / FULL_WIDTH
    px_per_mm = w / cal.SHELL_WIDTH_MM
    fab = scene.fabric
    cx, cy = np.array([w / 2, h / 2]) + nz.contact_offset_mm * px_per_mm
    conform = 1.0 + 0.15 * 2 * fab.thickness_mm * fab.compressibility
    sigma = cal.CONTACT_SIGMA_PX * scale * conform
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    g = np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * sigma**2)).astype(np.float32)
    radial_x, radial_y = ((x - cx) / sigma * g).astype(np.float32), ((y - cy) / sigma * g).astype(np.float32)
    shear_x, shear_y = np.float32(np.cos(RUB_DIRECTION_RAD)) * g, np.float32(np.sin(RUB_DIRECTION_RAD)) * g
    normal = np.interp(frame_t, motion.t, motion.normal_n)
    shear = np.interp(frame_t, motion.t, motion.shear_n)
    frames = np.empty((len(frame_t), h, w, 3), np.uint8)
    for k, (fn, ft) in enumerate(zip(normal, shear)):
        a, s = float(cal.INDENT_PX_PER_N * scale * fn / conform), float(-cal.SHEAR_PX_PER_N * scale * ft)
        map_x = x - a * radial_x - s * shear_x
        map_y = y - a * radial_y - s * shear_y
        img = cv2.remap(base, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        img *= (1.0 - float(cal.SHADING_PER_N * fn) * g)[..., None]
        img += rng.standard_normal(img.shape, dtype=np.float32) * cal.CAMERA_NOISE
        frames[k] = np.clip(img, 0, 255)
    return frames
