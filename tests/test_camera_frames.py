"""The camera-frames study: which frame it picks, that its numbers are the panels' own, and a run."""

import json
import types

import numpy as np
import pytest

from fabricjax.errors import UserError
from fabricjax.sim import trial
from fabricjax.store.workspace import Location
from fabricjax.studies.diagnostics import camera_frames as cf
from fabricjax.studies.release import reproduce_plan


def strokes(cycles=3, start=0.5, hz=1.0, amplitude=3.0):
    """A motion of `cycles` sine strokes of the thumb from `start` (s), at rest before and after."""
    t = np.arange(0, start + cycles / hz + 1.0, 0.001)
    on = (t >= start) & (t <= start + cycles / hz)
    x = np.where(on, amplitude * np.sin(2 * np.pi * hz * (t - start)), 0.0)
    return types.SimpleNamespace(t=t, finger_mm=x, rubbing_start_s=start)


FRAMES = 0.01 + 0.02 * np.arange(250)  # 50 Hz, off the control grid by 10 ms


@pytest.mark.parametrize("cycle,expected_t", [(1, 0.75), (2, 1.75), (3, 2.75)])
def test_the_moment_is_the_thumbs_furthest_excursion_within_the_chosen_cycle(cycle, expected_t):
    k = cf.moment(strokes(), FRAMES, cycle)
    assert FRAMES[k] == pytest.approx(expected_t)


def test_a_growing_stroke_peaks_where_its_own_cycle_does_not_at_the_next():
    m = strokes()
    m.finger_mm = m.finger_mm * np.clip(m.t - 0.5, 0, None)  # amplitude grows: later peaks are higher
    k = cf.moment(m, FRAMES, 2)
    assert 1.5 <= FRAMES[k] < 2.5  # within cycle 2, though cycle 3 rises higher
    inside = (FRAMES >= 1.5) & (FRAMES < 2.5)
    assert np.interp(FRAMES[k], m.t, m.finger_mm) == pytest.approx(np.interp(FRAMES[inside], m.t, m.finger_mm).max())


def test_a_cycle_the_trial_lacks_or_no_frame_sees_is_an_error():
    with pytest.raises(ValueError, match="cycle 4 is not in this trial: it rubs 3 whole cycles"):
        cf.moment(strokes(), FRAMES, 4)
    with pytest.raises(ValueError, match="no camera frame"):
        cf.moment(strokes(), np.array([0.1, 3.9]), 2)


def test_the_moment_of_a_simulated_trial_lies_in_its_second_cycle_at_the_thumbs_far_side():
    proc = trial.procedure(cf._scene("default", 1, 1))
    m, t = proc.motion, proc.frame_times
    k = cf.moment(m, t)
    x = np.interp(t, m.t, m.finger_mm)
    assert t[k] > m.rubbing_start_s and x[k] > 0
    # the first cycle's out-and-back lies before it: one earlier upward zero crossing after rubbing starts
    before = x[(t > m.rubbing_start_s) & (t < t[k])]
    assert np.sum((before[:-1] < 0) & (before[1:] >= 0)) == 1


def test_fabric_and_day_differences_are_pooled_over_pairs():
    fabrics = [np.full((2, 3), v) for v in (0.0, 1.0, 2.0, 3.0)]  # pair differences 1, 2, 3, 1, 2, 1
    days = [np.full((2, 3), v) for v in (0.0, 0.5, 1.0)]  # 0.5, 1, 0.5
    c = cf.compare(fabrics, days)
    assert c["fabric_rms_dn"] == pytest.approx(np.sqrt(20 / 6)) and c["fabric_pairs"] == 6
    assert c["day_rms_dn"] == pytest.approx(np.sqrt(1.5 / 3)) and c["day_pairs"] == 3
    assert c["larger"] == "fabric" and c["fabric_over_day"] == pytest.approx(np.sqrt(20 / 6) / np.sqrt(0.5))
    assert cf.compare(days, fabrics)["larger"] == "day"
    assert cf.compare(days, days)["larger"] == "neither"
    with pytest.raises(ValueError, match="at least two"):
        cf.pair_rms(days[:1])


