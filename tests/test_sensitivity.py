"""The simulator's unknowns: declared calibrations fitted to one measurement each, and the Morris
screening of the estimates (fast paths with a stand-in measurement; the real smoke-preset run)."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from fabricjax.errors import UserError
from fabricjax.sim import estimates
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents
from fabricjax.studies.diagnostics import calibrate, sensitivity

RESULTS = Path(__file__).resolve().parents[1] / "results"
TL = estimates.ESTIMATES["SHELL_TL_MAX_DB"]


def _with_target(target: float) -> estimates.Estimate:
    return dataclasses.replace(TL, calibrated=dataclasses.replace(TL.calibrated, paper_value=target))


def _linear_drop(point):
    """A stand-in for the trained row: the drop falls linearly with the cap in force."""
    drop = 30.0 - 0.7 * estimates.value("SHELL_TL_MAX_DB")
    return {"test": [90.0], "cafe": [90.0 - drop], "number": drop, "train_s": 0.0}


def test_the_fit_brackets_the_measurement_and_stops_within_tolerance(tmp_path, monkeypatch):
    monkeypatch.setitem(calibrate.MEASURE, "SHELL_TL_MAX_DB", _linear_drop)
    fit = calibrate.fit(_with_target(15.0), tmp_path, log=lambda s: None)
    assert fit["bracketed"]
    assert abs(fit["fitted_number"] - 15.0) <= calibrate.TOLERANCE_PP
    assert fit["fitted_value"] in [p["value"] for p in fit["points"]]  # a measured point, never an interpolated one
    assert TL.low <= fit["fitted_value"] <= TL.high
    assert estimates.in_force() == ()  # the registry's values are back in force


def test_a_measurement_outside_the_range_takes_the_closest_end_and_resumes(tmp_path, monkeypatch):
    monkeypatch.setitem(calibrate.MEASURE, "SHELL_TL_MAX_DB", _linear_drop)
    fit = calibrate.fit(_with_target(29.0), tmp_path, log=lambda s: None)
    assert not fit["bracketed"] and fit["fitted_value"] == TL.low and len(fit["points"]) == 2
    monkeypatch.setitem(
        calibrate.MEASURE, "SHELL_TL_MAX_DB", lambda point: pytest.fail("a measured point was measured again")
    )
    assert calibrate.fit(_with_target(29.0), tmp_path, log=lambda s: None)["points"] == fit["points"]
    doc = {
        **documents.header(
            calibrate.STUDY, module=calibrate.__name__, command=None, seeds=list(range(calibrate.SEEDS))
        ),
        "fits": [fit],
    }
    assert "the range's end" in calibrate.markdown(doc)


def test_one_estimate_per_measurement(monkeypatch):
    twin = dataclasses.replace(estimates.ESTIMATES["SHELL_TL_MIN_DB"], calibrated=TL.calibrated)
    monkeypatch.setattr(estimates, "ESTIMATES", {**estimates.ESTIMATES, twin.name: twin})
    with pytest.raises(UserError, match="one estimate per measurement"):
        calibrate.calibrated()


def test_the_registry_holds_the_published_calibration():
    """Each calibrated estimate's registry value is the fit results/calibration.json publishes."""
    doc = json.loads((RESULTS / "calibration.json").read_text())
    fits = {f["estimate"]: f for f in doc["fits"]}
    for e in calibrate.calibrated():
        assert e.value == pytest.approx(fits[e.name]["fitted_value"]), e.name
        assert fits[e.name]["paper_value"] == pytest.approx(e.calibrated.paper_value)


def test_the_design_is_deterministic_and_moves_only_uncalibrated_estimates_within_their_ranges():
    groups = sensitivity.screened_groups()
    x = sensitivity.design(groups, 2, seed=0)
    assert x.shape == (2 * (len(groups) + 1), len(groups))
    np.testing.assert_array_equal(x, sensitivity.design(groups, 2, seed=0))
    for u in x:
        values = sensitivity.point_values(u, groups)
        assert estimates.check(values) == values
        assert not any(estimates.ESTIMATES[n].calibrated for n in values)
    assert set(sensitivity.point_values(x[0], groups)) == {e.name for e in sensitivity.moved()}


