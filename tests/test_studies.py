"""The paper's studies on the smoke preset: outputs, tables, statistics, checkpoint -> t-SNE."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats as sps

from fabricjax import presets, sim, source
from fabricjax.config import Config
from fabricjax.errors import UserError
from fabricjax.reporting import results_files, stats
from fabricjax.sequences import data
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import (
    ablation_rows,
    documents,
    findings,
    linear_probe,
    probing,
    row_training,
    wilcoxon,
)
from fabricjax.studies.machinery.rows import RowSpec, check_overrides, label_key, select_rows
from fabricjax.studies.machinery.results import AblationRow
from fabricjax.studies.machinery.trained import TrainedRow
from fabricjax.studies.pages import ablation as ablation_page
from fabricjax.studies.diagnostics import day_shift, probe, sweep
from fabricjax.studies.paper import ablation, bandwidth, latents, noise, properties
from fabricjax.studies.release import reproduce, reproduce_plan, reproduce_readme, staleness
from fabricjax.training import curves, train

# Tiny on top of the smoke preset's own training settings: one epoch, one layer, width 16.
TINY = dict(epochs=1, width=16, n_layers=1)


@pytest.fixture(scope="session")
def workdir(tmp_path_factory):
    """The smoke dataset with camera frames, generated once for every test here."""
    root = tmp_path_factory.mktemp("studies")
    sim.ensure_dataset("smoke", root, streams=("audio", "proprio", "images"), progress=False)
    return root


def run_kwargs(workdir, results, **kw):
    return dict(preset="smoke", overrides=TINY, where=Location(workdir=workdir, results=results, command="test"), **kw)


def test_ablation_writes_table_statistics_and_confusions(workdir, tmp_path):
    rows = ["internal", "proprio", "internal+external"]
    doc = ablation.run(n_seeds=2, rows=rows, **run_kwargs(workdir, tmp_path))
    assert [r["name"] for r in doc["rows"]] == rows  # the table's order
    # per-sample records beside the results JSON, not in it: the JSON is tracked, the records are not
    samples = json.loads((tmp_path / f"ablation{results_files.SAMPLES}").read_text())
    n_test = len(samples["sequences"]["test"]["labels"]["fabric"])
    assert "predictions" not in json.dumps(doc) and "trial_key" not in json.dumps(doc)
    for r in doc["rows"]:
        assert len(r["accuracy"]["test"]["fabric"]) == 2
        assert np.asarray(samples["rows"][r["name"]]["test"]["fabric"]).shape == (2, n_test)
        assert r["wall_s"] > 0 and r["config"]["epochs"] == 1
    w = doc["wilcoxon"]
    assert w["per_seed"]["pairing"].startswith("per seed") and w["per_seed"]["n_pairs"] == 2
    assert w["per_sample"]["n_pairs"] == 2 * n_test
    assert (tmp_path / "ablation_confusion.png").stat().st_size > 0
    assert doc["figures"] == ["ablation_confusion.png", "ablation_time_to_accuracy.png"]
    assert (tmp_path / "ablation_time_to_accuracy.png").stat().st_size > 0
    md = (tmp_path / "ablation.md").read_text()
    assert "smallest attainable p" in md and "command: `test`" in md and "`ablation_time_to_accuracy.png`" in md
    assert (
        "Paper [%]" not in md and "95.06 ± 1.85" not in md
    )  # the install check is not the paper's table: no paper columns
    assert json.loads((tmp_path / "ablation.json").read_text())["preset"] == "smoke"
    assert doc["compute_dtype"] == ["float32"] and "matrix products in float32 with float32 accumulation" in md
    assert doc["dataset"]["layout_s"] == 0.0 and "laid out" not in md  # no camera input to lay out


def test_the_smoke_preset_learns_and_says_it_checks_the_install(workdir, tmp_path):
    """The newcomer's proof that the install works: the smoke preset's own recipe puts Minsound
    well above chance (twice chance over the classes its test day has), and its report says that
    it checks the install and counts none of the paper's claims."""
    doc = ablation.run(
        n_seeds=1, rows=["internal"], preset="smoke", where=Location(workdir=workdir, results=tmp_path, command="test")
    )
    samples = json.loads((tmp_path / f"ablation{results_files.SAMPLES}").read_text())
    labels = samples["sequences"]["test"]["labels"]["fabric"]
    chance = 1 / len(set(labels))
    assert doc["rows"][0]["accuracy"]["test"]["fabric"][0] >= 2 * chance
    # the classifier has the smoke data's classes, no other, and predicts only those
    assert doc["rows"][0]["config"]["n_classes"] == len(set(labels)) == 5
    assert set(samples["rows"]["internal"]["test"]["fabric"][0]) <= set(labels)
    md = (tmp_path / "ablation.md").read_text()
    assert presets.INSTALL_CHECK_NOTE in md.split("\n")[2] and findings.NOT_COUNTED in md
    assert "evaluated claims reproduced" not in md


@pytest.mark.slow
def test_ablation_rerun_gives_identical_per_seed_accuracies(workdir, tmp_path):
    """The main command twice on one machine, training afresh (its checkpoints removed): the same
    per-seed accuracies, to the last bit."""
    rows = ["internal", f"{ablation.STEP_LAYERNORM}:internal+external"]
    first = ablation.run(n_seeds=2, rows=rows, **run_kwargs(workdir, tmp_path / "a"))
    for r in first["rows"]:
        shutil.rmtree(r["checkpoint"])
    second = ablation.run(n_seeds=2, rows=rows, **run_kwargs(workdir, tmp_path / "b"))
    samples = [json.loads((tmp_path / f / f"ablation{results_files.SAMPLES}").read_text()) for f in "ab"]
    assert samples[0]["rows"] == samples[1]["rows"]  # every prediction
    for a, b in zip(first["rows"], second["rows"]):
        assert a["accuracy"] == b["accuracy"]
    assert (
        first["rows"][1]["fusion_norm"] == "step_layernorm"
        and "our step-LayerNorm fusion" in first["rows"][1]["display_name"]
    )


