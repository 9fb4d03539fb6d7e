"""Minsight images: one millimetre scene at every size, the camera's day, the published force accuracy."""

import dataclasses

import cv2
import numpy as np
import pytest

from fabricjax import catalog
from fabricjax.sim import Scene, minsight
from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import nuisance
from fabricjax.store import archive

IMAGES = ("audio", "proprio", "images")


def scene(**kw) -> Scene:
    return Scene(kw.pop("fabric_id", 1), streams=IMAGES, **kw)


def contact_frames(sc: Scene, forces_n, size):
    """Noise-free frames of `sc`'s trial patch at the given normal forces (no shear)."""
    contact = minsight.trial_contact(sc, nuisance(sc), np.random.default_rng(0))
    indent, shear = minsight.loads_mm(np.asarray(forces_n, float), np.zeros(len(forces_n)))
    return minsight.physical_frames(sc, minsight.FrameLoads.still(indent, shear), contact, size=size)


def test_the_camera_day_is_deterministic_per_seed_and_day_and_moves_between_days():
    a, b = minsight.day_state(scene(day=1)), minsight.day_state(scene(day=1, trial=3, fabric_id=7))
    assert a == b  # one camera per day, whatever the trial
    days = [minsight.day_state(scene(day=d)) for d in range(1, 41)]
    assert len({d.led_gain for d in days}) == 40
    assert len({(d.seat_axial_mm, d.seat_rotation_rad) for d in days}) == 1  # over-moulded: never reseated
    red = np.array([d.led_gain[0] for d in days])
    assert 0.002 < red.std() < 0.05  # one port's supply, ~1 %/K of the red LED
    assert minsight.day_state(scene(day=1, seed=1)) != a
    ref1, ref1_again, ref2 = (minsight.reference(scene(day=d, image_size=(60, 80))) for d in (1, 1, 2))
    assert ref1.shape == (archive.REFERENCE_FRAMES, 60, 80, 3) and np.array_equal(ref1, ref1_again)
    noise = float(np.median(minsight._noise_sigma(ref1[0].astype(np.float32), (60, 80))))
    assert np.abs(ref1.mean(0) - ref2.mean(0)).mean() > noise  # a new day: another reference, not just noise


def test_the_averaged_reference_s_noise_falls_as_one_over_the_root_of_its_frames():
    sc = scene(day=3, image_size=(60, 80))
    frames, clean = minsight.reference(sc).astype(np.float64), minsight.no_contact_frame(sc)
    lit = (clean > 20) & (clean < 235)  # away from the dark rim and saturation
    spread = [float(np.std((frames[:n].mean(0) - clean)[lit])) for n in (1, 4, 16)]
    sigma = float(np.median(minsight._noise_sigma(clean, (60, 80))[lit]))
    assert spread[0] == pytest.approx(np.hypot(sigma, 1 / np.sqrt(12)), rel=0.25)  # one frame: noise and rounding
    assert spread[1] / spread[0] == pytest.approx(0.5, rel=0.2) and spread[2] / spread[1] == pytest.approx(0.5, rel=0.2)


def test_two_days_frames_differ_beyond_the_noise_at_the_same_contact():
    f1, f2 = (contact_frames(scene(day=d), [0.1], (60, 80))[0] for d in (1, 2))
    noise = float(np.median(minsight._noise_sigma(f1, (60, 80))))
    assert np.abs(f1 - f2).mean() > noise


def test_a_smaller_frame_is_the_full_resolution_render_area_averaged():
    """154x205 frames are rendered on the full 308x410 grid and averaged 2x2: the same physical
    image; 60x80 frames come from a 2x render of the same millimetre scene, close to the full
    render area-averaged (differences at the image circle's rim, where the grids sample it apart,
    and in the grain's motion under the contact)."""
    sc = scene(image_size=archive.MINSIGHT_SIZE)
    forces = [0.0, 0.1, 0.14]
    full = contact_frames(sc, forces, archive.MINSIGHT_SIZE)
    half = contact_frames(sc, forces, (154, 205))
    assert np.allclose(half, full.reshape(3, 154, 2, 205, 2, 3).mean(axis=(2, 4)), rtol=1e-5, atol=1e-4)
    small = contact_frames(sc, forces, (60, 80))
    down = np.stack([cv2.resize(f, (80, 60), interpolation=cv2.INTER_AREA) for f in full])
    assert np.abs(small - down).mean() < 0.05 * down.mean()
    # the contact's change: the same pattern and size (the grain finer than a render pixel moves differently)
    change_small, change_down = (small[2] - small[0]).ravel(), (down[2] - down[0]).ravel()
    assert np.corrcoef(change_small, change_down)[0, 1] > 0.8
    assert np.abs(change_small).sum() == pytest.approx(np.abs(change_down).sum(), rel=0.2)


def snr(sc: Scene, step_n: float, size) -> float:
    """Ideal-observer SNR of a normal-force step from 0.1 N on one frame: the image change over the
    camera's shot noise, summed over pixels (matched filter)."""
    frames = contact_frames(sc, [cal.GRASP_FORCE_N, cal.GRASP_FORCE_N + step_n], size)
    sigma = minsight._noise_sigma(frames[0], size)
    return float(np.sqrt(np.sum(((frames[1] - frames[0]) / np.maximum(sigma, 1e-3)) ** 2)))


