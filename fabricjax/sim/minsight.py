"""Minsight images: the shell's interior under its LEDs, seen by its camera, deformed by the contact.

[paper, Minsight Images] The camera looks at the inside of an opaque silicone shell lit by
coloured LEDs; external light never enters. The scene is defined in millimetres
(calibration, "Minsight images"): a cylinder capped by a hemisphere, its grainy aluminium-filled
elastomer, an RGB LED ring beside the camera, an equidistant fisheye on the axis whose square
field is delivered at 308x410 as Minsight's camera node does. Each pixel sees one point of the wall
(`_View`), lit by each LED as a Lambertian surface (cos of incidence over distance squared).

The contact: Hertz's contact between two equal shells at the measured normal force gives the
indentation of the outer surface; the layer low-passes it on its way to the inner wall
(`inner_profile`). The wall moving toward the camera moves where each ray meets it (a shift along
the wall of w / tan of the ray's incidence) and tilts it (the LEDs' incidence changes: shading from
the normal, per colour); the tangential load drags it along the rubbing (`SHELL_SHEAR_STIFFNESS`),
which optical flow picks up. The folded stack sets the patch's shape and presses its fold ridge
through thick stacks only (`patch_geometry`). Weave textures and stick-slip micro-jumps are not
drawn: the layer filters sub-millimetre relief out, and slips average out within a 20 ms frame.

Every day the camera differs (`day_state`, drawn from the scene's "minsight_day" generator): the
LEDs' light (room temperature, supply voltage; the red channel drifts most, so the colour moves),
the shell's seating on the base after remounting, and the reference frame taken that day
(`reference`). Exposure and white balance are fixed by the camera node, so they do not drift.

Frames smaller than 308x410 are the same physical image area-averaged down (as the paper
downsamples): rendered at `calibration.RENDER_SUPERSAMPLE` times their size (at most 308x410),
the grain area-averaged over each pixel's footprint exactly (a summed-area table of the
flake cells), then averaged down; shot noise is added at the output size with the spread that
averaging the full-resolution camera's noise would leave. Only called when the scene's streams
include "images".
"""

from __future__ import annotations

import dataclasses
import functools

import cv2
import numpy as np

from fabricjax import archive, catalog
from fabricjax.sim import calibration as cal
from fabricjax.sim.motion import Motion
from fabricjax.sim.scene import Nuisance, Scene, nuisance

FULL_SIZE = archive.MINSIGHT_SIZE
R_IN = cal.SKELETON_RADIUS_MM
CAP_ARC_MM = np.pi / 2 * R_IN  # meridian arc from the apex to the cylinder
CIRCUMFERENCE_MM = 2 * np.pi * R_IN
CHUNK = 32  # [numerics] frames processed together: vectorised, with temporaries that stay in cache


@dataclasses.dataclass(frozen=True)
class CameraDay:
    """One recording day's camera: per-channel LED light and the shell's seating on the base."""

    led_gain: tuple[float, float, float]  # red, green, blue light relative to nominal
    seat_axial_mm: float  # the shell sits this much further from the camera
    seat_rotation_rad: float  # and turned about its axis by this much


def day_state(scene: Scene) -> CameraDay:
    """The camera of `scene`'s day (deterministic per seed, day and condition; see calibration)."""
    rng = scene.rng("minsight_day", "day")
    temperature_c = nuisance(scene).temperature_c  # the day's room ("climate"; None: the climate's centre)
    d_temp = 0.0 if temperature_c is None else temperature_c - float(np.mean(cal.ROOM_TEMPERATURE_C))
    vbus = cal.USB_VBUS_V + rng.uniform(-cal.USB_VBUS_TOLERANCE_V, cal.USB_VBUS_TOLERANCE_V)
    vf, t1 = np.asarray(cal.LED_FORWARD_V), np.asarray(cal.LED_T1_K)
    gain = (vbus - vf) / (cal.USB_VBUS_V - vf) * np.exp(-d_temp / t1)
    return CameraDay(
        led_gain=tuple(float(g) for g in gain),
        seat_axial_mm=float(rng.normal(0.0, cal.SEATING_AXIAL_SD_MM)),
        seat_rotation_rad=float(rng.normal(0.0, cal.SEATING_ROTATION_SD_RAD)),
    )