MAJORITY = {
    "label": 0,
    "accuracy": 5.0,
    "known": 100,
}  # the test split's majority class, as `findings.majority` gives it


SIGNIFICANT = {"per_sample": {"p_value": 0.01}, "per_seed": {"p_value": 0.0625}}  # the JSON's Wilcoxon tests


def _checklist(test: dict, majority=MAJORITY, collapsed=None, wilcoxon=SIGNIFICANT) -> list:
    return ablation.checklist({k: np.asarray(v) / 100 for k, v in test.items()}, majority, 21, collapsed, wilcoxon)


def _holds(test: dict, majority=MAJORITY) -> list[bool | None]:
    return [f.holds for f in _checklist(test, majority)]


def test_ablation_checklist_predicates_on_synthetic_per_seed_results():
    paper_like = {
        "image": [40, 42],
        "flow": [47, 48],
        "internal": [95, 94],
        "external": [59, 60],
        "proprio": [47, 46],
        "internal+external": [97, 98],
        f"{ablation.STEP_LAYERNORM}:internal+external": [96, 97],
        "internal+external+proprio": [96, 96],
        "tcn:internal+external+proprio": [75, 76],
    }
    assert _holds(paper_like) == [True] * 7
    wrong = {
        "image": [50, 50],
        "flow": [30, 32],
        "internal": [60, 62],
        "external": [55, 56],
        "proprio": [10, 12],
        "internal+external": [58, 59],
        f"{ablation.STEP_LAYERNORM}:internal+external": [61, 62],
        "internal+external+proprio": [50, 50],
        "tcn:internal+external+proprio": [51, 50],
    }
    # best single (61 > 55.5); palm only 5.5 pp worse; proprio 11 vs flow 31; images above flow;
    # + palm below Minsound; our fused variant 61.5 >= 61; TCN 50.5 above the transformer's 50
    assert _holds(wrong) == [True, False, False, False, False, True, False]
    assert _holds({"internal": [90]}) == [None] * 7  # rows not run: not evaluated
    # "well above chance" counts against the majority class, not 1 / classes: 47 % is not 10 pp above a 40 % majority
    unbalanced = {"label": 3, "accuracy": 40.0, "known": 100}
    assert _holds(paper_like, unbalanced)[2] is False and _holds(paper_like, None)[2] is None
    claim = _checklist(paper_like, unbalanced)[2]
    assert (
        "majority class 40.0 % (class 3), so at least 50.0 %" in claim.evidence
        and "1 / classes 4.8 %" in claim.evidence
    )
    # counted only where the evidence carries it: a collapsed image row, our variant's claim
    fs = _checklist(paper_like, collapsed={"image": [7, 7]})
    assert [f.counted for f in fs] == [True, True, True, False, True, False, True]
    assert fs[3].holds and "Minsight image collapsed on 2 of 2 seeds" == fs[3].not_counted
    assert findings.count(fs) == (5, 5)
    # the paper's significance: above by the mean but not by its test, or without a test at all
    assert _checklist(paper_like, wilcoxon={**SIGNIFICANT, "per_sample": {"p_value": 0.2}})[4].holds is False
    assert _checklist(paper_like, wilcoxon=None)[4].holds is None


def test_bandwidth_narrows_the_psd_per_row(workdir, tmp_path):
    doc = bandwidth.run(n_seeds=1, rows=["2.5"], **run_kwargs(workdir, tmp_path))
    (row,) = doc["rows"]
    assert row["psd_bins"] == 54 and row["config"]["bandwidth_khz"] == 2.5
    assert "89.87 ± 3.31" in (tmp_path / "bandwidth.md").read_text()
    full = {
        "s": data.SequenceSet(
            {"internal": np.zeros((2, 3, 512)), "external": np.zeros((2, 3, 512)), "proprio": np.zeros((2, 3, 18))},
            {},
            {},
        )
    }
    cut = data.narrow(full, Config(modalities=("internal", "proprio"), bandwidth_khz=15.0))["s"].inputs
    assert cut.keys() == {"internal", "proprio"}  # the row's inputs only
    assert cut["internal"].shape == (2, 3, 320) and cut["proprio"].shape == (2, 3, 18)
    with pytest.raises(
        UserError, match=r"sets bandwidth_khz per row itself \(every one of its 4 rows\); choose bandwidths with --rows"
    ):
        bandwidth.run(**run_kwargs(workdir, tmp_path) | {"overrides": {"bandwidth_khz": 10.0}})


def test_noise_tests_each_row_against_the_preceding_one(workdir, tmp_path):
    doc = noise.run(n_seeds=2, rows=["internal", "internal+proprio"], **run_kwargs(workdir, tmp_path))
    first, second = doc["rows"]
    assert first["wilcoxon"] is None and second["against"] == "internal"
    assert second["wilcoxon"]["per_seed"]["n_pairs"] == 2
    assert len(second["accuracy"]["cafe"]["fabric"]) == 2 and "test" in second["accuracy"]
    md = (tmp_path / "noise.md").read_text()
    assert "67.51 ± 5.05" in md and "< 0.0001" in md


def test_probe_writes_its_table_for_the_ablation_rows_inputs(workdir, tmp_path):
    rows = ["image", "proprio", "internal+external"]
    doc = probe.run(rows=rows, **run_kwargs(workdir, tmp_path))
    assert [r["name"] for r in doc["rows"]] == rows and doc["splits"] == ["train", "val", "test", "cafe"]
    assert doc["dataset"]["source"] == "simulated" and doc["dataset"]["sequences"]["cafe"] > 0
    for r in doc["rows"]:
        assert set(r["accuracy"]) == {"train", "val", "test", "cafe"} and r["C"] in linear_probe.C_GRID
        assert all(0 <= a <= 1 for a in r["accuracy"].values())
    samples = json.loads((tmp_path / f"probe{results_files.SAMPLES}").read_text())
    for r in doc["rows"]:
        assert len(samples["rows"][r["name"]]["test"]) == len(samples["sequences"]["test"]["labels"]["fabric"])
        assert "predictions" not in r and set(r["collapsed"]) == {"val", "test", "cafe"}
    image = doc["inputs"]["image"]  # the smoke preset's 60x80 frames: 14400 dims per step, reduced
    assert (
        image["step_dims"] == 60 * 80 * 3
        and image["probe_dims"] <= linear_probe.PCA_DIMS
        and 0 < image["explained_variance"] <= 1 + 1e-6
    )
    assert doc["inputs"]["proprio"]["probe_dims"] == 36 and doc["rows"][2]["probe_dims"] == 2 * 640
    md = (tmp_path / "probe.md").read_text()
    assert md.startswith("# Linear probe") and "command: `test`" in md and "| Minsound + palm mic | 1280 |" in md
    assert json.loads((tmp_path / "probe.json").read_text())["rows"] == json.loads(json.dumps(doc["rows"]))


