"""Minsight images: the textured shell interior under internal LED light, deformed by the contact.

[paper, Minsight Images] The camera looks at the inside of an opaque silicone shell lit by
coloured LEDs; external light never enters. Contact deforms the shell, and the image shows it as
* indentation: the normal force pushes the patch toward the camera, a radial bulge of the
  texture around the contact centre (grows with F_n) that also darkens as the surface tilts away
  from the LEDs. At the fixed 0.1 N grasp the force is the same for every fabric; what differs
  is the patch's shape (`patch_geometry`: wider on thick, compressible stacks; elongated across
  the fold on bending-stiff ones) and the fold ridge, a line pressed into the patch whose relief
  survives the shell only for thick stacks (calibration: exp(-2 pi d / lambda));
* what is not drawn, for physical reasons: weave textures (sub-mm to 3 mm periods) do not pass a
  ~2 mm shell (the same exp law), and stick-slip micro-jumps (~10-40 per second at these slide
  speeds) average out within a 20 ms frame into the Coulomb-limited shear below;
* shear: the tangential load drags the patch along the rubbing direction (stick: shear builds
  up; slip: it stays at mu * F_n), which is what optical flow picks up.
Rendered with one `cv2.remap` of a fixed procedural interior texture per frame (cheap), plus
camera noise. Only called when the scene's streams include "images".
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from fabricjax import archive, catalog
from fabricjax.sim import calibration as cal
from fabricjax.sim.motion import Motion
from fabricjax.sim.scene import Nuisance, Scene

FULL_WIDTH = archive.MINSIGHT_SIZE[1]  # the "full resolution" of the calibration's pixel sizes (`cal.*_PX*`)
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


def reference(scene: Scene) -> np.ndarray:
    """uint8 (H, W, 3): the no-contact frame of `scene`'s camera without noise (the interior as
    `render` draws it at zero force), e.g. the reference of a force proxy."""
    h, w = scene.image_size
    return np.clip(interior(scene.seed, h, w), 0, 255).astype(np.uint8)


def patch_geometry(fabric: catalog.Fabric, fold: float) -> tuple[float, float, float]:
    """(along, across, ridge) at full resolution for the folded stack at 0.1 N, see calibration:
    the patch's size along and across the fold relative to a thin, soft fabric's, and how much of
    the fold ridge's relief reaches the inner wall (0 for thin cloth, ~0.5 for a knitted hat)."""
    if not fabric.is_fabric:
        return 1.0, 1.0, 0.0
    stack_mm = 2.0 * fabric.thickness_mm * fold
    conform = 1.0 + cal.CONFORM_PER_MM * stack_mm * fabric.compressibility
    bending = 2.0 * (fabric.stretch_stiffness / cal.BENDING_REF_STRETCH_N_MM) * (fabric.thickness_mm / cal.BENDING_REF_THICKNESS_MM) ** 2
    wavelength = cal.RIDGE_WAVELENGTH_PER_THICKNESS * stack_mm
    ridge = float(np.exp(-2 * np.pi * cal.SHELL_THICKNESS_MM / wavelength))
    return conform, conform * (1.0 + bending) ** 0.25, ridge


def render(scene: Scene, motion: Motion, frame_t: np.ndarray, nz: Nuisance, rng: np.random.Generator) -> np.ndarray:
    """uint8 frames (T, H, W, 3) at the frame times."""
    h, w = scene.image_size
    base = interior(scene.seed, h, w)
    scale = w / FULL_WIDTH
    px_per_mm = w / cal.SHELL_WIDTH_MM
    fab = scene.fabric
    along, across, ridge = patch_geometry(fab, nz.fold)
    fold_angle = RUB_DIRECTION_RAD + np.pi / 2 + rng.normal(0.0, cal.FOLD_ANGLE_SPREAD_RAD)
    cx, cy = np.array([w / 2, h / 2]) + nz.contact_offset_mm * px_per_mm
    sigma = cal.CONTACT_SIGMA_PX * scale
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    # patch coordinates: u along the fold line, v across it
    c, s_ = np.cos(fold_angle), np.sin(fold_angle)
    u, v = (x - cx) * c + (y - cy) * s_, -(x - cx) * s_ + (y - cy) * c
    su, sv = sigma * along, sigma * across
    g = np.exp(-(u**2) / (2 * su**2) - v**2 / (2 * sv**2)).astype(np.float32)
    radial_x = ((u / su * c - v / sv * s_) * g).astype(np.float32)
    radial_y = ((u / su * s_ + v / sv * c) * g).astype(np.float32)
    # the fold ridge: a line across the patch at a random offset, pushing the wall out from its axis
    width = max(2.0 * fab.thickness_mm * nz.fold * px_per_mm, 0.5)
    dv = v - rng.uniform(-1.0, 1.0) * sv
    line = (ridge * np.exp(-(dv**2) / (2 * width**2)) * g).astype(np.float32)
    radial_x += (-dv / width * line * s_).astype(np.float32)
    radial_y += (dv / width * line * c).astype(np.float32)
    shear_x, shear_y = np.float32(np.cos(RUB_DIRECTION_RAD)) * g, np.float32(np.sin(RUB_DIRECTION_RAD)) * g
    normal = np.interp(frame_t, motion.t, motion.normal_n)
    shear = np.interp(frame_t, motion.t, motion.shear_n)
    frames = np.empty((len(frame_t), h, w, 3), np.uint8)
    for k, (fn, ft) in enumerate(zip(normal, shear)):
        a, s = float(cal.INDENT_PX_PER_N * scale * fn / along), float(-cal.SHEAR_PX_PER_N * scale * ft)
        map_x = x - a * radial_x - s * shear_x
        map_y = y - a * radial_y - s * shear_y
        img = cv2.remap(base, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        img *= (1.0 - float(cal.SHADING_PER_N * fn) * (g + line))[..., None]
        img += rng.standard_normal(img.shape, dtype=np.float32) * cal.CAMERA_NOISE
        frames[k] = np.clip(img, 0, 255)
    return frames
