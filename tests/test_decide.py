"""Calibrated confidence, the sequential stopping rule and unknown-fabric scores (fabricjax.inference.confidence),
and the decision study end to end on the smoke preset."""

import json

import numpy as np
import pytest

from fabricjax.inference import confidence
from fabricjax.store.workspace import Location
from tests.helpers import read_rrd


def overconfident(n=4000, classes=5, sharpen=3.0, seed=0):
    """Logits whose labels are drawn from softmax(z) but that report `sharpen` x z: a model whose
    probabilities are too confident by a known temperature."""
    rng = np.random.default_rng(seed)
    z = rng.normal(scale=1.5, size=(n, classes))
    labels = np.array([rng.choice(classes, p=p) for p in confidence.calibrated(z)])
    return sharpen * z, labels


def test_temperature_scaling_undoes_a_known_overconfidence_and_reduces_ece():
    logits, labels = overconfident()
    t = confidence.fit_temperature(logits[:2000], labels[:2000])
    assert 2.5 < t < 3.5  # the planted sharpening
    before = confidence.ece(confidence.calibrated(logits[2000:]), labels[2000:])
    after = confidence.ece(confidence.calibrated(logits[2000:], t), labels[2000:])
    assert before > 0.1 and after < before / 3
    # one scalar: the argmax, so the accuracy, is unchanged
    np.testing.assert_array_equal(np.argmax(confidence.calibrated(logits, t), -1), np.argmax(logits, -1))


def test_ece_is_zero_for_a_calibrated_bin_and_the_gap_otherwise():
    probs = np.array([[0.75, 0.25]] * 4)
    assert confidence.ece(probs, np.array([0, 0, 0, 1])) == pytest.approx(0.0)
    assert confidence.ece(probs, np.array([1, 1, 1, 1])) == pytest.approx(0.75)
    r = confidence.reliability(probs, np.array([0, 0, 0, 1]), bins=4)
    assert r["count"] == [0, 0, 0, 4] and r["accuracy"][3] == pytest.approx(0.75) and r["confidence"][0] is None


def test_the_stopping_rule_decides_when_the_accumulated_posterior_passes_the_threshold():
    # every window says class 2 with 0.6, the others 0.2: posterior after k windows 3^k / (3^k + 2)
    windows = np.tile([0.2, 0.2, 0.6], (10, 1))
    d = confidence.sequential(windows, threshold=0.95)
    assert (d.label, d.windows, d.confident) == (2, 4, True)  # 0.931 after 3, 0.976 after 4
    np.testing.assert_allclose(d.posteriors[:, 2], [3**k / (3**k + 2) for k in range(1, 5)])
    capped = confidence.sequential(windows, threshold=0.95, max_windows=2)
    assert (capped.label, capped.windows, capped.confident) == (2, 2, False)
    # evidence for another class later in the trial moves the posterior back
    mixed = np.concatenate([np.tile([0.6, 0.2, 0.2], (2, 1)), np.tile([0.1, 0.1, 0.8], (6, 1))])
    d = confidence.sequential(mixed, threshold=0.99)
    assert d.label == 2 and d.confident and d.windows > 2
    curve = confidence.decision_curve([windows, mixed], [2, 0], (0.5, 0.95), None, window_s=0.5)
    assert curve[0] == {"threshold": 0.5, "accuracy": 1.0, "mean_touch_s": 0.5, "confident": 1.0}  # one window each
    assert curve[1]["accuracy"] == 0.5 and curve[1]["mean_touch_s"] > 0.5


def test_mahalanobis_and_max_probability_tell_a_planted_unknown_class_apart():
    rng = np.random.default_rng(1)
    centres = rng.normal(scale=4.0, size=(4, 8))
    labels = rng.integers(0, 4, 800)
    train = centres[labels] + rng.normal(size=(800, 8))
    known = centres[rng.integers(0, 4, 200)] + rng.normal(size=(200, 8))
    unknown = rng.normal(scale=4.0, size=8) + rng.normal(size=(200, 8))
    m = confidence.Mahalanobis.fit(train, labels)
    k, u = m.score(known), m.score(unknown)
    assert confidence.auroc(k, u) > 0.9
    far, threshold = confidence.false_accept_rate(k, u)
    assert np.mean(k <= threshold) >= 0.95 and far < 0.2
    assert confidence.auroc(k, k) == pytest.approx(0.5)
    assert confidence.auroc(np.zeros(3), np.ones(3)) == 1.0 and confidence.auroc(np.ones(3), np.zeros(3)) == 0.0