def test_probe_command_reads_a_data_dir_and_writes_nothing_there(workdir, tmp_path):
    """A folder of recordings outside the workspace (the smoke archives, hard-linked): its index goes
    to the workspace, and nothing is written into it."""
    simulated = sim.ensure_dataset("smoke", workdir, streams=("audio", "proprio", "images"), progress=False)
    folder = tmp_path / "recordings"
    folder.mkdir()
    for archive in simulated.glob("*.npz"):
        os.link(archive, folder / archive.name)
    before = sorted((p.name, p.stat().st_mtime_ns) for p in folder.rglob("*"))
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    cmd = [
        sys.executable,
        "-m",
        "experiments.probe",
        "--preset=smoke",
        "--rows=proprio",
        f"--data_dir={folder}",
        f"--workdir={workdir}",
        f"--results={tmp_path / 'results'}",
    ]
    out = subprocess.run(
        cmd, check=True, env=env, cwd=Path(__file__).parents[1], capture_output=True, text=True, timeout=300
    )
    results = tmp_path / "results"
    assert out.stdout.strip().splitlines()[-1] == (
        f"wrote {results / 'probe.json'}, {results / 'probe.md'}, {results / f'probe{results_files.SAMPLES}'}"
    )
    doc = json.loads((results / "probe.json").read_text())
    assert doc["dataset"]["source"] == "recorded" and doc["dataset"]["folder"] == str(folder)
    assert [r["name"] for r in doc["rows"]] == ["proprio"] and doc["command"].startswith(
        "python -m experiments.probe --preset=smoke"
    )
    assert sorted((p.name, p.stat().st_mtime_ns) for p in folder.rglob("*")) == before  # only read


@pytest.fixture(scope="module")
def property_run(workdir, tmp_path_factory):
    results = tmp_path_factory.mktemp("properties")
    return properties.run(n_seeds=2, rows=["internal+proprio"], **run_kwargs(workdir, results)), results


def test_properties_report_training_and_holdout_fabrics_and_checkpoint(property_run):
    doc, results = property_run
    assert doc["fabrics"]["holdout"] == [1, 21]  # the smoke preset's holdouts
    assert 0 in doc["fabrics"]["test"] and not {1, 21} & set(doc["fabrics"]["test"])
    (row,) = doc["rows"]
    for split in ("test", "holdout"):
        assert set(row["accuracy"][split]) == {"stretchiness", "roughness", "thickness"}
    assert doc["chance"]["roughness"] == pytest.approx(20.0)
    assert Path(row["checkpoint"]).is_dir()
    md = (results / "properties.md").read_text()
    assert "97.40" in md and "76.15" in md and row["checkpoint"] in md
    # every accuracy beside its split's majority level, from the split's own labels, and each seed's collapse in the
    # JSON
    samples = json.loads((results / f"properties{results_files.SAMPLES}").read_text())
    for split in properties.SPLITS:
        for p in properties.PROPERTIES:
            labels = np.asarray(samples["sequences"][split]["labels"][p])
            assert doc["majority"][split][p] == findings.majority(labels)
            predictions = samples["rows"][row["name"]][split][p]
            assert row["collapsed"][split][p] == findings.collapsed(predictions, labels)
    assert "Majority level, holdout fabrics [%]" in md and "above its majority level" in md
    # "above chance" is counted against the majority level alone
    claim = doc["findings"][0]
    means = {p: 100 * np.mean(row["accuracy"]["holdout"][p]) for p in properties.PROPERTIES}
    assert claim["holds"] == all(means[p] > doc["majority"]["holdout"][p]["accuracy"] for p in properties.PROPERTIES)
    assert (
        claim["claim"].startswith("Minsound + proprioception: every property is above chance")
        and "1 / levels" in claim["evidence"]
    )


def test_latents_from_the_property_checkpoint(property_run, workdir, tmp_path):
    doc, _ = property_run
    out = latents.run(doc["rows"][0]["checkpoint"], where=Location(workdir=workdir, results=tmp_path, command="test"))
    assert [p["fabric_id"] for p in out["points"]] == [1, 2, 3, 4, 21]  # fabrics of the smoke preset but 0
    assert out["seed"] == out["checkpoint_seeds"][int(np.argmax(out["best_val_per_seed"]))]
    assert np.isfinite([p["xy"] for p in out["points"]]).all()
    assert (tmp_path / "latents.png").stat().st_size > 0
    assert out["findings"] and (tmp_path / "latents.md").read_text().startswith("# Latent space")
    with pytest.raises(UserError, match="seed 7"):
        latents.run(doc["rows"][0]["checkpoint"], seed=7, where=Location(workdir=workdir, results=tmp_path))


def test_tsne_is_finite_for_identical_and_few_points():
    xy, perplexity = latents.tsne(np.ones((6, 8)))
    assert perplexity is None and np.array_equal(xy, np.zeros((6, 2)))
    xy, perplexity = latents.tsne(np.random.default_rng(0).normal(size=(5, 8)))
    assert perplexity == pytest.approx(4 / 3) and xy.shape == (5, 2) and np.isfinite(xy).all()
    assert latents.tsne(np.ones((2, 3)))[0].shape == (2, 2)