def render_size(size: tuple[int, int]) -> tuple[int, int]:
    """The grid a frame of `size` is rendered on before area-averaging: `RENDER_SUPERSAMPLE` times
    its size, at most the full 308x410 (a full-size frame is rendered as it is)."""
    h, w = size
    s = max(1, min(cal.RENDER_SUPERSAMPLE, FULL_SIZE[0] // h, FULL_SIZE[1] // w))
    return h * s, w * s


@functools.lru_cache(maxsize=2)
def _flake_table(seed: int) -> np.ndarray:
    """Summed-area table (float64, (S+1, C+1)) of the wall's flake albedo on the (meridian arc,
    circumferential arc) grid of `FLAKE_SIZE_MM` cells: the same shell every day."""
    rng = Scene(0, seed=seed).rng("minsight_interior", "hardware")
    n_s = int(np.ceil((CAP_ARC_MM + cal.SHELL_CYLINDER_MM + 1.0) / cal.FLAKE_SIZE_MM))
    n_c = int(np.ceil(CIRCUMFERENCE_MM / cal.FLAKE_SIZE_MM))
    cells = 1.0 + cal.FLAKE_CONTRAST * rng.standard_normal((n_s, n_c))
    table = np.zeros((n_s + 1, n_c + 1))
    table[1:, 1:] = cells.cumsum(0).cumsum(1)
    return table


def _box_average(table: np.ndarray, s0, s1, c0, c1) -> np.ndarray:
    """Mean of the cell field over [s0, s1] x [c0, c1] (mm; c may wrap around the circumference):
    the summed-area table interpolated bilinearly at the box's corners."""
    n_s, n_c = table.shape[0] - 1, table.shape[1] - 1
    total_c = table[:, -1]

    def integral(s, c):  # integral of the cells over [0, s] x [0, c], c unwrapped
        i = np.clip(s / cal.FLAKE_SIZE_MM, 0, n_s - 1e-9)
        turns, cw = np.divmod(c / cal.FLAKE_SIZE_MM, n_c)
        i0, fi = np.floor(i).astype(int), i - np.floor(i)
        j0, fj = np.floor(cw).astype(int), cw - np.floor(cw)
        out = 0.0
        for di, wi in ((0, 1 - fi), (1, fi)):
            for dj, wj in ((0, 1 - fj), (1, fj)):
                out = out + wi * wj * table[i0 + di, np.minimum(j0 + dj, n_c)]
        return out + turns * ((1 - fi) * total_c[i0] + fi * total_c[np.minimum(i0 + 1, n_s)])

    area = (s1 - s0) * (c1 - c0) / cal.FLAKE_SIZE_MM**2
    return (integral(s1, c1) - integral(s0, c1) - integral(s1, c0) + integral(s0, c0)) / area


@dataclasses.dataclass(frozen=True)
class _View:
    """Per pixel of a render grid: where its ray meets the wall and what it sees there."""

    valid: np.ndarray  # (H, W) bool: inside the lens's image circle
    s: np.ndarray  # meridian arc from the apex, mm (material coordinates, seating applied)
    c: np.ndarray  # circumferential arc, mm
    jac_inv: np.ndarray  # (H, W, 2, 2): pixel (x, y) change per (s, c) mm change
    shift_n: np.ndarray  # (H, W, 2): (s, c) seen per mm of inward wall displacement
    light: np.ndarray  # (3, H, W) irradiance of each LED (cos incidence / distance^2, emitter cosine)
    light_tangent: np.ndarray  # (3, H, W, 2): each LED's unit direction projected on (e_s, e_c), / distance^2
    albedo: np.ndarray  # (H, W) flake albedo averaged over the pixel's footprint


def _hit(h: int, w: int, axial: float, rotation: float):
    """Rays of an (h, w) grid through the equidistant fisheye: surface point, normal, arcs."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    xn, yn = (x + 0.5) / w * 2 - 1, (y + 0.5) / h * 2 - 1
    rn = np.hypot(xn, yn)
    theta, psi = rn * cal.CAMERA_HALF_FOV_RAD, np.arctan2(yn, xn)
    d = np.stack([np.sin(theta) * np.cos(psi), np.sin(theta) * np.sin(psi), np.cos(theta)], -1)
    cyl = cal.SHELL_CYLINDER_MM + axial  # the cap starts here (the shell seated `axial` further)
    with np.errstate(divide="ignore"):
        z_wall = R_IN / np.tan(np.maximum(theta, 1e-9))
    on_wall = z_wall <= cyl
    dc = d[..., 2] * cyl
    t_cap = dc + np.sqrt(np.maximum(dc**2 - (cyl**2 - R_IN**2), 0.0))
    t = np.where(on_wall, z_wall / np.maximum(d[..., 2], 1e-9), t_cap)
    p = d * t[..., None]
    centre = np.array([0.0, 0.0, cyl])
    radial = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], -1)
    normal = np.where(on_wall[..., None], -radial, -(p - centre) / R_IN)  # toward the interior
    beta = np.arccos(np.clip((p[..., 2] - cyl) / R_IN, -1, 1))  # polar angle on the cap
    s = np.where(on_wall, CAP_ARC_MM + (cyl - p[..., 2]), R_IN * beta)
    c = np.mod(R_IN * (psi - rotation), CIRCUMFERENCE_MM)
    e_c = np.stack([-np.sin(psi), np.cos(psi), np.zeros_like(psi)], -1)
    e_s = np.cross(e_c, normal)  # along the meridian, away from the apex
    return rn <= 1.0, p, d, normal, s, c, e_s, e_c


@functools.lru_cache(maxsize=8)  # [numerics]
def _view(seed: int, h: int, w: int, axial: float, rotation: float) -> _View:
    valid, p, d, normal, s, c, e_s, e_c = _hit(h, w, axial, rotation)
    # pixel footprint and Jacobian from neighbouring rays (c unwrapped locally)
    ds_dx, ds_dy = np.gradient(s, axis=1), np.gradient(s, axis=0)
    cu = np.unwrap(np.unwrap(c / R_IN, axis=1), axis=0) * R_IN
    dc_dx, dc_dy = np.gradient(cu, axis=1), np.gradient(cu, axis=0)
    jac = np.stack([np.stack([ds_dx, ds_dy], -1), np.stack([dc_dx, dc_dy], -1)], -2)  # d(s,c)/d(x,y)
    det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
    det = np.where(np.abs(det) < 1e-12, 1e-12, det)
    jac_inv = (
        np.stack([np.stack([jac[..., 1, 1], -jac[..., 0, 1]], -1), np.stack([-jac[..., 1, 0], jac[..., 0, 0]], -1)], -2)
        / det[..., None, None]
    )
    # a wall moving inward by w meets the ray earlier: the seen point moves by w d_t / (d . n)
    dn = np.minimum(np.sum(d * normal, -1), -0.05)  # [numerics] bounds the shift of grazing rays
    d_t = d - np.sum(d * normal, -1, keepdims=True) * normal
    shift_n = np.stack([np.sum(d_t * e_s, -1), np.sum(d_t * e_c, -1)], -1) / dn[..., None]
    lights, tangents = [], []
    for angle in cal.LED_ANGLES_RAD:
        led = np.array([cal.LED_RING_RADIUS_MM * np.cos(angle), cal.LED_RING_RADIUS_MM * np.sin(angle), 0.0])
        to_led = led - p
        dist2 = np.sum(to_led**2, -1)
        unit = to_led / np.sqrt(dist2)[..., None]
        # the collimator passes the LED's light within a cone about the axis, fading to its edge
        cone = np.cos(cal.COLLIMATOR_HALF_ANGLE_RAD)
        emit = np.maximum((-unit[..., 2] - cone) / (1 - cone), 0.0)
        lights.append(np.maximum(np.sum(unit * normal, -1), 0.0) * emit / dist2)
        tangents.append(np.stack([np.sum(unit * e_s, -1), np.sum(unit * e_c, -1)], -1) * (emit / dist2)[..., None])
    half_s = 0.5 * np.hypot(ds_dx, ds_dy).clip(cal.FLAKE_SIZE_MM / 4)
    half_c = 0.5 * np.hypot(dc_dx, dc_dy).clip(cal.FLAKE_SIZE_MM / 4)
    albedo = _box_average(_flake_table(seed), s - half_s, s + half_s, c - half_c, c + half_c)
    return _View(valid, s, c, jac_inv, shift_n, np.stack(lights), np.stack(tangents), albedo)


@functools.lru_cache(maxsize=2)
def _exposure(seed: int) -> float:
    """DN per unit radiance: the nominal no-contact frame's brightest pixels at EXPOSURE_LEVEL_DN."""
    v = _view(seed, *FULL_SIZE, 0.0, 0.0)
    radiance = (v.albedo * v.light)[:, v.valid]
    return cal.EXPOSURE_LEVEL_DN / float(np.percentile(radiance.max(0), cal.EXPOSURE_PERCENTILE))


@functools.lru_cache(maxsize=4)  # [numerics]
def inner_profile(force_n: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The inner wall's displacement profile at `force_n`: (radii mm, profile normalised to 1 at
    the centre, the outer surface's indentation per shell in mm, the share of it the inner wall
    keeps at the centre), see calibration (Hertz, layer low-pass, held by the skeleton)."""
    e_star = cal.ELASTOMER_E_PA / (2 * (1 - cal.ELASTOMER_POISSON**2))
    r_eff = cal.SHELL_OUTER_RADIUS_MM / 2 * 1e-3
    a = (3 * force_n * r_eff / (4 * e_star)) ** (1 / 3) * 1e3  # mm
    indent = a**2 / cal.SHELL_OUTER_RADIUS_MM  # per shell
    n, dx = 256, 2 * cal.CONTACT_SUPPORT_MM * 2 / 256  # [numerics] FFT grid over twice the support's diameter
    xy = (np.arange(n) - n // 2) * dx
    r = np.hypot(*np.meshgrid(xy, xy))
    inside = np.clip(r / a, 0, 1)
    q = np.maximum(r / a, 1.0)
    outer = np.where(
        r <= a, 1 - 0.5 * inside**2, (2 / np.pi) * ((1 - 0.5 * q**2) * np.arcsin(1 / q) + 0.5 * np.sqrt(q**2 - 1))
    )
    k = 2 * np.pi * np.hypot(*np.meshgrid(np.fft.fftfreq(n, dx), np.fft.fftfreq(n, dx)))
    inner = np.real(np.fft.ifft2(np.fft.fft2(outer) * np.exp(-k * cal.SHELL_THICKNESS_MM)))
    radii = xy[n // 2 :]
    line = inner[n // 2, n // 2 :]
    line = np.clip(line - np.interp(cal.CONTACT_SUPPORT_MM, radii, line), 0.0, None)  # held by the skeleton
    return radii, line / line[0], float(indent), float(line[0])


def patch_geometry(fabric: catalog.Fabric, fold: float) -> tuple[float, float, float]:
    """(along, across, ridge) for the folded stack at 0.1 N, see calibration: the patch's size along
    and across the fold relative to a thin, soft fabric's, and how much of the fold ridge's relief
    reaches the inner wall (0 for thin cloth, ~0.5 for a knitted hat)."""
    if not fabric.is_fabric:
        return 1.0, 1.0, 0.0
    stack_mm = 2.0 * fabric.thickness_mm * fold
    conform = 1.0 + cal.CONFORM_PER_MM * stack_mm * fabric.compressibility
    bending = (
        2.0
        * (fabric.stretch_stiffness / cal.BENDING_REF_STRETCH_N_MM)
        * (fabric.thickness_mm / cal.BENDING_REF_THICKNESS_MM) ** 2
    )
    wavelength = cal.RIDGE_WAVELENGTH_PER_THICKNESS * stack_mm
    ridge = float(np.exp(-2 * np.pi * cal.SHELL_THICKNESS_MM / wavelength))
    return conform, conform * (1.0 + bending) ** (1 / 4), ridge


@dataclasses.dataclass(frozen=True)
class _Contact:
    """Per pixel of a render grid, per unit load: where the seen point moves and how the light changes."""

    per_indent: np.ndarray  # (H, W, 2) pixel shift per mm of centre indentation
    per_shear: np.ndarray  # (H, W, 2) pixel shift per mm of centre shear
    shading: np.ndarray  # (3, H, W) irradiance change per mm of centre indentation


def _contact(
    view: _View,
    centre_sc: np.ndarray,
    fold_angle: float,
    along: float,
    across: float,
    ridge: float,
    ridge_offset: float,
    ridge_width: float,
) -> _Contact:
    radii, profile, _, _ = inner_profile(cal.GRASP_FORCE_N)
    ds = view.s - centre_sc[0]
    dc = np.mod(view.c - centre_sc[1] + CIRCUMFERENCE_MM / 2, CIRCUMFERENCE_MM) - CIRCUMFERENCE_MM / 2
    cos, sin = np.cos(fold_angle), np.sin(fold_angle)
    u, v = ds * cos + dc * sin, -ds * sin + dc * cos  # along and across the fold line
    rho = np.hypot(u / along, v / across)
    g = np.interp(rho, radii, profile, right=0.0)
    dg = np.gradient(profile, radii)
    dg_drho = np.interp(rho, radii, dg, right=0.0)
    rho_safe = np.maximum(rho, 1e-6)
    dg_du, dg_dv = dg_drho * u / (along**2 * rho_safe), dg_drho * v / (across**2 * rho_safe)
    dv = v - ridge_offset
    line = ridge * np.exp(-(dv**2) / (2 * ridge_width**2))
    w = g * (1 + line)
    dw_du = dg_du * (1 + line)
    dw_dv = dg_dv * (1 + line) - g * line * dv / ridge_width**2
    grad = np.stack([dw_du * cos - dw_dv * sin, dw_du * sin + dw_dv * cos], -1)  # d w / d(s, c)
    to_px = lambda sc: np.einsum("hwij,hwj->hwi", view.jac_inv, sc)  # noqa: E731
    per_indent = to_px(view.shift_n * w[..., None])
    per_shear = to_px(-np.stack([np.zeros_like(g), w], -1))  # material dragged along +c is seen from -c
    # the tilted wall: n' = n - grad w, so each LED's cos of incidence drops by grad w . its direction
    shading = -np.sum(view.light_tangent * grad[None], -1)
    return _Contact(per_indent, per_shear, np.where(view.valid, shading, 0.0))


def _area_down(frames: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(T, H, W, C) -> (T, h, w, C) mean over each output pixel's k x k block (H = k h, W = k w)."""
    k = frames.shape[1] // size[0]
    out = np.zeros((frames.shape[0], *size, frames.shape[3]), np.float32)
    for di in range(k):
        for dj in range(k):
            out += frames[:, di::k, dj::k]
    return out / np.float32(k * k)


def _noise_sigma(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Shot noise (DN) of frames of `size` showing `image` (DN), see calibration."""
    dn_per_electron = 255.0 / cal.CAMERA_FULL_WELL_E
    area = np.sqrt(size[0] * size[1] / (FULL_SIZE[0] * FULL_SIZE[1]))
    return np.sqrt(np.maximum(image, 0.0) * np.float32(dn_per_electron)) * np.float32(cal.RESIZE_NOISE_FACTOR * area)


def physical_frames(
    scene: Scene,
    indent_mm: np.ndarray,
    shear_mm: np.ndarray,
    contact: dict | None = None,
    size: tuple[int, int] | None = None,
) -> np.ndarray:
    """Noise-free float32 frames (T, h, w, 3) in DN of `scene`'s day at `size` (the scene's by
    default) for centre indentations and shears (mm per frame), rendered on `render_size(size)` and
    area-averaged down. `contact` holds the trial's patch (`trial_contact`); None: no contact."""
    size = tuple(size or scene.image_size)
    big = render_size(size)
    day = day_state(scene)
    view = _view(scene.seed, *big, day.seat_axial_mm, day.seat_rotation_rad)
    gain = _exposure(scene.seed) * np.asarray(day.led_gain)[:, None, None]  # DN per unit irradiance, per colour
    base = gain * view.light  # (3, H, W)
    albedo = np.where(view.valid, view.albedo, 0.0).astype(np.float32)
    y, x = np.mgrid[0 : big[0], 0 : big[1]].astype(np.float32)
    frames = np.empty((len(indent_mm), *size, 3), np.float32)
    if contact is None:
        frames[:] = _area_down((albedo[..., None] * base.transpose(1, 2, 0))[None].astype(np.float32), size)
        return frames
    c = _contact(view, **contact)
    valid = view.valid[..., None]
    base_t = np.where(valid, base.transpose(1, 2, 0), 0.0).astype(np.float32)
    shade = np.where(valid, (gain * c.shading).transpose(1, 2, 0), 0.0).astype(np.float32)
    px, py = c.per_indent[..., 0].astype(np.float32), c.per_indent[..., 1].astype(np.float32)
    sx, sy = c.per_shear[..., 0].astype(np.float32), c.per_shear[..., 1].astype(np.float32)
    indent, shear = np.asarray(indent_mm, np.float32), np.asarray(shear_mm, np.float32)
    seen = np.empty((CHUNK, *big, 1), np.float32)
    for start in range(0, len(indent), CHUNK):
        stop = min(start + CHUNK, len(indent))
        for k in range(start, stop):
            a, s = indent[k], shear[k]
            seen[k - start, ..., 0] = cv2.remap(
                albedo, x + a * px + s * sx, y + a * py + s * sy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
            )
        light = base_t[None] + indent[start:stop, None, None, None] * shade[None]
        frames[start:stop] = _area_down(seen[: stop - start] * np.maximum(light, 0.0), size)
    return frames


def trial_contact(scene: Scene, nz: Nuisance, rng: np.random.Generator) -> dict:
    """The trial's patch on the wall: centre (s, c mm), fold direction and ridge (the trial's draws)."""
    along, across, ridge = patch_geometry(scene.fabric, nz.fold)
    fold_angle = np.pi / 2 + rng.normal(0.0, cal.FOLD_ANGLE_SPREAD_RAD)  # the fold runs roughly along the finger
    radii, profile, _, _ = inner_profile(cal.GRASP_FORCE_N)
    half = float(np.interp(0.5, profile[::-1], radii[::-1]))  # half-displacement radius
    ridge_offset = rng.uniform(-1.0, 1.0) * half * across
    stack_mm = 2.0 * scene.fabric.thickness_mm * nz.fold if scene.fabric.is_fabric else 0.0
    # a thicker stack stops the closing fingers earlier, so the contact lands further towards the tip
    axial = cal.CONTACT_AXIAL_MM + cal.CONTACT_SHIFT_PER_STACK_MM * stack_mm
    centre = np.array([CAP_ARC_MM + cal.SHELL_CYLINDER_MM - axial, 0.0]) + nz.contact_offset_mm
    width = max(stack_mm, cal.FLAKE_SIZE_MM) if scene.fabric.is_fabric else 1.0
    return dict(
        centre_sc=centre,
        fold_angle=float(fold_angle),
        along=along,
        across=across,
        ridge=ridge,
        ridge_offset=float(ridge_offset),
        ridge_width=float(width),
    )


def loads_mm(normal_n: np.ndarray, shear_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The inner wall's centre indentation (Hertz: a^2 / R ~ F^(2/3)) and shear (F_t over the
    shell's shear stiffness), both as the layer passes them to the inner wall, mm per frame."""
    _, _, indent_ref, share = inner_profile(cal.GRASP_FORCE_N)
    indent = indent_ref * (np.maximum(normal_n, 0.0) / cal.GRASP_FORCE_N) ** (2 / 3)
    return share * indent, share * np.asarray(shear_n) / cal.SHELL_SHEAR_STIFFNESS_N_MM


def quantise(frames: np.ndarray, size: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """uint8 frames: the noise-free frames plus the camera's shot noise at `size` (in chunks of
    frames, so the temporaries stay small)."""
    out = np.empty(frames.shape, np.uint8)
    for start in range(0, len(frames), CHUNK):
        clean = frames[start : start + CHUNK]
        noisy = clean + rng.standard_normal(clean.shape, dtype=np.float32) * _noise_sigma(clean, size)
        np.clip(np.rint(noisy, out=noisy), 0, 255, out=noisy)
        out[start : start + CHUNK] = noisy
    return out


def reference(scene: Scene) -> np.ndarray:
    """uint8 (H, W, 3): the no-contact frame `scene`'s day takes as its reference (one frame after
    the camera's warm-up, with its noise), e.g. the reference of a force proxy."""
    clean = physical_frames(scene, np.zeros(1), np.zeros(1))
    return quantise(clean, scene.image_size, scene.rng("minsight_reference", "day"))[0]


def render(scene: Scene, motion: Motion, frame_t: np.ndarray, nz: Nuisance, rng: np.random.Generator) -> np.ndarray:
    """uint8 frames (T, H, W, 3) at the frame times."""
    contact = trial_contact(scene, nz, rng)
    normal = np.interp(frame_t, motion.t, motion.normal_n)
    shear = np.interp(frame_t, motion.t, motion.shear_n)
    indent, drag = loads_mm(normal, shear)
    return quantise(physical_frames(scene, indent, drag, contact), scene.image_size, rng)
