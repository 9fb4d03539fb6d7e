"""The flow-budget study: its conditions switch the loads they name, its statistics measure known
motions, and a tiny run writes the numbers it computed."""

import json

import numpy as np
import pytest

from fabricjax.errors import UserError
from fabricjax.sim import minsight
from fabricjax.store.workspace import Location
from fabricjax.studies.diagnostics import flow_budget as fb
from fabricjax.studies.release import reproduce_plan


def _loads(n=6):
    t = np.arange(n, dtype=np.float64)
    return minsight.FrameLoads(0.2 + 0.01 * t, 0.05 * t, 0.3 * t, 0.7 * t)


def test_each_condition_moves_only_its_own_load_and_holds_the_rest():
    loads, rubbing = _loads(), np.array([False, False, True, True, True, True])
    held = np.mean(loads.indent_mm[2:])
    c = fb.effect_loads(loads, rubbing)
    assert list(c) == list(fb.CONDITIONS) and c["all"] is loads
    moving = {"indentation": "indent_mm", "shear": "shear_mm", "travel": "travel_mm", "texture": "slide_mm"}
    for name, cond in c.items():
        for field in ("indent_mm", "shear_mm", "travel_mm", "slide_mm"):
            got = getattr(cond, field)
            if name == "all" or moving.get(name) == field:
                np.testing.assert_array_equal(got, getattr(loads, field))
            elif field == "indent_mm":
                np.testing.assert_allclose(got, held)  # the patch stays, at its mean depth over the rubbing
            else:
                np.testing.assert_array_equal(got, 0.0)


def _pattern(h=40, w=48, seed=0):
    """A smooth random texture Farneback can track (uint8, RGB)."""
    rng = np.random.default_rng(seed)
    big = rng.standard_normal((h + 16, w + 16))
    kernel = np.outer(*(2 * [np.hanning(7) / np.hanning(7).sum()]))
    from scipy.signal import convolve2d

    smooth = convolve2d(big, kernel, mode="same")
    return np.clip(128 + 60 * smooth / smooth.std(), 0, 255)


def test_flow_stats_measure_a_known_shift_and_a_still_scene():
    base = _pattern()
    frames = np.stack([base[8:48, 8 - k : 56 - k] for k in range(4)]).astype(np.uint8)  # 1 px right per frame
    frames = np.repeat(frames[..., None], 3, -1)
    circle = np.ones(frames.shape[1:3], bool)
    moving = fb.flow_stats(frames, circle, "opencv")
    assert moving["mean_px"] == pytest.approx(1.0, abs=0.15) and moving["kept_px"] == pytest.approx(1.0, abs=0.3)
    still = fb.flow_stats(np.repeat(frames[:1], 4, 0), circle, "opencv")
    # identical frames: Farneback's own floor, far below the shift
    assert still["mean_px"] < 0.01 and still["kept_px"] < 0.1 * moving["kept_px"]
    assert fb.kept_count((60, 80)) == 5 and fb.kept_count((308, 410)) == 127  # as flow.py's filter keeps


def test_the_wall_moves_by_each_loads_change_between_rubbing_frames():
    loads, rubbing = _loads(), np.array([False, True, True, True, True, True])
    contact = {
        "patch": minsight.Patch(1.0, 1.0, 1.0, 0.0, 0.0),
        "texture_amplitude": 0.01,
        "texture_wavelength": 1.4,  # the slide advances half a wavelength per frame: the ripple flips sign
    }
    moved = fb.wall_motion(loads, contact, rubbing)
    a, _ = minsight.hertz(0.1)
    share = minsight.inner_profile(round(a, 2))[2]
    assert len(moved["shear"]) == 4  # the pairs of rubbing frames
    np.testing.assert_allclose(moved["shear"], 0.05) and np.testing.assert_allclose(moved["travel"], 0.3)
    np.testing.assert_allclose(moved["indentation"], share * 0.01)
    np.testing.assert_allclose(moved["texture"], 0.02, atol=1e-12)