def test_ablation_table_puts_the_paper_and_the_difference_beside_ours():
    labels = [0, 1, 2, 2]
    rows = [
        {
            "name": "internal",
            "backbone": "attention",
            "modalities": ["internal"],
            "display_name": "Minsound",
            "fusion_norm": "sequence_minmax",
            "paper_mean": 95.06,
            "paper_sd": 1.85,
            "seeds": [0, 1, 2],
            "wall_s": 12.34,
            "accuracy": {"test": {"fabric": [0.9, 0.95, 1.0]}},
            "collapsed": {"test": findings.collapsed([[0, 1, 2, 3]] * 3, labels)},
        },
        {
            "name": "tcn",
            "backbone": "tcn",
            "modalities": ["internal", "external", "proprio"],
            "display_name": "TCN: Minsound + palm mic + proprioception",
            "fusion_norm": "sequence_minmax",
            "paper_mean": 75.41,
            "paper_sd": 11.2,
            "seeds": [0, 1, 2],
            "wall_s": 5.0,
            "accuracy": {"test": {"fabric": [0.5, 0.5, 0.5]}},
            "collapsed": {"test": findings.collapsed([[0, 1, 2, 3], [2] * 4, [2] * 4], labels)},
        },
    ]
    lines = ablation_page.table([AblationRow.from_json(r) for r in rows], findings.majority(labels)).splitlines()
    assert lines[0].startswith(
        "| Backbone | Modalities | Test accuracy [%] (ours, 3 seeds) | Majority class, test [%] | Paper [%] "
        "| Ours − paper [pp]"
    )
    assert lines[2] == "| Transformer | Minsound | 95.00 ± 5.00 | 50.00 (class 2) | 95.06 ± 1.85 | -0.06 | 12.3 |"
    # two of its seeds predict one class for every sequence: the table says so beside the accuracy, and beside the
    # majority class
    assert lines[3] == (
        "| TCN | Minsound + palm mic + proprioception | 50.00 ± 0.00 (collapsed to class 2: 2 of 3 seeds) | "
        "50.00 (class 2) | "
        "75.41 ± 11.20 | -25.41 | 5.0 |"
    )


def test_noise_and_bandwidth_tables():
    w = {"p_value": 0.001953125, "min_attainable_p": 0.001953125, "method": "exact"}
    fine = {"cafe": [None, None], "test": [None, None]}
    rows = [
        {
            "name": "internal",
            "modalities": ["internal"],
            "paper": {"mean": 67.51, "sd": 5.05, "p": None},
            "wilcoxon": None,
            "wall_s": 1.0,
            "accuracy": {"cafe": {"fabric": [0.7, 0.7]}, "test": {"fabric": [0.9, 0.9]}},
            "collapsed": {**fine, "cafe": [4, None]},
        },
        {
            "name": "internal+proprio",
            "modalities": ["internal", "proprio"],
            "paper": {"mean": 87.51, "sd": 2.66, "p": "< 0.0001"},
            "wall_s": 2.0,
            "wilcoxon": {"per_seed": w, "per_sample": {**w, "method": "approx"}},
            "accuracy": {"cafe": {"fabric": [0.9, 0.8]}, "test": {"fabric": [1.0, 1.0]}},
            "collapsed": fine,
        },
    ]
    majority = {"cafe": findings.majority([4, 4, 1]), "test": findings.majority([0, 1, 1, 2])}
    lines = noise.table(rows, majority).splitlines()
    assert lines[2] == (
        "| Minsound | 70.00 ± 0.00 (collapsed to class 4: 1 of 2 seeds) | 66.67 (class 4) | 67.51 ± 5.05 | "
        "+2.49 | – | – | – | "
        "90.00 ± 0.00 | 50.00 (class 1) | 1.0 |"
    )
    assert "0.001953 (floor 0.002, exact)" in lines[3] and "< 0.0001" in lines[3]
    bw = [
        {
            "bandwidth_khz": 2.5,
            "psd_bins": 54,
            "paper": {"val_mean": 92.43, "val_sd": 1.13, "test_mean": 89.87, "test_sd": 3.31},
            "wall_s": 3.0,
            "accuracy": {"val": {"fabric": [0.9]}, "test": {"fabric": [0.8]}},
            "collapsed": {"val": [None], "test": [None]},
        }
    ]
    assert bandwidth.table(bw, {"val": majority["cafe"], "test": None}).splitlines()[2] == (
        "| 2.5 | 54 | 90.00 ± 0.00 | 66.67 (class 4) | 92.43 ± 1.13 | -2.43 | 80.00 ± 0.00 | – | 89.87 ± "
        "3.31 | -9.87 | 3.0 |"
    )


def fake_row(name, accuracy, predictions, seeds):
    metrics = {
        "eval": {
            "test": {"accuracy": {"fabric": np.asarray(accuracy)}, "predictions": {"fabric": np.asarray(predictions)}}
        }
    }
    return TrainedRow(name, None, train.TrainedSeeds(None, tuple(seeds), None, None, metrics), 1.0)


def test_paired_tests_pair_per_seed_and_per_sample_like_scipy():
    rng = np.random.default_rng(0)
    labels = rng.integers(0, 21, 40)
    labels[:3] = -1  # unknown labels are not samples
    pa = np.where(rng.random((5, 40)) < 0.6, labels, (labels + 1) % 21)
    pb = np.where(rng.random((5, 40)) < 0.8, labels, (labels + 1) % 21)
    acc_a = np.array([0.50, 0.55, 0.61, 0.58, 0.52])
    acc_b = acc_a + np.array([0.03, -0.01, 0.05, 0.07, 0.02])
    a, b = fake_row("a", acc_a, pa, range(5)), fake_row("b", acc_b, pb, range(5))
    res = wilcoxon.paired_tests(a, b, "test", labels)
    assert res["per_seed"].p_value == pytest.approx(sps.wilcoxon(acc_b, acc_a, method="exact").pvalue)
    assert res["per_seed"].method == stats.EXACT and res["per_seed"].min_attainable_p == pytest.approx(0.0625)
    cb, ca = ((pb == labels)[:, 3:]).ravel().astype(float), ((pa == labels)[:, 3:]).ravel().astype(float)
    expected = sps.wilcoxon(cb, ca, zero_method="wilcox", method="approx")
    assert res["per_sample"].n_pairs == 5 * 37 and res["per_sample"].method == stats.APPROX
    assert res["per_sample"].p_value == pytest.approx(expected.pvalue)
    same = wilcoxon.paired_tests(a, a, "test", labels)
    assert same["per_seed"].p_value == 1.0 and same["per_sample"].n_nonzero == 0
    with pytest.raises(ValueError, match="different seeds"):
        wilcoxon.paired_tests(a, fake_row("c", acc_b, pb, range(1, 6)), "test", labels)