def test_a_force_step_at_the_published_accuracy_is_above_the_camera_noise():
    """[minsight, insight] Force accuracy ~0.03 N (Insight) to 0.07 N (Minsight): a 0.03 N step at the
    grasp's 0.1 N changes one frame well above the shot noise at 308x410 and still above it at the
    paper's 60x80 (Andrussow et al.: 60x80 suffices for precise forces); a step a hundred times
    smaller is below the noise at 60x80, a thousand times smaller at 308x410."""
    sc = scene(image_size=archive.MINSIGHT_SIZE)
    assert snr(sc, cal.FORCE_ACCURACY_N, archive.MINSIGHT_SIZE) > 20
    assert snr(sc, cal.FORCE_ACCURACY_N, (60, 80)) > 3
    assert snr(sc, cal.FORCE_ACCURACY_N / 1000, archive.MINSIGHT_SIZE) < 1
    assert snr(sc, cal.FORCE_ACCURACY_N / 100, (60, 80)) < 1


def test_indentation_follows_hertz_and_the_layer_passes_the_incompressible_half_space_s_share():
    """[phys] Hertz between two equal shells: a = (3 F R_eff / 4 E*)^(1/3) ~ 1.8 mm at 0.1 N, a^2 / R
    per shell ~0.27 mm, growing as F^(2/3). The share the 1.55 mm layer passes to the inner wall's
    centre is the Boussinesq point-load solution for nu = 0.5, u_z = P (2 (1 - nu) / R + z^2 / R^3) /
    (4 pi G), integrated over the Hertz pressure at depth d against at the surface: ~0.62."""
    a, indent = minsight.hertz(0.1)
    assert a == pytest.approx(1.78, abs=0.02) and indent == pytest.approx(0.27, abs=0.02)
    radii, profile, share = minsight.inner_profile(a)
    assert profile[0] == 1.0 and profile[-1] == 0.0 and np.all(np.diff(profile[radii < 6]) <= 1e-9)
    r = np.linspace(0.0, a, 200001)[1:]
    load = np.sqrt(1 - (r / a) ** 2) * 2 * np.pi * r  # Hertz pressure on rings (shape only)
    d = cal.SHELL_THICKNESS_MM

    def uz(z):
        big = np.hypot(r, z)
        return np.trapezoid(load * (1.0 / big + z**2 / big**3), r)  # 2 (1 - nu) = 1

    half_space = uz(d) / uz(0.0)
    assert 0.85 * half_space < share < half_space  # the skeleton's hold at 11.8 mm cuts the tail: ~10 % less
    assert share == pytest.approx(0.62, abs=0.03) and share > np.exp(-2 * np.pi * d / (4 * a)) * 1.5
    low, high = minsight.loads_mm(np.array([0.05, 0.1]), np.zeros(2))[0]
    assert high / low == pytest.approx(2 ** (2 / 3), rel=1e-6)


def test_the_contact_rolls_along_the_shell_as_two_spheres_touch_on_their_line_of_centres():
    """The tips offset by +-x over a stack t: the contact is where the line between the centres
    crosses each shell, found here by sampling the shell for the point nearest the other centre."""
    r = cal.SHELL_OUTER_RADIUS_MM
    angles = np.linspace(-0.6, 0.6, 600001)
    for x, t in ((3.0, 0.3), (-2.0, 5.0), (0.5, 2.0)):
        other = np.array([2 * x, 2 * r + t])  # the other shell's centre, from this one's
        points = r * np.stack([np.sin(angles), np.cos(angles)], -1)
        nearest = angles[np.argmin(np.hypot(*(points - other).T))]
        assert minsight.travel_mm(x, t) == pytest.approx(r * nearest, abs=1e-3)
    assert minsight.travel_mm(3.0, 0.3) == pytest.approx(3.0 * 2 * r / (2 * r + 0.3), rel=0.03)  # +-3 mm for silk


def test_a_compressible_stack_spreads_the_patch_as_an_elastic_foundation():
    """a = sqrt(2 R_eff (d_shell + d_stack)) with d_stack the stack's give at 0.1 N, at two thicknesses;
    at the same force the centre is shallower as 1 / a."""
    a0, d_shell = minsight.hertz(cal.GRASP_FORCE_N)
    fleece = catalog.fabric(10)
    for thickness in (0.5, 2.5):
        fabric = dataclasses.replace(fleece, thickness_mm=thickness)
        patch = minsight.patch_geometry(fabric, 1.0)
        d_stack = fabric.compressibility * 2 * thickness
        expected = np.sqrt(2 * (cal.SHELL_OUTER_RADIUS_MM / 2) * (d_shell + d_stack))
        assert a0 * patch.along == pytest.approx(expected, rel=1e-6)
        assert patch.depth == pytest.approx(a0 / expected, rel=1e-6)
    silk = minsight.patch_geometry(catalog.fabric(12), 1.0)
    assert a0 * silk.along == pytest.approx(1.8, abs=0.1)
    assert 5.0 < a0 * minsight.patch_geometry(fleece, 1.0).along < 7.0


def test_contact_changes_a_local_patch_and_shear_moves_it_above_the_noise():
    sc = scene(image_size=(60, 80))
    frames = contact_frames(sc, [0.0, 0.1], (60, 80))
    change = np.abs(frames[1] - frames[0]).sum(-1)
    assert np.median(change) < 0.01 * change.max()  # a local patch, not a global change
    contact = minsight.trial_contact(sc, nuisance(sc), np.random.default_rng(0))
    indent, _ = minsight.loads_mm(np.array([0.1, 0.1]), np.zeros(2))
    sheared = minsight.physical_frames(sc, minsight.FrameLoads.still(indent, np.array([0.0, 0.05])), contact)
    noise = minsight._noise_sigma(sheared[0], (60, 80))
    assert np.sqrt(np.sum(((sheared[1] - sheared[0]) / np.maximum(noise, 1e-3)) ** 2)) > 3  # ideal observer
