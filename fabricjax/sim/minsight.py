"""Minsight images: the shell's interior under its LEDs, seen by its camera, deformed by the contact.

[paper, Minsight Images] The camera looks at the inside of an opaque silicone shell lit by
coloured LEDs; external light never enters. The scene is defined in millimetres
(calibration, "Minsight images"): a cylinder capped by a hemisphere, its grainy aluminium-filled
elastomer, an RGB LED ring beside the camera, an equidistant fisheye on the axis whose square
field is delivered at 308x410 as Minsight's camera node does. Each pixel sees one point of the wall
(`_View`), lit by each LED as a Lambertian surface (cos of incidence over distance squared).

The interior as Minsight images it: the mould insert's radial ridges (`INTERIOR_RIDGES`) tilt the
wall to and fro around the circumference, so each LED lights their flanks differently, and each
LED's collimated cone ends in a sharp edge, so the colours meet in zones with sharp borders; the
whole image circle is lit (`_rest`).

The contact (`patch_geometry`, `_contact`, `frame_loads`): Hertz's contact between two equal shells
at the measured normal force gives the indentation of the outer surface; a compressible stack
spreads it like an elastic foundation (a wider, shallower patch); the incompressible layer passes
it to the inner wall with the kernel (1 + kd) e^(-kd) (`layer_transfer`, `inner_profile`). The
wall moving toward the camera moves where each ray meets it (a shift along the wall of w / tan of
the ray's incidence) and tilts it (the LEDs' incidence changes: shading from the normal, per
colour); the tangential load drags it along the rubbing (`SHELL_SHEAR_STIFFNESS`), which optical
flow picks up. The two convex fingertips, offset by the stroke, roll the contact along the shell
(`travel_mm`), so the patch travels with every stroke. The folded stack presses its fold ridge
through thick stacks only, and a coarse weave or knit (periods of millimetres) ripples the patch
as the cloth slides across it; finer textures the layer filters out.

Every day the camera differs (`day_state`, drawn from the scene's "minsight_day" generator): the
LEDs' light (room temperature, the port's supply voltage; the red channel drifts most, so the
colour moves). The shell is over-moulded on its skeleton and never remounted, so where it sits on
the camera is one draw for the device. The session's reference averages `archive.REFERENCE_FRAMES`
no-contact frames (`reference`). Exposure and white balance are fixed by the camera node, so they
do not drift.

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

from fabricjax import catalog
from fabricjax.sim import calibration as cal
from fabricjax.sim.motion import Motion
from fabricjax.sim.scene import Nuisance, Scene, nuisance
from fabricjax.store import archive

FULL_SIZE = archive.MINSIGHT_SIZE
R_IN = cal.SKELETON_RADIUS_MM
CAP_ARC_MM = np.pi / 2 * R_IN  # meridian arc from the apex to the cylinder
CIRCUMFERENCE_MM = 2 * np.pi * R_IN
CHUNK = 32  # [numerics] frames processed together: vectorised, with temporaries that stay in cache


@dataclasses.dataclass(frozen=True)
class CameraDay:
    """One recording day's camera: per-channel LED light, and the shell's seating on the base (the
    device's, the same every day)."""

    led_gain: tuple[float, float, float]  # red, green, blue light relative to nominal
    seat_axial_mm: float  # the shell sits this much further from the camera
    seat_rotation_rad: float  # and turned about its axis by this much


def day_state(scene: Scene) -> CameraDay:
    """The camera of `scene`'s day (deterministic per seed, day and condition; see calibration)."""
    rng = scene.rng("minsight_day", "day")
    temperature_c = nuisance(scene).temperature_c  # the day's room ("climate"; None: the climate's centre)
    d_temp = 0.0 if temperature_c is None else temperature_c - float(np.mean(cal.ROOM_TEMPERATURE_C))
    vbus = cal.USB_VBUS_V + rng.uniform(-cal.USB_VBUS_DAY_SPREAD_V, cal.USB_VBUS_DAY_SPREAD_V)
    vf, t1 = np.asarray(cal.LED_FORWARD_V), np.asarray(cal.LED_T1_K)
    gain = (vbus - vf) / (cal.USB_VBUS_V - vf) * np.exp(-d_temp / t1)
    seating = scene.rng("minsight_seating", "hardware")
    return CameraDay(
        led_gain=tuple(float(g) for g in gain),
        seat_axial_mm=float(seating.normal(0.0, cal.SEATING_AXIAL_SD_MM)),
        seat_rotation_rad=float(seating.normal(0.0, cal.SEATING_ROTATION_SD_RAD)),
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
    ridge_slope: np.ndarray  # (H, W) the ridges' slope along e_c, averaged over the pixel's footprint
    area: np.ndarray  # (H, W) the wall's area each pixel sees, mm^2 (0 outside the image circle)


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
        # the collimator passes the LED's light within a cone about the axis, its edge a penumbra
        off_axis = np.arccos(np.clip(-unit[..., 2], -1.0, 1.0))
        emit = np.clip((cal.COLLIMATOR_HALF_ANGLE_RAD - off_axis) / cal.COLLIMATOR_EDGE_RAD + 0.5, 0.0, 1.0)
        lights.append(np.maximum(np.sum(unit * normal, -1), 0.0) * emit / dist2)
        tangents.append(np.stack([np.sum(unit * e_s, -1), np.sum(unit * e_c, -1)], -1) * (emit / dist2)[..., None])
    half_s = 0.5 * np.hypot(ds_dx, ds_dy).clip(cal.FLAKE_SIZE_MM / 4)
    half_c = 0.5 * np.hypot(dc_dx, dc_dy).clip(cal.FLAKE_SIZE_MM / 4)
    albedo = _box_average(_flake_table(seed), s - half_s, s + half_s, c - half_c, c + half_c)
    area = np.where(valid, np.abs(jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]), 0.0)
    lights, tangents = np.stack(lights), np.stack(tangents)
    return _View(valid, s, c, jac_inv, shift_n, lights, tangents, albedo, ridge_slope(c, 2 * half_c), area)


def ridge_slope(c: np.ndarray, footprint_mm: np.ndarray) -> np.ndarray:
    """Slope along the circumference of the interior's moulded ridges, h(c) = H/2 (1 - cos(2 pi N c / C)),
    averaged over a footprint (mm along c): the box average of a sine is the sine times sinc."""
    k = 2 * np.pi * cal.INTERIOR_RIDGES / CIRCUMFERENCE_MM
    return 0.5 * cal.INTERIOR_RIDGE_HEIGHT_MM * k * np.sin(k * c) * np.sinc(footprint_mm * k / (2 * np.pi))


def _rest(view: _View) -> np.ndarray:
    """(3, H, W) irradiance of the resting wall per colour: each LED's direct light, its ridges'
    flanks tilted toward or away from it (cos of incidence changes by the slope times the LED's
    direction along e_c), plus the light the reflective interior passes around the closed shell, as
    in an integrating cavity: rho / (1 - rho) times the wall's mean direct irradiance, even over the
    wall (see calibration)."""
    tilted = view.light - view.ridge_slope[None] * view.light_tangent[..., 1]
    direct = np.where(view.valid[None], np.maximum(tilted, 0.0), 0.0)
    rho = cal.INTERIOR_REFLECTANCE
    around = rho / (1 - rho) * np.sum(direct * view.area, (1, 2)) / np.sum(view.area)
    return np.where(view.valid[None], direct + around[:, None, None], 0.0)


@functools.lru_cache(maxsize=2)
def _exposure(seed: int) -> float:
    """DN per unit radiance: the nominal no-contact frame's median pixel (its brightest channel) at
    EXPOSURE_LEVEL_DN."""
    v = _view(seed, *FULL_SIZE, 0.0, 0.0)
    radiance = (v.albedo * _rest(v))[:, v.valid]
    return cal.EXPOSURE_LEVEL_DN / float(np.percentile(radiance.max(0), cal.EXPOSURE_PERCENTILE))


def hertz(force_n: float) -> tuple[float, float]:
    """(contact radius, indentation of each shell), mm, of two equal shells pressed by `force_n`
    (Hertz, see calibration)."""
    e_star = cal.ELASTOMER_E_PA / (2 * (1 - cal.ELASTOMER_POISSON**2))
    r_eff = cal.SHELL_OUTER_RADIUS_MM / 2 * 1e-3
    a = (3 * force_n * r_eff / (4 * e_star)) ** (1 / 3) * 1e3
    return a, a**2 / cal.SHELL_OUTER_RADIUS_MM


def layer_transfer(k: np.ndarray, depth_mm: float) -> np.ndarray:
    """Share of a surface displacement of wavenumber `k` (rad/mm) that reaches `depth_mm` in an
    incompressible elastic solid: (1 + k d) e^(-k d) (see calibration)."""
    kd = np.abs(k) * depth_mm
    return (1.0 + kd) * np.exp(-kd)


@functools.lru_cache(maxsize=64)  # [numerics]
def inner_profile(radius_mm: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The inner wall's displacement under a Hertz patch of contact radius `radius_mm`: (radii mm,
    profile normalised to 1 at the centre, the share of the outer indentation the inner wall keeps
    at the centre), see calibration (the layer's kernel, held by the skeleton, the free inner face)."""
    a = radius_mm
    n, dx = 256, 2 * cal.CONTACT_SUPPORT_MM * 2 / 256  # [numerics] FFT grid over twice the support's diameter
    xy = (np.arange(n) - n // 2) * dx
    r = np.hypot(*np.meshgrid(xy, xy))
    inside = np.clip(r / a, 0, 1)
    q = np.maximum(r / a, 1.0)
    outer = np.where(
        r <= a, 1 - 0.5 * inside**2, (2 / np.pi) * ((1 - 0.5 * q**2) * np.arcsin(1 / q) + 0.5 * np.sqrt(q**2 - 1))
    )
    k = 2 * np.pi * np.hypot(*np.meshgrid(np.fft.fftfreq(n, dx), np.fft.fftfreq(n, dx)))
    inner = np.real(np.fft.ifft2(np.fft.fft2(outer) * layer_transfer(k, cal.SHELL_THICKNESS_MM)))
    radii = xy[n // 2 :]
    line = inner[n // 2, n // 2 :]
    line = np.clip(line - np.interp(cal.CONTACT_SUPPORT_MM, radii, line), 0.0, None)  # held by the skeleton
    return radii, line / line[0], float(min(line[0] * cal.INNER_FACE_FREE_GAIN, 1.0))


@dataclasses.dataclass(frozen=True)
class Patch:
    """The folded stack's patch at the grasp's force, relative to two bare shells' Hertz patch."""

    along: float  # radius along the fold
    across: float  # radius across the fold
    depth: float  # the outer surface's indentation at the centre
    ridge: float  # share of the fold ridge's relief that reaches the inner wall
    stack_mm: float  # the stack's thickness (two layers of the folded cloth)


def patch_geometry(fabric: catalog.Fabric, fold: float) -> Patch:
    """The patch of the folded stack at 0.1 N, see calibration: a compressible stack spreads it like
    an elastic foundation, a ~ sqrt(2 R_eff (d_shell + d_stack)), and makes it shallower at the same
    force (d ~ F / (a E*)); a bending-stiff stack widens it across the fold; the fold ridge reaches
    the inner wall through the layer's kernel (0 for thin cloth, ~0.5 for a knitted hat)."""
    if not fabric.is_fabric:
        return Patch(1.0, 1.0, 1.0, 0.0, 0.0)
    stack_mm = 2.0 * fabric.thickness_mm * fold
    _, d_shell = hertz(cal.GRASP_FORCE_N)
    spread = float(np.sqrt((d_shell + fabric.compressibility * stack_mm) / d_shell))
    bending = (
        2.0
        * (fabric.stretch_stiffness / cal.BENDING_REF_STRETCH_N_MM)
        * (fabric.thickness_mm / cal.BENDING_REF_THICKNESS_MM) ** 2
    )
    wavelength = cal.RIDGE_WAVELENGTH_PER_THICKNESS * stack_mm
    ridge = float(layer_transfer(2 * np.pi / wavelength, cal.SHELL_THICKNESS_MM))
    return Patch(spread, spread * (1.0 + bending) ** (1 / 4), 1.0 / spread, ridge, stack_mm)


def travel_mm(finger_mm: np.ndarray, stack_mm: float) -> np.ndarray:
    """How far the contact rolls along each shell when the fingertips are offset by +-finger_mm:
    the contact of two spheres of radius R lies on the line of their centres, which a lateral offset
    of 2 x turns by arctan(2 x / (2 R + t)) over a stack of thickness t, and the contact moves R times
    that along each shell (~ x 2R / (2R + t))."""
    r = cal.SHELL_OUTER_RADIUS_MM
    return r * np.arctan(2 * np.asarray(finger_mm) / (2 * r + stack_mm))


def texture_relief(fabric: catalog.Fabric) -> tuple[float, float]:
    """(amplitude mm, wavelength mm) of the cloth's dominant weave or knit relief along the rubbing,
    as it reaches the inner wall: all its roughness in that period (an upper bound, sqrt(2) x RMS),
    passed by the layer's kernel; none for bare fingers."""
    if not fabric.is_fabric:
        return 0.0, 1.0
    wavelength = fabric.weave_period_mm
    passed = layer_transfer(2 * np.pi / wavelength, cal.SHELL_THICKNESS_MM) * cal.INNER_FACE_FREE_GAIN
    return float(np.sqrt(2) * fabric.roughness_um * 1e-3 * passed), float(wavelength)


@dataclasses.dataclass(frozen=True)
class _Contact:
    """Per pixel of a render grid, per unit of each load a frame's contact is a sum of (B: the
    indentation, the shear drag, the cloth's relief in cosine and in sine phase): where the seen
    point moves and how the light changes."""

    shift: np.ndarray  # (B, H, W, 2) pixel shift per mm
    shading: np.ndarray  # (B, 3, H, W) irradiance change per mm


def _contact(view: _View, contact: dict, centre_c: float) -> _Contact:
    """The contact's fields with its centre at circumferential arc `centre_c` (mm)."""
    patch, fold_angle = contact["patch"], contact["fold_angle"]
    a, _ = hertz(cal.GRASP_FORCE_N)
    radii, profile, share = inner_profile(round(a * patch.along, 2))  # [numerics] patches within 10 um share a profile
    along, across = 1.0, patch.across / patch.along  # the profile is the along radius's
    ds = view.s - contact["centre_s"]
    dc = np.mod(view.c - centre_c + CIRCUMFERENCE_MM / 2, CIRCUMFERENCE_MM) - CIRCUMFERENCE_MM / 2
    cos, sin = np.cos(fold_angle), np.sin(fold_angle)
    u, v = ds * cos + dc * sin, -ds * sin + dc * cos  # along and across the fold line
    rho = np.hypot(u / along, v / across)
    g = np.interp(rho, radii, profile, right=0.0)
    dg_drho = np.interp(rho, radii, np.gradient(profile, radii), right=0.0)
    rho_safe = np.maximum(rho, 1e-6)
    dg_du, dg_dv = dg_drho * u / (along**2 * rho_safe), dg_drho * v / (across**2 * rho_safe)
    rotate = lambda du, dv: np.stack([du * cos - dv * sin, du * sin + dv * cos], -1)  # noqa: E731  d/d(s, c)
    grad_g = rotate(dg_du, dg_dv)
    dv = v - contact["ridge_offset"]
    width = contact["ridge_width"]
    line = patch.ridge * np.exp(-(dv**2) / (2 * width**2))
    grad_line = rotate(np.zeros_like(u), -line * dv / width**2)
    indent = share * patch.depth
    normal_fields = [  # (w, grad w) per unit load
        (indent * g * (1 + line), indent * ((1 + line)[..., None] * grad_g + g[..., None] * grad_line))
    ]
    k = 2 * np.pi / contact["texture_wavelength"]
    for wave, dwave in ((np.cos(k * dc), -k * np.sin(k * dc)), (np.sin(k * dc), k * np.cos(k * dc))):
        grad = wave[..., None] * grad_g + np.stack([np.zeros_like(g), g * dwave], -1)
        normal_fields.append((g * wave, grad))
    to_px = lambda sc: np.einsum("hwij,hwj->hwi", view.jac_inv, sc)  # noqa: E731
    shifts = [to_px(view.shift_n * w[..., None]) for w, _ in normal_fields]
    # the tilted wall: n' = n - grad w, so each LED's cos of incidence drops by grad w . its direction
    shades = [np.where(view.valid, -np.sum(view.light_tangent * grad[None], -1), 0.0) for _, grad in normal_fields]
    shear = to_px(-np.stack([np.zeros_like(g), g], -1))  # material dragged along +c is seen from -c
    shift = np.stack([shifts[0], shear, shifts[1], shifts[2]]).astype(np.float32)
    shading = np.stack([shades[0], np.zeros_like(shades[0]), shades[1], shades[2]]).astype(np.float32)
    return _Contact(shift, shading)


@dataclasses.dataclass(frozen=True)
class FrameLoads:
    """What the contact does at each frame, in mm: the outer surface's indentation per shell at the
    centre, the skin's drag, the contact's travel along the shell and the cloth's slide across it."""

    indent_mm: np.ndarray
    shear_mm: np.ndarray
    travel_mm: np.ndarray
    slide_mm: np.ndarray

    @staticmethod
    def still(indent_mm, shear_mm=None) -> "FrameLoads":
        """Loads of a contact that neither travels nor slides."""
        indent = np.asarray(indent_mm, np.float64)
        zero = np.zeros_like(indent)
        return FrameLoads(indent, zero if shear_mm is None else np.asarray(shear_mm, np.float64), zero, zero)


def loads_mm(normal_n: np.ndarray, shear_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The outer surface's centre indentation per shell (Hertz: a^2 / R ~ F^(2/3)) and the inner
    wall's shear drag (F_t over the shell's shear stiffness, the share the inner face keeps), mm."""
    _, indent_ref = hertz(cal.GRASP_FORCE_N)
    indent = indent_ref * (np.maximum(normal_n, 0.0) / cal.GRASP_FORCE_N) ** (2 / 3)
    return indent, cal.INNER_SHEAR_SHARE * np.asarray(shear_n) / cal.SHELL_SHEAR_STIFFNESS_N_MM


def frame_loads(motion: Motion, frame_t: np.ndarray, contact: dict) -> FrameLoads:
    """The loads of `contact` at the frame times, from the trial's motion."""
    at = lambda x: np.interp(frame_t, motion.t, x)  # noqa: E731
    indent, shear = loads_mm(at(motion.normal_n), at(motion.shear_n))
    travel = travel_mm(at(motion.finger_mm), contact["patch"].stack_mm)
    return FrameLoads(indent, shear, travel, at(motion.slide_mm))


def _area_down(frames: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(T, C, H, W) -> (T, C, h, w) mean over each output pixel's k x k block (H = k h, W = k w)."""
    k = frames.shape[2] // size[0]
    out = np.zeros((*frames.shape[:2], *size), np.float32)
    for di in range(k):
        for dj in range(k):
            out += frames[..., di::k, dj::k]
    return out / np.float32(k * k)


def _noise_sigma(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Shot noise (DN) of frames of `size` showing `image` (DN), see calibration."""
    dn_per_electron = 255.0 / cal.CAMERA_FULL_WELL_E
    area = np.sqrt(size[0] * size[1] / (FULL_SIZE[0] * FULL_SIZE[1]))
    return np.sqrt(np.maximum(image, 0.0) * np.float32(dn_per_electron)) * np.float32(cal.RESIZE_NOISE_FACTOR * area)


def _scene_view(scene: Scene, big: tuple[int, int]) -> tuple[_View, np.ndarray]:
    """The render grid's view of `scene`'s day and its DN per unit irradiance per colour (3, 1, 1)."""
    day = day_state(scene)
    view = _view(scene.seed, *big, day.seat_axial_mm, day.seat_rotation_rad)
    return view, _exposure(scene.seed) * np.asarray(day.led_gain)[:, None, None]


def resting_wall(view: _View, gain: np.ndarray) -> np.ndarray:
    """(3, H, W) DN of the wall at rest: each colour's irradiance (`_rest`) times the flake albedo and
    the day's DN per unit irradiance (`gain`, `_scene_view`)."""
    return gain * view.albedo[None] * _rest(view)


def no_contact_frame(scene: Scene, size: tuple[int, int] | None = None) -> np.ndarray:
    """Noise-free float32 (h, w, 3) frame in DN of `scene`'s day without contact: what the session's
    averaged reference converges to."""
    size = tuple(size or scene.image_size)
    view, gain = _scene_view(scene, render_size(size))
    rest = np.maximum(resting_wall(view, gain), 0.0)  # as `physical_frames`
    return _area_down(rest[None].astype(np.float32), size)[0].transpose(1, 2, 0)


def physical_frames(scene: Scene, loads: FrameLoads, contact: dict, size: tuple[int, int] | None = None) -> np.ndarray:
    """Noise-free float32 frames (T, h, w, 3) in DN of `scene`'s day at `size` (the scene's by
    default) under `loads`, rendered on `render_size(size)` and area-averaged down. `contact` is the
    trial's patch (`trial_contact`). The contact's fields are computed at centres `TRAVEL_STEP_MM`
    apart over the trial's travel and interpolated linearly between them (a trial that does not
    travel has one centre, and nothing to interpolate)."""
    size = tuple(size or scene.image_size)
    big = render_size(size)
    view, gain = _scene_view(scene, big)
    albedo = np.where(view.valid, view.albedo, 0.0)
    texture = np.concatenate([resting_wall(view, gain).transpose(1, 2, 0), albedo[..., None]], -1)
    texture = texture.astype(np.float32)  # (H, W, 4): the resting wall's DN per colour, and its albedo
    step = cal.TRAVEL_STEP_MM
    lo, hi = np.floor(loads.travel_mm.min() / step), np.ceil(loads.travel_mm.max() / step)
    offsets = np.arange(lo, hi + 1) * step
    fields = [_contact(view, contact, contact["centre_c"] + o) for o in offsets]
    loads_per_field = len(fields[0].shift)
    # per centre (K) and unit load (B), flat: the pixels' shift (H W 2) and the shading in DN (3 H W)
    shift = np.stack([f.shift.reshape(loads_per_field, -1) for f in fields])
    shading = np.stack([(f.shading * gain[None].astype(np.float32)).reshape(loads_per_field, -1) for f in fields])
    amplitude, wavelength = contact["texture_amplitude"], contact["texture_wavelength"]
    phase = 2 * np.pi * loads.slide_mm / wavelength
    coef = np.stack([loads.indent_mm, loads.shear_mm, amplitude * np.cos(phase), amplitude * np.sin(phase)], -1).astype(
        np.float32
    )  # (T, B)
    travels = len(offsets) > 1
    position = np.clip((loads.travel_mm - offsets[0]) / step, 0, len(offsets) - 1)
    below = np.minimum(position.astype(np.int64), max(len(offsets) - 2, 0))  # the centre at or below each frame's
    frac = (position - below).astype(np.float32)[:, None]  # and how far on towards the next
    y, x = np.mgrid[0 : big[0], 0 : big[1]].astype(np.float32)
    xy = np.stack([x, y], -1)  # (H, W, 2): each pixel's own place in the resting wall's image
    frames = np.empty((len(coef), *size, 3), np.float32)
    move, move_next = np.empty((2, CHUNK, shift.shape[-1]), np.float32)
    tilt, tilt_next = np.empty((2, CHUNK, shading.shape[-1]), np.float32)
    seen = np.empty((CHUNK, 3, *big), np.float32)
    for start in range(0, len(coef), CHUNK):
        n = min(CHUNK, len(coef) - start)
        for k in range(n):  # frame by frame: a product over many frames at once may sum in another order
            i, load = below[start + k], coef[start + k]
            np.dot(load, shift[i], out=move[k])
            np.dot(load, shading[i], out=tilt[k])
            if travels:
                np.dot(load, shift[i + 1], out=move_next[k])
                np.dot(load, shading[i + 1], out=tilt_next[k])
        if travels:
            for at, at_next in ((move[:n], move_next[:n]), (tilt[:n], tilt_next[:n])):
                at_next -= at
                at_next *= frac[start : start + n]
                at += at_next
        # where each pixel sees the resting wall, the chunk's frames stacked as one tall image (each
        # pixel is sampled on its own), split into planes as the shading is laid out: r, g, b, albedo
        where = (move[:n].reshape(n, *big, 2) + xy).reshape(n * big[0], big[1], 2)
        wall = cv2.split(cv2.remap(texture, where, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE))
        shade = tilt[:n].reshape(n, 3, *big)
        for colour in range(3):
            np.multiply(wall[3].reshape(n, *big), shade[:, colour], out=seen[:n, colour])
            seen[:n, colour] += wall[colour].reshape(n, *big)
        np.maximum(seen[:n], 0.0, out=seen[:n])
        frames[start : start + n] = _area_down(seen[:n], size).transpose(0, 2, 3, 1)
    return frames


def trial_contact(scene: Scene, nz: Nuisance, rng: np.random.Generator) -> dict:
    """The trial's patch on the wall: centre (s, c mm), its geometry, fold direction and ridge, and the
    cloth's texture (the trial's draws)."""
    patch = patch_geometry(scene.fabric, nz.fold)
    fold_angle = np.pi / 2 + rng.normal(0.0, cal.FOLD_ANGLE_SPREAD_RAD)  # the fold runs roughly along the finger
    a, _ = hertz(cal.GRASP_FORCE_N)
    radii, profile, _ = inner_profile(round(a * patch.along, 2))  # [numerics] as `_contact`
    half = float(np.interp(0.5, profile[::-1], radii[::-1]))  # half-displacement radius
    ridge_offset = rng.uniform(-1.0, 1.0) * half * patch.across / patch.along
    # a thicker stack stops the closing fingers earlier, so the contact lands further towards the tip
    axial = cal.CONTACT_AXIAL_MM + cal.CONTACT_SHIFT_PER_STACK_MM * patch.stack_mm
    centre = np.array([CAP_ARC_MM + cal.SHELL_CYLINDER_MM - axial, 0.0]) + nz.contact_offset_mm
    width = max(patch.stack_mm, cal.FLAKE_SIZE_MM) if scene.fabric.is_fabric else 1.0
    amplitude, wavelength = texture_relief(scene.fabric)
    return dict(
        patch=patch,
        centre_s=float(centre[0]),
        centre_c=float(centre[1]),
        fold_angle=float(fold_angle),
        ridge_offset=float(ridge_offset),
        ridge_width=float(width),
        texture_amplitude=amplitude,
        texture_wavelength=wavelength,
    )


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
    """uint8 (R, H, W, 3): the `archive.REFERENCE_FRAMES` no-contact frames `scene`'s session takes
    as its reference (each with its own noise; the features average them)."""
    clean = np.broadcast_to(no_contact_frame(scene), (archive.REFERENCE_FRAMES, *scene.image_size, 3))
    return quantise(np.ascontiguousarray(clean), scene.image_size, scene.rng("minsight_reference", "day"))


def stroke_frames(
    scene: Scene,
    motion: Motion,
    frame_t: np.ndarray,
    nz: Nuisance,
    rng: np.random.Generator,
    size: tuple[int, int] | None = None,
) -> np.ndarray:
    """Noise-free float32 frames (T, h, w, 3) in DN of the trial at the frame times (its patch drawn
    from `rng`, as `render` draws it)."""
    contact = trial_contact(scene, nz, rng)
    return physical_frames(scene, frame_loads(motion, frame_t, contact), contact, size)


def render(scene: Scene, motion: Motion, frame_t: np.ndarray, nz: Nuisance, rng: np.random.Generator) -> np.ndarray:
    """uint8 frames (T, H, W, 3) at the frame times."""
    return quantise(stroke_frames(scene, motion, frame_t, nz, rng), scene.image_size, rng)