def test_ten_seed_floor_and_row_selection():
    a = fake_row("a", np.linspace(0.5, 0.6, 10), np.zeros((10, 4), int), range(10))
    b = fake_row("b", np.linspace(0.5, 0.6, 10) + np.arange(1, 11) / 100, np.zeros((10, 4), int), range(10))
    res = wilcoxon.paired_tests(a, b, "test", np.zeros(4, int))["per_seed"]
    assert res.p_value == pytest.approx(2 / 2**10) and res.min_attainable_p == pytest.approx(0.001953125)
    assert [r.name for r in select_rows(ablation_rows.PAPER_ROWS, None)] == [r.name for r in ablation_rows.PAPER_ROWS]
    with pytest.raises(ValueError, match="unknown rows"):
        select_rows(ablation_rows.PAPER_ROWS, ["audio"])


def test_rows_are_chosen_by_name_or_by_the_label_the_tables_print():
    """--rows=Minsound,proprioception: what the tables print, in any case, beside the names logs and
    checkpoints use; the rows come back in the table's order, an unknown one is a one-line error."""
    names = lambda chosen: [r.name for r in chosen]  # noqa: E731
    assert names(select_rows(ablation.ROWS, ["Minsound", "proprioception"])) == ["internal", "proprio"]
    assert names(select_rows(ablation.ROWS, ["PROPRIO", "minsound", "internal"])) == ["internal", "proprio"]
    assert names(select_rows(ablation.ROWS, ["tcn: minsound + palm mic + proprioception"])) == [
        "tcn:internal+external+proprio"
    ]
    assert names(select_rows(bandwidth.ROWS, ["15 kHz", "2.5"])) == ["2.5", "15"]
    assert names(select_rows(properties.ROWS, ["Minsound + Proprioception + Minsight image"])) == [
        "internal+proprio+image"
    ]
    with pytest.raises(UserError) as e:
        select_rows(noise.ROWS, ["Minsound", "audio"])
    assert str(e.value) == (
        "unknown rows ['audio']; choose a row's name or its label, in any case, or a group (all): internal (Minsound), "
        "internal+proprio (Minsound + proprioception), internal+proprio+external (Minsound + proprioception + palm mic)"
    )


def test_a_label_matches_in_any_spacing_around_plus_and_any_order_of_its_inputs():
    """--rows="Minsound+palm mic", and the noise study's "Minsound + proprioception + palm mic" for the
    ablation's "Minsound + palm mic + proprioception"; "TCN: " and "(our step-LayerNorm fusion)" still
    tell rows of the same inputs apart, and no two rows of a study share a label read so."""
    names = lambda rows, *chosen: [r.name for r in select_rows(rows, chosen)]  # noqa: E731
    assert names(ablation.ROWS, "Minsound+palm mic") == ["internal+external"]
    assert names(ablation.ROWS, noise.ROWS[-1].label) == ["internal+external+proprio"]
    assert names(ablation.ROWS, "TCN:proprioception+Minsound + PALM MIC") == ["tcn:internal+external+proprio"]
    assert names(ablation.ROWS, "palm mic+minsound (our step-LayerNorm fusion)") == [
        f"{ablation.STEP_LAYERNORM}:internal+external"
    ]
    assert names(probe.ROWS, "Minsound + Minsight image, frames − session reference") == [
        probing.SESSION + "image+internal"
    ]
    for bad in ("Minsound palm mic", "Minsound + palm", "TCN: Minsound + palm mic"):
        with pytest.raises(UserError, match="unknown rows"):
            select_rows(ablation.ROWS, [bad])
    for rows in (ablation.ROWS, noise.ROWS, bandwidth.ROWS, properties.ROWS, probe.ROWS, day_shift.ROWS):
        assert len({label_key(r.label) for r in rows}) == len(rows)


def test_the_ablation_trains_the_papers_rows_unless_asked_for_a_group():
    """Without --rows the ablation trains the paper's table; "all", "ours" and "paper" name groups in
    any case, beside names and labels; an empty --rows is refused, not read as every row."""
    names = lambda chosen: [r.name for r in chosen]  # noqa: E731
    assert names(ablation.STUDY.select(None)) == names(ablation_rows.PAPER_ROWS)
    assert names(ablation.STUDY.select(["ALL"])) == names(ablation.ROWS)
    assert names(ablation.STUDY.select(["ours"])) == names(ablation_rows.STEP_LAYERNORM_ROWS)
    assert names(ablation.STUDY.select(["ours", "Minsound"])) == ["internal", *names(ablation_rows.STEP_LAYERNORM_ROWS)]
    assert names(select_rows(noise.ROWS, None)) == names(noise.ROWS)
    with pytest.raises(UserError, match="no rows given"):
        ablation.STUDY.select([])
    # a name or label picks one row in every study: no label repeats, or is another row's name
    for rows in (ablation.ROWS, bandwidth.ROWS, noise.ROWS, properties.ROWS, probe.ROWS, day_shift.ROWS):
        keys = [k.casefold() for r in rows for k in {r.name, r.label}]
        assert len(keys) == len(set(keys)), [r.name for r in rows]


# Every study whose rows set `Config` fields, with how to run it (the sweep also needs a grid).
STUDIES_WITH_ROWS = {
    "ablation": (ablation.ROWS, ablation.run),
    "bandwidth": (bandwidth.ROWS, bandwidth.run),
    "noise": (noise.ROWS, noise.run),
    "properties": (properties.ROWS, properties.run),
    "probe": (probe.ROWS, probe.run),
    "sweep": (ablation.ROWS, lambda **kw: sweep.run(grid={"epochs": (1,)}, **kw)),
}