def _stand_in_measure(point, preset):
    """Responses that follow two estimates' values: servo noise moves Minsound, the camera day the image."""
    tone = estimates.value("SERVO_TONE_PA") / estimates.ESTIMATES["SERVO_TONE_PA"].high
    grain = estimates.value("FLAKE_CONTRAST") / estimates.ESTIMATES["FLAKE_CONTRAST"].high
    minsound, image = 90 - 40 * tone, 10 + 30 * grain
    responses = {name: 0.0 for name in sensitivity.PLOTTED}
    responses.update(
        {
            "probe test: Minsound [%]": minsound,
            "probe test: Minsight image − session reference [%]": image,
            "Minsound margin over the best other single input [pp]": minsound - max(image, 50.0),
            "optical flow − image, test [pp]": 20 - image,
            "proprioception − optical flow, test [pp]": 1.0,
            "palm's gain in the cafe [pp]": -5.0,
            "image property margin over chance, test [pp]": 0.0,
            "best camera input, test [%]": image,
        }
    )
    side = {"image carries thickness": False, "image carries roughness": False, "camera carries the fabric": image > 20}
    return responses, side


def test_the_screening_ranks_the_group_that_moves_each_response(tmp_path, monkeypatch):
    monkeypatch.setattr(sensitivity, "measure", _stand_in_measure)
    where = Location(workdir=tmp_path, results=tmp_path / "results")
    (tmp_path / "results").mkdir()
    report = tmp_path / "results" / "REPORT.md"
    report.write_text(f"# report\n\n{sensitivity.REPORT_BEGIN}\nSTALE BLOCK\n{sensitivity.REPORT_END}\n\nkept\n")
    doc = sensitivity.run(
        preset="smoke", trajectories=3, groups=["servo noise", "camera day"], where=where, progress=False
    )
    r = doc["responses"]
    assert np.argmax(r["probe test: Minsound [%]"]["mu_star"]) == 0 and r["probe test: Minsound [%]"]["mu_star"][1] == 0
    assert np.argmax(r["probe test: Minsight image − session reference [%]"]["mu_star"]) == 1
    claims = {c["claim"]: c for c in doc["claims"]}
    assert len(claims) == len(sensitivity.CLAIMS)
    assert claims[sensitivity.CLAIMS[3].text]["holds_at"] == 0  # the palm never helps here
    assert claims[sensitivity.CLAIMS[0].text]["holds_at"] == len(doc["points"])
    for name in ("sensitivity.md", "sensitivity.json", "sensitivity.png"):
        assert (tmp_path / "results" / name).is_file()
    text = report.read_text()
    assert "STALE BLOCK" not in text and text.endswith("kept\n") and sensitivity.CLAIMS[0].text in text
    # resumable: every point is read back, none measured again
    monkeypatch.setattr(
        sensitivity, "measure", lambda point, preset: pytest.fail("a measured point was measured again")
    )
    again = sensitivity.run(
        preset="smoke", trajectories=3, groups=["servo noise", "camera day"], where=where, progress=False
    )
    assert again["responses"] == doc["responses"]


def test_unknown_or_too_few_groups_are_one_line_errors(tmp_path):
    with pytest.raises(UserError, match="unknown estimate groups"):
        sensitivity.run(groups=["servo noise", "no such group"], where=Location(workdir=tmp_path), progress=False)
    with pytest.raises(UserError, match="at least two groups"):
        sensitivity.run(groups=["servo noise"], where=Location(workdir=tmp_path), progress=False)


@pytest.mark.slow
def test_the_screening_runs_on_the_smoke_preset(tmp_path):
    """Every point simulated anew with its estimates and probed: three points of two groups."""
    where = Location(workdir=tmp_path, results=tmp_path / "results")
    doc = sensitivity.run(
        preset="smoke", trajectories=1, groups=["servo noise", "camera day"], where=where, progress=False
    )
    assert len(doc["points"]) == 3
    r = doc["responses"]
    # servo noise is audio only, the camera's day images only: each leaves the other's inputs exactly as they were
    assert r["probe test: Minsound [%]"]["mu_star"][1] == 0
    assert r["day share: Minsight image − session reference [%]"]["mu_star"][0] == 0
    assert r["day share: Minsight image − session reference [%]"]["mu_star"][1] > 0
    assert not (
        tmp_path / "sensitivity" / "smoke-r1-seed0" / "point-000"
    ).exists()  # each point's data removed once measured