def test_temperatures_round_trip_beside_a_checkpoint_and_bad_ones_are_one_line_errors(tmp_path):
    from fabricjax.errors import UserError

    assert confidence.load_temperature(tmp_path, 0) is None
    confidence.save_temperatures(tmp_path, {0: 1.7, 3: 0.9}, "val")
    assert confidence.load_temperature(tmp_path, 3) == 0.9 and confidence.load_temperature(tmp_path, 5) is None
    (tmp_path / confidence.TEMPERATURE_FILE).write_text(json.dumps({"temperature": {"0": -1}}))
    with pytest.raises(UserError, match="temperature.0"):
        confidence.load_temperature(tmp_path, 0)


@pytest.mark.slow
def test_decide_on_the_smoke_preset_writes_its_reports_and_the_stream_applies_the_temperature(tmp_path):
    from fabricjax.studies.diagnostics import decide
    from fabricjax.studies.diagnostics import stream

    results = tmp_path / "results"
    doc = decide.run(preset="smoke", where=Location(workdir=tmp_path / "ws", results=results))
    m = doc["models"][0]
    assert {p.name for p in results.iterdir()} >= {"decide.md", "decide.json", "decide.png"}
    assert set(m["splits"]) == {"test", "cafe"} and m["unknown"]["fabrics"] == [21]  # the smoke preset's one new fabric
    for d in m["splits"].values():  # each accuracy beside its split's majority class (of the sequences, of the trials)
        assert d["majority"]["known"] == d["sequences"] and d["majority_trials"]["known"] == d["trials"]
        assert d["collapsed"] is None or 0 <= d["collapsed"] < len(doc["dataset"]["classes"])
    assert "| majority class [%] |" in (results / "decide.md").read_text()
    assert all(0 <= v["auroc"] <= 1 for v in m["unknown"]["scores"].values())
    assert confidence.load_temperature(m["checkpoint"], m["seed"]) == pytest.approx(m["temperature"])
    lines = []
    s = stream.run(
        preset="smoke",
        where=Location(workdir=tmp_path / "ws", results=results),
        realtime=False,
        print_every=0,
        out=lines.append,
        view_save=tmp_path / "s.rrd",
    )
    assert s["temperature"] == pytest.approx(m["temperature"]) and any("sequential decision" in x for x in lines)
    # the accumulated posterior, once per non-overlapping window after the first full one
    windows = (s["steps"] - s["window_steps"]) // s["window_steps"] + 1
    assert len(read_rrd(tmp_path / "s.rrd")["/prediction/posterior"]["steps"]) == s["decided_steps"]
    assert s["decision"] is None or 1 <= s["decision"]["windows"] <= windows


@pytest.mark.slow
def test_reproduce_runs_decide_on_the_ablations_checkpoint(tmp_path):
    from fabricjax.studies.release import reproduce, reproduce_plan

    plan = (reproduce_plan.Step("ablation", 1, ("internal",)), reproduce_plan.Step("decide", rows=("internal",)))
    said = []
    reproduce.run(
        preset="smoke",
        plan=plan,
        overrides=dict(epochs=1, width=16, n_layers=1),
        where=Location(workdir=tmp_path / "ws", results=tmp_path / "out"),
        say=said.append,
    )
    ablation = json.loads((tmp_path / "out" / "ablation.json").read_text())
    doc = json.loads((tmp_path / "out" / "decide.json").read_text())
    assert [m["checkpoint"] for m in doc["models"]] == [ablation["rows"][0]["checkpoint"]]
    assert doc["models"][0]["name"] == "internal" and "--checkpoint=" in doc["command"]
    assert f"## {reproduce_plan.title('decide')}" in (tmp_path / "out" / "REPORT.md").read_text()


@pytest.mark.slow
def test_decide_on_recorded_data_uses_its_label_map_splits_and_unknown_labels(tmp_path):
    """A rig's own classes (oak, pine, felt), its own split names in meta, felt never trained and
    named the unknown by --unknown_labels; no cafe split: reported without one."""
    from fabricjax.studies.diagnostics import decide
    from tests.test_rig_data import _rig_dataset

    trials = [(0, "train"), (1, "train")] * 3 + [(0, "val"), (1, "val"), (0, "test"), (1, "test"), (2, "test")]
    ds = _rig_dataset(tmp_path / "ds", trials)
    doc = decide.run(
        preset="smoke",
        overrides={"modalities": ("internal",), "epochs": 1},
        where=Location(data_dir=ds, workdir=tmp_path / "ws", results=tmp_path / "out"),
        unknown_labels=[2],
    )
    m = doc["models"][0]
    assert doc["dataset"]["classes"] == ["oak", "pine", "felt"] and list(m["splits"]) == ["test"]
    assert (
        m["unknown"]["fabrics"] == [2]
        and m["unknown"]["unknown_sequences"] == 3
        and m["unknown"]["known_sequences"] == 6
    )
    assert "on recorded data" in (tmp_path / "out" / "decide.md").read_text()