@pytest.mark.parametrize(
    "study, field",
    [(s, f) for s, (rows, _) in STUDIES_WITH_ROWS.items() for f in sorted({f for r in rows for f in r.settings})],
)
def test_an_override_a_study_would_replace_per_row_is_an_error(study, field, tmp_path):
    """--set of a field any of the study's chosen rows sets would be silently replaced, or would
    silently change what a row is (--set=backbone=attention made the ablation's TCN row a
    transformer): it fails in one line naming the field and the rows, before any data is read."""
    settings, run = STUDIES_WITH_ROWS[study]
    with pytest.raises(
        UserError,
        match=f"the {study} study sets {field} per row itself \\((every one of its {len(settings)} rows|rows "
        f".+)\\); choose",
    ) as e:
        run(
            preset="smoke",
            rows=["all"],
            overrides={field: Config.__dataclass_fields__[field].default},
            where=Location(workdir=tmp_path / "nothing", results=tmp_path),
        )
    assert "\n" not in str(e.value)
    assert not (tmp_path / "nothing").exists()


def test_an_override_is_refused_only_where_a_chosen_row_sets_the_field():
    """Our variant's image rows read frames unrotated; the paper's image row alone takes a --set of
    the rotation, a variant run of it."""
    paper_image, ours = ablation.STUDY.select(["image", "step_layernorm:image"])
    assert ours.settings["augment_rotation"] is False and "augment_rotation" not in paper_image.settings
    assert check_overrides("ablation", {"augment_rotation": False}, [paper_image], "") == {"augment_rotation": False}
    with pytest.raises(UserError, match="sets augment_rotation per row itself"):
        check_overrides("ablation", {"augment_rotation": False}, [paper_image, ours], "")


def test_the_override_error_names_the_rows_that_set_the_field():
    rows = [
        RowSpec(n, s, n)
        for n, s in (
            ("a", {"backbone": "tcn", "modalities": ("internal",)}),
            ("b", {"modalities": ("proprio",)}),
            ("c", {"modalities": ("flow",)}),
        )
    ]
    with pytest.raises(UserError) as e:
        check_overrides(
            "toy", {"backbone": "attention", "modalities": ("internal",), "epochs": 1}, rows, "choose them with --rows"
        )
    assert str(e.value) == (
        "the toy study sets backbone per row itself (rows a); modalities per row itself (every one of its 3 rows); "
        "choose them with --rows"
    )
    assert check_overrides("toy", {"epochs": 1}, rows, "") == {"epochs": 1}


def test_the_ablation_row_counts_the_docs_state_are_the_code_s():
    paper, variants = len(ablation_rows.PAPER_ROWS), len(ablation_rows.STEP_LAYERNORM_ROWS)
    tcn = sum(r.settings["backbone"] == "tcn" for r in ablation_rows.PAPER_ROWS)
    assert tcn == 1 and len(ablation.ROWS) == paper + variants
    repo = Path(__file__).parents[1]
    said = {
        "fabricjax/studies/paper/ablation.py": [
            f"{paper - tcn} transformer rows and the TCN row, and {variants} of them again"
        ],
        "fabricjax/studies/__init__.py": [
            f"{paper} rows incl. TCN (Table ablation_table) + {variants} step-LayerNorm variants"
        ],
        "experiments/ablation.py": [f"its {paper} rows and our {variants} fusion-variant rows"],
        "docs/usage.md": [
            f"the paper's {paper - tcn} transformer rows + TCN (`--rows=all` adds {variants} rows again",
            f"8 points x {len(ablation.STUDY.select(None))} rows",
        ],
    }
    for path, texts in said.items():
        text = " ".join((repo / path).read_text().split())
        for t in texts:
            assert t in text, (path, t)


def test_results_say_how_they_were_made():
    assert (
        documents.command_markdown("python -m experiments.noise --seeds=10")
        == "- command: `python -m experiments.noise --seeds=10`"
    )
    assert documents.command_markdown(None) == "- command: none (called from Python)"  # not the test runner's argv


def test_ablation_command_end_to_end(workdir):
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_DISABLE_MOST_OPTIMIZATIONS": "1"}
    cmd = [
        sys.executable,
        "-m",
        "experiments.ablation",
        "--preset=smoke",
        "--seeds=1",
        "--set=epochs=1",
        "--rows=internal",
        f"--workdir={workdir}",
        "--cpu_devices=2",
    ]
    out = subprocess.run(
        cmd, check=True, env=env, cwd=Path(__file__).parents[1], capture_output=True, text=True, timeout=300
    )
    results = workdir / "results"  # the default: under the workspace, not in the repository
    written = ", ".join(
        str(results / f)
        for f in ("ablation.json", "ablation.md", f"ablation{results_files.SAMPLES}", "ablation_time_to_accuracy.png")
    )
    assert out.stdout.strip().splitlines()[-1] == f"wrote {written}"
    doc = json.loads((results / "ablation.json").read_text())
    assert [r["name"] for r in doc["rows"]] == ["internal"] and doc["seeds"] == [0]
    assert doc["machine"]["devices"] == ["cpu:0", "cpu:1"]  # --cpu_devices took effect before JAX started
    assert doc["command"].startswith("python -m experiments.ablation --preset=smoke")
    assert "| Transformer | Minsound |" in (results / "ablation.md").read_text()


@pytest.mark.slow
def test_camera_rows(workdir, tmp_path):
    """Image and optical-flow rows (CNN encoders, rotation augmentation) end to end."""
    doc = ablation.run(n_seeds=2, rows=["image+internal", "flow", "proprio"], **run_kwargs(workdir, tmp_path))
    assert [r["name"] for r in doc["rows"]] == ["flow", "proprio", "image+internal"] and doc[
        "wilcoxon"
    ] is None  # the table's order
    assert (
        doc["dataset"]["layout_s"] > 0
        and "camera inputs laid out for training" in (tmp_path / "ablation.md").read_text()
    )
    assert (tmp_path / "ablation_confusion.png").stat().st_size > 0
    doc = properties.run(n_seeds=1, rows=["internal+proprio+image"], **run_kwargs(workdir, tmp_path))
    out = latents.run(doc["rows"][0]["checkpoint"], where=Location(workdir=workdir, results=tmp_path))
    assert np.isfinite([p["xy"] for p in out["points"]]).all()