def test_a_panel_shows_the_mean_of_the_channels():
    d = np.zeros((2, 2, 3), np.float32)
    d[0, 0] = (3.0, -6.0, 0.0)
    assert cf.shown(d)[0, 0] == pytest.approx(-1.0) and cf.panel_numbers(cf.shown(d))["max_abs_dn"] == 1.0


def test_the_page_prints_the_numbers_of_the_panels_it_drew(tmp_path, monkeypatch):
    """Panels of known values in place of the renderer: fabric f on day d differs from its
    reference by f + d / 10 everywhere."""

    def fake(scene, sizes):
        when = {"frame": 7, "t_s": 0.14, "finger_mm": 3.0, "normal_n": 0.1, "shear_n": 0.05}
        value = scene.fabric_id + scene.day / 10
        refs = {s: np.full((*s, 3), 100.0, np.float32) for s in sizes}
        refs[sizes[0]][0, :2, 1] = -5.0  # two pixels below 0 DN, which light cannot
        return when, {s: np.full((*s, 3), value, np.float32) for s in sizes}, refs

    monkeypatch.setattr(cf, "render", fake)
    doc = cf.run(sizes=((12, 16),), where=Location(results=tmp_path))
    # fabrics 12, 1, 10, 9 on day 1: 12.1, 1.1, 10.1, 9.1; denim's days: 1.1, 1.2, 1.3
    fabric = np.sqrt((11**2 + 2**2 + 3**2 + 9**2 + 8**2 + 1**2) / 6)
    day = np.sqrt((0.1**2 + 0.2**2 + 0.1**2) / 3)
    md = (tmp_path / "camera_frames.md").read_text()
    assert (
        f"| 12x16 | {fabric:.2f} (6 pairs) | {day:.2f} (3 pairs) | the fabrics differ more than denim's days "
        f"({fabric / day:.2f} times) |" in md
    )
    assert "| fabrics | 12x16 | 10 polar fleece | 1 | 7 | 0.140 | 3.00 | 0.100 | +0.050 | 10.10 | 10.10 |" in md
    assert "| days | 12x16 | 1 cotton denim | 3 | " in md and "![" in md and "(camera_frames.png)" in md
    assert "isolated dots: 2 pixels at 12x16 (least -5.0 DN)" in md
    assert doc["figures"] == ["camera_frames.png"] and (tmp_path / "camera_frames.png").stat().st_size > 0
    saved = json.loads((tmp_path / "camera_frames.json").read_text())
    assert saved["comparison"]["12x16"]["fabric_rms_dn"] == pytest.approx(fabric)
    assert saved["colour_limit_dn"] == pytest.approx(12.1)
    assert saved["fingerprints"]["code"] and saved["fingerprints"]["simulator"]


def test_a_run_renders_every_panel_at_small_sizes(tmp_path):
    doc = cf.run(sizes=((12, 16), (24, 32)), where=Location(results=tmp_path))
    panels = doc["panels"]
    assert len(panels) == 2 * (len(cf.FABRICS) + len(cf.DAYS))
    assert all(p["max_abs_dn"] > 0 for p in panels)  # the contact shows in every panel
    by = {(p["block"], p["fabric"], p["day"], tuple(p["size"])): p for p in panels}
    for size in ((12, 16), (24, 32)):  # denim's day 1 is one panel, shown in both blocks
        assert by[("fabric", 1, 1, size)] == {**by[("day", 1, 1, size)], "block": "fabric"}
    assert set(doc["comparison"]) == {"12x16", "24x32"}
    assert all(c["fabric_rms_dn"] > 0 and c["day_rms_dn"] > 0 for c in doc["comparison"].values())


def test_it_has_no_rows_and_reads_no_data(tmp_path):
    with pytest.raises(UserError, match="no rows"):
        cf.run(rows=["x"], where=Location(results=tmp_path))
    with pytest.raises(UserError, match="--data_dir has no say"):
        cf.run(where=Location(results=tmp_path, data_dir=tmp_path))


