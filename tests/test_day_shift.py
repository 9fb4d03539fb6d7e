"""The day-shift study: its variance split on known data, and its run on the smoke preset, on a
recorded folder and inside `reproduce` after the probe."""

import json
import os

import numpy as np
import pytest

from fabricjax import sim
from fabricjax.store.workspace import Location
from fabricjax.studies.diagnostics import day_shift, palm
from fabricjax.studies.machinery import camera_variation, day_variation
from fabricjax.studies.release import reproduce, reproduce_plan, staleness

TINY = dict(epochs=1, width=16, n_layers=1)


def _design(n_fabrics=4, days=(1, 2, 3), trials=(5, 5, 2)):
    fabric = np.repeat(np.arange(n_fabrics), sum(trials))
    day = np.tile(np.concatenate([np.full(t, d) for d, t in zip(days, trials)]), n_fabrics)
    return fabric, day


def test_the_shares_find_the_factor_that_moves_the_trials():
    rng = np.random.default_rng(0)
    fabric, day = _design()
    noise = 0.01 * rng.standard_normal((len(fabric), 3))
    by_fabric = day_variation.variance_shares(rng.standard_normal((4, 3))[fabric] + noise, fabric, day)
    by_day = day_variation.variance_shares(rng.standard_normal((4, 3))[day] + noise, fabric, day)
    assert by_fabric["fabric"] > 0.99 and by_day["day"] > 0.99 and by_day["fabric"] < 0.01
    for shares in (by_fabric, by_day):
        assert sum(shares.values()) == pytest.approx(1.0) and min(shares.values()) >= -1e-12
    constant = day_variation.variance_shares(np.ones((len(fabric), 2)), fabric, day)
    assert all(np.isnan(v) for v in constant.values())


def test_on_balanced_trials_the_shares_are_the_two_way_analysis_of_variance():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((3, 2, 4, 5)) + rng.standard_normal((3, 1, 1, 5)) + rng.standard_normal((1, 2, 1, 5))
    fabric, day, _ = (a.ravel() for a in np.meshgrid(np.arange(3), np.arange(2), np.arange(4), indexing="ij"))
    ours = day_variation.variance_shares(x.reshape(-1, 5), fabric, day)
    theirs = palm.variance_shares(x)
    for k in day_variation.SHARES:
        assert ours[k] == pytest.approx(float(np.mean(theirs[k])))


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    root = tmp_path_factory.mktemp("day_shift")
    sim.ensure_dataset("smoke", root, streams=("audio", "proprio"), progress=False)
    return root


@pytest.mark.slow
def test_day_shift_runs_after_the_probe_in_reproduce_and_shows_its_gap(workdir, tmp_path):
    plan = (
        reproduce_plan.Step("probe", rows=("proprio", "internal")),
        reproduce_plan.Step("day_shift", rows=("proprio", "internal")),
    )
    reproduce.run(
        preset="smoke", plan=plan, overrides=TINY, where=Location(workdir=workdir, results=tmp_path), say=lambda s: None
    )
    doc = json.loads((tmp_path / "day_shift.json").read_text())
    probe_doc = json.loads((tmp_path / "probe.json").read_text())
    assert [r["name"] for r in doc["rows"]] == [
        "internal",
        "proprio",
    ]  # the table's order and doc["days"] == [1, 2, 3] and doc["probe_missing"] is None
    for r in doc["rows"]:
        assert sum(r["shares"].values()) == pytest.approx(1.0)
        assert r["probe"] == {
            s: next(p for p in probe_doc["rows"] if p["name"] == r["name"])["accuracy"][s] for s in ("val", "test")
        }
    report = (tmp_path / "REPORT.md").read_text()
    assert f"## {reproduce_plan.title('day_shift')}" in report and "Test − validation [pp]" in report
    assert report.count("| – (deterministic) | – (not in the paper) |") == 2
    manifest = json.loads((tmp_path / reproduce_plan.MANIFEST).read_text())
    prints = manifest["day_shift"]["fingerprints"]
    other = staleness.step_key(plan[1], "smoke", TINY, prints, manifest["probe"]["key"] + "0")
    assert (
        other
        != staleness.step_key(plan[1], "smoke", TINY, prints, manifest["probe"]["key"])
        == manifest["day_shift"]["key"]
    )  # the probe's key is in the day shift's