# The smallest plan that still has a study that depends on another (latents on properties) and
# one without seeds (the probe); the other studies' own runs are tested above.
SMOKE_PLAN = (
    reproduce_plan.Step("probe", rows=("proprio",)),
    reproduce_plan.Step("bandwidth", 1, ("2.5",)),
    reproduce_plan.Step("properties", 1, ("internal+proprio",)),
    reproduce_plan.Step("latents"),
)


def test_reproduce_runs_every_study_then_skips_what_is_up_to_date(workdir, tmp_path):
    said = []
    kw = dict(
        preset="smoke",
        plan=SMOKE_PLAN,
        overrides=TINY,
        where=Location(workdir=workdir, results=tmp_path),
        say=said.append,
    )
    first = reproduce.run(**kw)
    assert list(first) == [s.study for s in SMOKE_PLAN]
    assert all(f"{s.study:<11} run" in said[0] for s in SMOKE_PLAN)
    assert (
        f"estimated time: none for probe, bandwidth, properties, latents: no earlier run of the smoke preset "
        f"in {tmp_path}" in said[0]
    )
    text = (tmp_path / "REPORT.md").read_text()
    for s in SMOKE_PLAN:
        assert f"## {reproduce_plan.title(s.study)}" in text
    assert (
        text.count("Rerun alone: `python -m experiments.") == 4
        and "`python -m experiments.bandwidth --seeds=1 --preset=smoke --rows=2.5" in text
    )
    assert (
        "`python -m experiments.probe --preset=smoke --rows=proprio --set=" in text
        and "| – (deterministic) | – (not in the paper) |" in text
    )
    assert "--checkpoint=" in text and "![bandwidth.png](bandwidth.png)" in text and "(latents.png)" in text
    # every paper study's checklist is in the report (the probe has none), not counted: smoke checks the install
    assert text.count(findings.NOT_COUNTED) == 3 and "evaluated claims reproduced" not in text
    assert presets.INSTALL_CHECK_NOTE in text.split("\n")[2] and text.count("| not counted (install check) |") == 3
    outputs = {p.name: p.stat().st_ino for p in tmp_path.iterdir() if p.name not in ("REPORT.md", "reproduce.json")}
    assert {
        "probe.md",
        "probe.json",
        "bandwidth.md",
        "bandwidth.png",
        "properties.json",
        "latents.png",
        "latents.md",
    } <= set(outputs)

    said.clear()
    second = reproduce.run(**kw)
    assert all(f"{s.study:<11} skip" in said[0] for s in SMOKE_PLAN) and "run   ~" not in said[0]
    assert second == first  # same keys, wall times and commands: nothing reran
    assert {p.name: p.stat().st_ino for p in tmp_path.iterdir() if p.name in outputs} == outputs  # nothing rewritten
    assert "0 of 4 studies run by this call" in (tmp_path / "REPORT.md").read_text()
    said.clear()
    reproduce.run(**{**kw, "plan": (reproduce_plan.Step("latents"),)})  # alone: keyed on the manifest's property study
    assert "latents     skip" in said[0]
    assert all(f"## {reproduce_plan.title(s.study)}" in (tmp_path / "REPORT.md").read_text() for s in SMOKE_PLAN)


def test_reproduce_keys_follow_what_decides_the_numbers():
    prints = {"code": "c0de", "simulator": "e5", "data": None}
    step = reproduce_plan.Step("noise", 10)
    key = staleness.step_key(step, "default", {}, prints)
    assert key == staleness.step_key(step, "default", {}, dict(prints))
    assert key != staleness.step_key(reproduce_plan.Step("noise", 5), "default", {}, prints)
    assert key != staleness.step_key(step, "smoke", {}, prints)
    assert key != staleness.step_key(step, "default", {"epochs": 3}, prints)
    # other recordings, too
    for name, other in (
        ("code", "other code"),
        ("simulator", "other simulator"),
        ("data", "a" * 16),
    ):
        assert key != staleness.step_key(step, "default", {}, {**prints, name: other}), name
    latents_step = reproduce_plan.Step("latents")
    assert staleness.step_key(latents_step, "default", {}, prints, "props-a") != staleness.step_key(
        latents_step, "default", {}, prints, "props-b"
    )
    assert reproduce_plan.command(step, "default", {"epochs": 3, "modalities": ("internal", "proprio")}, "results") == (
        "python -m experiments.noise --seeds=10 --preset=default --set=epochs=3 "
        "--set=modalities=internal,proprio --results=results"
    )


def test_palm_variance_shares_recover_planted_effects():
    from fabricjax.studies.diagnostics import palm

    rng = np.random.default_rng(0)
    fabric, day = rng.normal(0, 3.0, (6, 1, 1, 1)), rng.normal(0, 1.0, (1, 4, 1, 1))
    x = np.broadcast_to(fabric + day, (6, 4, 3, 2)) + rng.normal(0, 0.01, (6, 4, 3, 2))
    shares = palm.variance_shares(x)
    total = sum(shares[k] for k in ("fabric", "day", "fabric x day", "trial"))
    assert np.allclose(total, 1.0)
    assert np.allclose(
        shares["fabric"] / shares["day"], 6 * 4 * 3 * fabric.var(ddof=0) / (4 * 3 * 6 * day.var(ddof=0)), rtol=1e-2
    )
    assert np.all(shares["trial"] < 1e-3) and np.all(shares["fabric x day"] < 1e-3)
    # a condition effect (the last day is the cafe, 20 dB up) is split off the day effect
    conditions = ["lab", "lab", "lab", "cafe"]
    y = x + np.array([0.0, 0.0, 0.0, 20.0])[None, :, None, None]
    split = palm.variance_shares(y, conditions)
    assert np.allclose(
        sum(split[k] for k in ("fabric", "condition", "day within condition", "fabric x day", "trial")), 1.0
    )
    assert np.all(split["condition"] > 0.8) and np.all(split["day within condition"] < split["condition"] / 20)