def test_reproduce_runs_it_last_without_seeds_and_names_its_command():
    assert (
        reproduce_plan.PLAN[-1] == reproduce_plan.Step("camera_frames") and "camera_frames" in reproduce_plan.UNSEEDED
    )
    assert reproduce_plan.STUDIES["camera_frames"] is cf
    assert (
        reproduce_plan.command(reproduce_plan.Step("camera_frames"), "default", {}, "results")
        == "python -m experiments.camera_frames --preset=default --results=results"
    )


def test_smoothing_removes_pixel_speckle_and_keeps_a_broad_patch_at_any_size():
    for h, w in ((60, 80), (308, 410)):
        y, x = np.mgrid[0:h, 0:w]
        speckle = np.where((x + y) % 2, 1.0, -1.0)
        patch = np.exp(-(((x - w / 2) / (w / 8)) ** 2 + ((y - h / 2) / (h / 8)) ** 2))
        rms = lambda a: np.sqrt(np.mean(a**2))  # noqa: E731
        assert rms(cf.smoothed(speckle)[h // 4 : -h // 4, w // 4 : -w // 4]) < 0.01  # away from the frame's edge
        assert rms(cf.smoothed(patch) - patch) < 0.1 * rms(patch)
    # the same extent on the wall: a 5.13 times larger frame is smoothed over 5.13 times more pixels
    one = np.zeros((60, 80))
    one[30, 40] = 1.0
    big = np.zeros((308, 410))
    big[154, 205] = 1.0
    spread = lambda a: np.sqrt(np.sum(a * (np.arange(a.shape[1]) - a.shape[1] // 2) ** 2) / a.sum())  # noqa: E731
    assert spread(cf.smoothed(big)) / spread(cf.smoothed(one)) == pytest.approx(410 / 80, rel=0.02)


def test_concentration_counts_the_fewest_pixels_that_hold_half_of_the_difference():
    filled = np.ones((2, 5), bool)
    a, b = np.zeros((2, 5)), np.zeros((2, 5))
    b[0, 0] = 3.0  # one pixel holds all of it
    assert cf.concentration([a, b], filled) == pytest.approx(0.1)
    assert cf.concentration([a, a + 1.0], filled) == pytest.approx(0.5)  # every pixel alike: half of them
    b[:] = 1.0
    b[0, 0] = 2.0  # 4 + 9 x 1 = 13: the large pixel and three more reach half
    assert cf.concentration([a, b], filled) == pytest.approx(0.4)
    filled[1] = False  # only the pixels the shell fills count: 4 + 4 x 1 = 8, the large pixel holds half
    assert cf.concentration([a, b], filled) == pytest.approx(0.2)
    assert np.isnan(cf.concentration([a, a], filled))


def test_the_page_carries_the_sentence_it_shares_with_day_shift_and_its_own_number(tmp_path, monkeypatch):
    def fake(scene, sizes):
        when = {"frame": 7, "t_s": 0.14, "finger_mm": 3.0, "normal_n": 0.1, "shear_n": 0.05}
        diffs = {}
        for s in sizes:
            d = np.zeros((*s, 3), np.float32)
            d[: s[0] // 10, :, :] = scene.fabric_id + scene.day / 10  # the contact: a tenth of the rows
            diffs[s] = d
        return when, diffs, {s: np.full((*s, 3), 100.0, np.float32) for s in sizes}

    monkeypatch.setattr(cf, "render", fake)
    cf.run(sizes=((30, 40), (60, 80)), where=Location(results=tmp_path))
    md = (tmp_path / "camera_frames.md").read_text()
    assert cf.camera_variation.RECONCILE in md
    # the default preset's model reads 30x40: the fabrics differ on its first 3 of 30 rows, alike on each
    assert "Here, at 30x40, half of the fabrics' squared difference lies on 5.0 % of the pixels the shell fills." in md
    assert "| 60x80 | " in md and " | 5.0 |" in md