@pytest.mark.slow
def test_day_shift_reads_a_recorded_folder_and_says_when_the_probe_is_missing(workdir, tmp_path):
    folder = tmp_path / "recordings"
    folder.mkdir()
    for archive in sim.ensure_dataset("smoke", workdir, streams=("audio", "proprio"), progress=False).glob("*.npz"):
        os.link(archive, folder / archive.name)
    before = sorted((p.name, p.stat().st_mtime_ns) for p in folder.rglob("*"))
    doc = day_shift.run(
        preset="smoke",
        rows=["external"],
        where=Location(workdir=workdir, data_dir=folder, results=tmp_path / "results", command="test"),
    )
    assert (
        doc["dataset"]["source"] == "recorded"
        and doc["rows"][0]["probe"] is None
        and "no probe results" in doc["probe_missing"]
    )
    md = (tmp_path / "results" / "day_shift.md").read_text()
    assert md.startswith("# Day shift") and "on recorded data" in md and "Probe columns: no probe results" in md
    assert sorted((p.name, p.stat().st_mtime_ns) for p in folder.rglob("*")) == before


def test_weighted_by_variance_a_few_loud_fabric_dimensions_outweigh_many_quiet_day_ones():
    """Day_shift against camera_frames in small: 90 quiet dimensions that only the day moves (what is
    fixed per session) and 10 loud ones that the fabric moves (the contact)."""
    rng = np.random.default_rng(2)
    fabric, day = _design()
    quiet = 0.01 * rng.standard_normal((3, 90))[day - 1] + 0.001 * rng.standard_normal((len(day), 90))
    loud = 5.0 * rng.standard_normal((4, 10))[fabric] + 0.5 * rng.standard_normal((len(day), 10))
    x = np.concatenate([quiet, loud], axis=1)
    alike = day_variation.variance_shares(x, fabric, day)
    weighted = day_variation.variance_shares(x, fabric, day, weighted=True)
    assert alike["day"] > 0.8 and alike["fabric"] < 0.2
    assert weighted["fabric"] > 0.95 and weighted["day"] < 0.01
    assert sum(weighted.values()) == pytest.approx(1.0)
    assert 0.85 <= day_variation.day_led_dims(x, fabric, day) <= 0.9  # the quiet ones, bar a day drawn near 0
    # one dimension, or dimensions on one scale alike: the two weighings agree
    same = np.tile(x[:, :1], (1, 3))
    assert day_variation.variance_shares(same, fabric, day, weighted=True) == pytest.approx(
        day_variation.variance_shares(same, fabric, day)
    )


def test_the_page_shares_the_camera_frames_sentence_with_the_image_rows_weighted():
    row = dict(summary_dims=4, probe=None, shares={k: 0.25 for k in day_variation.SHARES})
    doc = {
        "rows": [
            {
                **row,
                "name": "internal",
                "display_name": "Minsound",
                "shares_weighted": dict(row["shares"]),
                "day_led_dims": 0.0,
            },
            {
                **row,
                "name": "session:image",
                "display_name": "Minsight image − session reference",
                "shares_weighted": {"fabric": 0.6, "day": 0.1, "fabric x day": 0.1, "trial": 0.2},
                "day_led_dims": 0.75,
            },
        ]
    }
    text = "\n".join(day_shift.image_weighting(doc))
    assert camera_variation.RECONCILE in text
    assert "Minsight image − session reference gives the fabric 60.0 % of its variation and the day 10.0 %" in text
    assert "in 75.0 % of its 4 dimensions" in text and "| Minsound |" not in text
    assert day_shift.image_weighting({"rows": doc["rows"][:1]}) == []