def test_the_fabric_share_is_eta_squared_beside_chance():
    e = fb.eta_squared([[1.0, 1.0], [3.0, 3.0]])
    assert e == {"share": 1.0, "chance": pytest.approx(1 / 3)}
    e = fb.eta_squared([[0.0, 2.0], [0.0, 2.0]])
    assert e["share"] == 0.0
    e = fb.eta_squared([[0.0, 2.0], [2.0, 4.0]])  # between 2 x (1 - 2)^2 + 2 x (3 - 2)^2 = 4 of total 8
    assert e["share"] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="more values than groups"):
        fb.eta_squared([[1.0], [2.0]])


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("flow_budget")
    doc = fb.run(
        fabrics=(0, 10),
        trials=((1, 0), (2, 0)),
        cycles=2,
        size=(30, 40),
        paper_size=(60, 80),
        paper_frames=6,
        where=Location(results=out),
    )
    return out, doc


def test_a_tiny_run_measures_every_condition_and_writes_what_it_measured(tiny):
    out, doc = tiny
    saved = json.loads((out / "flow_budget.json").read_text())
    md = (out / "flow_budget.md").read_text()
    assert saved["headline"] == doc["headline"] and saved["fingerprints"]["simulator"]
    assert set(doc["trials_measured"]) == {"0", "10"} and all(len(v) == 2 for v in doc["trials_measured"].values())
    for rs in doc["trials_measured"].values():
        for r in rs:
            assert set(r["flow"]) == set(fb.CONDITIONS)
            flow = r["flow"]
            # noise-free, the moving contact shows more flow than the still one, and the drag moves the wall
            assert flow["all"]["noise-free"]["kept_px"] > flow["still"]["noise-free"]["kept_px"]
            assert r["wall"]["shear"]["max_mm"] > 0 and r["wall"]["travel"]["max_mm"] > 0
            # shot noise adds flow of its own
            assert flow["still"]["shot noise"]["mean_px"] > flow["still"]["noise-free"]["mean_px"]
    h = doc["headline"]
    assert h["signal_over_noise"] == pytest.approx(
        np.mean([fb.signal_over_noise(r) for rs in doc["trials_measured"].values() for r in rs])
    )
    assert h["fabric_share_chance"] == pytest.approx(1 / 3)
    assert h["paper_size_signal_over_noise"] == pytest.approx(
        np.mean([fb.signal_over_noise(r) for r in doc["at_paper_size"]["trials"].values()])
    )
    assert f"**{h['signal_over_noise']:.2f} times**" in md and f"**{h['paper_size_signal_over_noise']:.2f}**" in md
    assert fb.gap_sentence(doc) in md and "## Against Minsight's published figures" in md
    assert "| 10 polar fleece |" in md and "| still |" in md


def test_the_published_figures_are_compared_with_the_simulated_range(tiny):
    _, doc = tiny
    rows = {c["quantity"]: c for c in doc["published"]}
    drag = rows["the inner wall's drag between two frames, p95 (mm)"]
    measured = [np.mean([r["wall"]["shear"]["p95_mm"] for r in rs]) for rs in doc["trials_measured"].values()]
    assert drag["simulated"] == pytest.approx([min(measured), max(measured)]) and drag["published"] == 0.4
    assert "Nature Machine Intelligence 4 (2022)" in drag["source"]
    assert rows["frames per rubbing cycle"]["published"] == pytest.approx(25.0)
    shear = rows["the tangential load's swing over the rubbing (N)"]
    sentence = fb.published_sentence(doc)
    assert f"swings by {shear['simulated'][0] / 0.03:.0f}-{shear['simulated'][1] / 0.03:.0f} times" in sentence


def test_it_has_no_rows_and_reads_no_data(tmp_path):
    with pytest.raises(UserError, match="no rows"):
        fb.run(rows=["x"], where=Location(results=tmp_path))
    with pytest.raises(UserError, match="--data_dir has no say"):
        fb.run(where=Location(results=tmp_path, data_dir=tmp_path))


def test_reproduce_runs_it_before_the_camera_frames_without_seeds_and_names_its_command():
    plan = [s.study for s in reproduce_plan.PLAN]
    assert plan.index("flow_budget") == plan.index("camera_frames") - 1
    assert "flow_budget" in reproduce_plan.UNSEEDED and "flow_budget" in reproduce_plan.SIMULATOR_ONLY
    assert reproduce_plan.STUDIES["flow_budget"] is fb
    assert (
        reproduce_plan.command(reproduce_plan.Step("flow_budget"), "default", {}, "results")
        == "python -m experiments.flow_budget --preset=default --results=results"
    )