def test_palm_physics_on_smoke_scenes(tmp_path):
    """Short scenes: the lab floor and the cafe loudspeaker reach the palm at the paper's 29-31 and
    47-55 dB(A), the thumb's contact is far louder inside Minsound than the fabric is at the palm, and
    the file is written."""
    from fabricjax.studies.diagnostics import palm

    doc = palm.run(preset="smoke", cycles=1, where=Location(results=tmp_path))
    lab, cafe = doc["sources"]["lab"], doc["sources"]["cafe"]
    assert all(29.0 <= v["room floor"]["palm"][-1] <= 31.0 for v in lab.values())
    assert all(47.0 <= v["cafe loudspeaker"]["palm"][-1] <= 55.0 for v in cafe.values())
    for v in lab.values():
        assert v["thumb contact"]["Minsound"][-1] > palm.rubbing_at_palm(v)[-1] + 20
    assert set(doc["shares_all"]["palm"]) >= {"fabric", "condition", "day within condition"}
    text = (tmp_path / "palm_physics.md").read_text()
    assert "Fabric, day and condition" in text and "- code: " in text and "; written " in text and "- machine: " in text


def test_reproduce_writes_the_readme_block_of_a_scratch_copy(workdir, tmp_path):
    """The README beside a results folder gets its results block from the run (and nothing else of
    it changes); the block is what the tracked headline renders, the same numbers as the ablation's table."""
    readme = tmp_path / "README.md"
    before = (Path(__file__).parents[1] / "README.md").read_text()
    readme.write_text(before)
    plan = (reproduce_plan.Step("ablation", 1, ("internal",)), reproduce_plan.Step("probe", rows=("internal",)))
    said = []
    reproduce.run(
        preset="smoke",
        plan=plan,
        overrides=TINY,
        where=Location(workdir=workdir, results=tmp_path / "results", command="test"),
        say=said.append,
    )
    head = json.loads((tmp_path / "results" / reproduce_plan.HEADLINE).read_text())
    block = reproduce_readme.readme_block(head)
    after = readme.read_text()
    assert block in after and f"reproduce: wrote the results block of {readme}" in said
    assert after.split(reproduce_readme.README_BEGIN)[0] == before.split(reproduce_readme.README_BEGIN)[0]
    assert after.split(reproduce_readme.README_END)[1] == before.split(reproduce_readme.README_END)[1]
    [row] = head["rows"]
    assert (
        row["inputs"] == "Minsound"
        and f"| {row['ours'].split(' (')[0]} |" in (tmp_path / "results" / "ablation.md").read_text()
    )
    assert "from `test` on the smoke preset".lower() in block.lower() and "not counted (install check)" in block
    assert not reproduce_readme.write_readme_block(
        tmp_path / "results" / "nothing.md", block
    )  # no README there: nothing written
    assert not (tmp_path / "results" / "nothing.md").exists()


def test_a_rows_time_to_accuracy_is_its_validation_curve_against_its_cumulative_epoch_seconds():
    """The curve the ablation draws: each trained epoch's end (the epochs' wall times summed) beside
    every seed's validation accuracy, epochs the run never trained (every seed stopped) left out."""
    wall = np.array([[3.0, 1.0, 1.0, np.nan]] * 2)
    val = np.array([[0.2, 0.5, 0.6, np.nan], [0.3, 0.4, 0.7, np.nan]])
    row = fake_row("a", np.array([0.6, 0.7]), np.zeros((2, 4), int), range(2))
    row.results.metrics["epochs"] = {curves.WALL_TAG: wall, "val/accuracy/fabric": val}
    seconds, per_seed = row.time_to_accuracy()
    np.testing.assert_array_equal(seconds, [3.0, 4.0, 5.0])
    np.testing.assert_array_equal(per_seed, val[:, :3])


def test_a_change_of_what_presents_numbers_redraws_the_pages_and_trains_nothing(workdir, tmp_path, monkeypatch):
    """Only the code that presents numbers changed (a view's, `source.VIEWS`): reproduce draws the
    training studies' Markdown and figures again from their results JSON, training and reading
    nothing else, and their numbers are the ones it had."""
    plan = (reproduce_plan.Step("bandwidth", 1, ("2.5",)), reproduce_plan.Step("probe", rows=("proprio",)))
    kw = dict(
        preset="smoke",
        plan=plan,
        overrides=TINY,
        where=Location(workdir=workdir, results=tmp_path, command="test"),
        say=lambda s: None,
    )
    reproduce.run(**kw)
    numbers, figure = (tmp_path / "bandwidth.json").read_text(), (tmp_path / "bandwidth.png").stat().st_ino
    probe_page = (tmp_path / "probe.md").stat().st_ino
    unedited, plots = source._executed_hash, "fabricjax.reporting.plots"
    monkeypatch.setattr(source, "_executed_hash", lambda m: "edited" if m == plots else unedited(m))
    monkeypatch.setattr(bandwidth, "TITLE", "PSD bandwidth, drawn again")  # what the edited view would draw
    monkeypatch.setattr(row_training, "train_rows", lambda *a, **k: pytest.fail("a study trained"))
    said = []
    reproduce.run(**{**kw, "say": said.append})
    assert "bandwidth   draw" in said[0] and "probe       run" in said[0]  # the probe has no path but running
    assert "reproduce: bandwidth drawn again from bandwidth.json" in said
    assert (tmp_path / "bandwidth.md").read_text().startswith("# PSD bandwidth, drawn again")
    assert (tmp_path / "bandwidth.png").stat().st_ino != figure and (tmp_path / "probe.md").stat().st_ino != probe_page
    redrawn = json.loads((tmp_path / "bandwidth.json").read_text())
    assert {k: v for k, v in redrawn.items() if k != "figures"} == {
        k: v for k, v in json.loads(numbers).items() if k != "figures"
    }
    said.clear()
    reproduce.run(**{**kw, "say": said.append})  # drawn with today's views: nothing again
    assert all(f"{s.study:<11} skip" in said[0] for s in plan)
