"""The linear probe without a dataset: its summaries, a planted cue it must find and noise it must
not, and its table beside the ablation's in REPORT.md (the study on the smoke preset, its
command, --data_dir and reproduce are in test_studies.py)."""

import json

import numpy as np
import pytest

from fabricjax.studies.machinery import findings, linear_probe, probing
from fabricjax.studies.diagnostics import probe
from fabricjax.studies.paper import ablation
from fabricjax.studies.pages import probe as probe_page
from fabricjax.studies.release import reproduce_plan, reproduce_report

N_CLASSES, PER_CLASS, N_STEPS = 6, 60, 10
SPLIT_SEEDS = {"train": 1, "val": 2, "test": 3}


def test_rows_are_the_ablations_distinct_input_sets_in_its_order():
    paper = [r.name for r in ablation.ROWS if not r.name.startswith(("tcn:", ablation.STEP_LAYERNORM))]
    # then every input set with the image again, its frames read against their session's reference,
    # and the image alone once more, its training frames rotated as the paper's training rotates them
    assert [r.name for r in probe.ROWS] == paper + [probing.SESSION + n for n in paper if "image" in n.split("+")] + [
        probing.ROTATED + "image"
    ]
    rows = [
        {
            "modalities": list(p.modalities),
            **({"image_reference": p.settings["image_reference"]} if "image_reference" in p.settings else {}),
        }
        for p in probe.ROWS
    ]
    for (
        r
    ) in ablation.ROWS:  # every ablation row, the TCN and fusion variants included, has its probe under either reading
        for reference in ("none", "training_mean", "session"):
            p = probing.row_for(r.modalities, rows, reference)
            assert p is not None and probing.reading(p.get("image_reference")) == (
                probing.reading(reference) if "image" in r.modalities else "frame"
            )


def test_a_row_trained_rotated_is_set_beside_the_rotated_probe_where_there_is_one():
    rows = [
        {"modalities": ["image"], "image_reference": "session"},
        {"modalities": ["image"], "image_reference": "session", "rotated": True},
        {"modalities": ["image", "internal"], "image_reference": "session"},
    ]
    assert probing.row_for(["image"], rows, "session") is rows[0]
    assert probing.row_for(["image"], rows, "session", rotated=True) is rows[1]
    assert probing.row_for(["internal", "image"], rows, "session", rotated=True) is rows[2]  # no rotated probe


def test_rotated_summaries_turn_each_sequence_by_one_angle_for_all_its_frames(monkeypatch):
    monkeypatch.setattr(linear_probe, "SUMMARY_CHUNK", 3)  # several chunks and a partial last one
    rng = np.random.default_rng(0)
    h, w = 12, 16
    yy, xx = np.mgrid[:h, :w]
    disc = ((yy - (h - 1) / 2) ** 2 + (xx - (w - 1) / 2) ** 2 <= 4**2).astype(np.int16)
    # a centred disc whose brightness changes from frame to frame, plus a bar off the centre
    frames = np.zeros((7, 5, h, w, 3), np.int16)
    frames += (disc[None, None, :, :, None] * rng.integers(50, 100, (7, 5, 1, 1, 1))).astype(np.int16)
    frames[:, :, 1:3, 1:5] = 80
    got = linear_probe.summarise_rotated(frames, draws=2)
    plain = linear_probe.summarise(frames)
    assert got.shape == (14, plain.shape[1]) and got.dtype == np.float32
    d = h * w * 3
    core = ((yy - (h - 1) / 2) ** 2 + (xx - (w - 1) / 2) ** 2 <= 2.5**2).reshape(-1, 1) * np.ones(3)
    core = np.tile(core.reshape(-1).astype(bool), 2)
    for draw in range(2):  # the disc's core is where it was, whatever the angle; the bar has moved
        np.testing.assert_allclose(got[draw * 7 : (draw + 1) * 7][:, core], plain[:, core], rtol=1e-4, atol=1e-3)
    bar = np.zeros((h, w, 3), bool)
    bar[1:3, 1:5] = True
    moved = np.abs(got[:, :d][:, bar.reshape(-1)] - np.tile(plain[:, :d][:, bar.reshape(-1)], (2, 1))).max(axis=1)
    assert (moved > 1).mean() > 0.8  # almost every draw moves the bar
    assert not np.allclose(got[:7], got[7:])  # the two draws' angles differ


def test_summaries_are_the_mean_and_sd_over_steps_of_every_dimension(monkeypatch):
    monkeypatch.setattr(linear_probe, "SUMMARY_CHUNK", 2)  # several chunks and a partial last one
    rng = np.random.default_rng(0)
    for x in (
        rng.integers(0, 256, (5, 4, 3, 2, 3), dtype=np.uint8),
        rng.normal(size=(5, 4, 2, 3, 2)).astype(np.float16),
    ):
        flat = x.reshape(5, 4, -1).astype(np.float64)
        got = linear_probe.summarise(x)
        assert got.dtype == np.float32 and got.shape == (5, 2 * flat.shape[2])
        np.testing.assert_allclose(got, np.concatenate([flat.mean(1), flat.std(1)], axis=1), rtol=1e-5, atol=1e-5)
    assert linear_probe.summarise(np.zeros((0, 4, 18), np.float32)).shape == (0, 36)  # an empty split
    assert np.isfinite(linear_probe.summarise(np.full((3, 1, 5), 7.0, np.float32))).all()  # one step: SD 0, finite


def _stream(split: str, level: float) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Sequences of two inputs, noise plus a level `level` (in noise SDs) that class k plants in
    its own place: proprioception-shaped (18 dims per step, class k in dimension k) and
    image-shaped (12x16x3 = 576 dims, wider than PCA_ABOVE; class k brightens its own 4x4 patch)."""
    rng = np.random.default_rng(SPLIT_SEEDS[split])
    labels = np.repeat(np.arange(N_CLASSES), PER_CLASS)
    idx = np.arange(len(labels))
    proprio = rng.normal(size=(len(labels), N_STEPS, 18)).astype(np.float32)
    proprio[idx, :, labels] += level
    image = rng.normal(120.0, 30.0, size=(len(labels), N_STEPS, 12, 16, 3))
    for k in range(N_CLASSES):
        row, col = divmod(k, 4)
        image[labels == k, :, 4 * row : 4 * row + 4, 4 * col : 4 * col + 4, :] += 30.0 * level
    return {"proprio": proprio, "image": np.clip(image, 0, 255).astype(np.uint8)}, labels


def _probe(level: float, modality: str) -> dict:
    streams = {s: _stream(s, level) for s in SPLIT_SEEDS}
    inp = linear_probe.prepare({s: x[modality] for s, (x, _) in streams.items()})
    assert (inp.explained_variance is not None) == (modality == "image")  # the image input goes through the PCA
    return linear_probe.fit(inp.features, {s: y for s, (_, y) in streams.items()})


@pytest.mark.parametrize("modality", ["proprio", "image"])
def test_a_planted_class_level_is_found_and_pure_noise_is_at_chance(modality):
    chance = 1 / N_CLASSES
    planted = _probe(1.0, modality)
    assert planted["accuracy"]["test"] > 0.9, planted["accuracy"]
    noise = _probe(0.0, modality)
    n_test = N_CLASSES * PER_CLASS
    assert abs(noise["accuracy"]["test"] - chance) < 5 * np.sqrt(chance * (1 - chance) / n_test), noise["accuracy"]
    assert noise["accuracy"]["train"] > noise["accuracy"]["test"]  # the noise is fitted on train, and read nowhere else
    assert [e["C"] for e in planted["per_c"]] == sorted(linear_probe.C_GRID) and planted["C"] in linear_probe.C_GRID
    assert planted["accuracy"]["val"] == max(e["accuracy"]["val"] for e in planted["per_c"])
    assert len(planted["predictions"]["test"]) == n_test and "train" not in planted["predictions"]


def _ablation_row(name, test, predictions=None):
    r = next(r for r in ablation.ROWS if r.name == name)
    return {
        "name": name,
        "modalities": list(r.modalities),
        "display_name": ablation.display_name(name),
        "accuracy": {"test": {"fabric": test}},
        "collapsed": {"test": findings.collapsed(predictions or [[0, 1, 2, 3]] * len(test))},
    }


PROBE_DOC = {
    "preset": "default",
    "dataset": {"folder": "/w/datasets/default", "source": "simulated"},
    "rows": [
        {"name": "internal", "modalities": ["internal"], "accuracy": {"test": 0.65}, "collapsed": {"test": [1]}},
        {
            "name": "internal+external+proprio",
            "modalities": ["internal", "external", "proprio"],
            "accuracy": {"test": 0.75},
        },
    ],
}
ABLATION_DOC = {
    "preset": "default",
    "dataset": {"folder": "/w/datasets/default", "source": "simulated"},
    "seeds": [0, 1],
    "rows": [
        _ablation_row("internal", [0.8, 0.9]),
        _ablation_row("proprio", [0.4, 0.4], [[5] * 4] * 2),
        _ablation_row("tcn:internal+external+proprio", [0.7, 0.7]),
        _ablation_row(f"{ablation.STEP_LAYERNORM}:internal+external+proprio", [0.8, 0.8]),
    ],
}


def test_the_probe_sits_beside_every_ablation_row_with_the_difference():
    lines = probe_page.beside_ablation(PROBE_DOC, ABLATION_DOC).splitlines()
    assert lines[0] == "| Ablation row | Linear probe, test [%] | Model, test [%] (2 seeds) | Model − probe [pp] |"
    assert (
        lines[2] == "| Minsound | 65.00 (collapsed to class 1) | 85.00 ± 7.07 | +20.00 |"
    )  # a probe predicting one class says so
    assert (
        lines[3] == "| proprioception | – | 40.00 ± 0.00 (collapsed to class 5: 2 of 2 seeds) | – |"
    )  # not probed in this run
    assert (
        lines[4] == "| TCN: Minsound + palm mic + proprioception | 75.00 | 70.00 ± 0.00 | -5.00 |"
    )  # the TCN row, same inputs
    assert (
        lines[5]
        == "| Minsound + palm mic + proprioception (our step-LayerNorm fusion) | 75.00 | 80.00 ± 0.00 | +5.00 |"
    )
    text = "\n".join(lines)
    assert "2 of 3 rows at or above their probe's test accuracy" in text and "Not the same data" not in text
    other = {**PROBE_DOC, "preset": "smoke", "dataset": {"folder": "/w/datasets/smoke"}}
    assert (
        "**Not the same data**: ablation on default `/w/datasets/default`, probe on smoke"
        in probe_page.beside_ablation(other, ABLATION_DOC)
    )


def test_report_sets_the_probe_beside_the_ablation_from_their_json(tmp_path):
    for study, doc in (("ablation", ABLATION_DOC), ("probe", PROBE_DOC)):
        (tmp_path / f"{study}.json").write_text(
            json.dumps(
                {
                    **doc,
                    "machine": {
                        "cpu": "x",
                        "cores": 2,
                        "platform": "p",
                        "python": "3",
                        "jax_backend": "cpu",
                        "devices": [],
                    },
                }
            )
        )
        (tmp_path / f"{study}.md").write_text(f"# {study}\n\n{study} table\n")
    manifest = {
        s: {"wall_s": 60.0, "finished": "today", "command": f"python -m experiments.{s}"} for s in ("ablation", "probe")
    }
    text = reproduce_report.write_report(tmp_path / "REPORT.md", manifest, "default", None, "test", 1.0, 2).read_text()
    assert (
        text.index("## Modality ablation")
        < text.index("## Linear probe")
        < text.index("### The probe beside the model, row by row")
    )
    assert "| Minsound | 65.00 (collapsed to class 1) | 85.00 ± 7.07 | +20.00 |" in text
    assert "| – (deterministic) | – (not in the paper) |" in text  # the summary line of the probe
    (tmp_path / "ablation.json").unlink()
    del manifest["ablation"]
    assert (
        "beside the model"
        not in reproduce_report.write_report(
            tmp_path / "REPORT.md", manifest, "default", None, "test", 1.0, 1
        ).read_text()
    )


def test_reproduce_runs_the_probe_without_seeds():
    step = next(s for s in reproduce_plan.PLAN if s.study == "probe")
    assert step.seeds is None and reproduce_plan.PLAN.index(step) == 1  # right after the ablation
    assert (
        reproduce_plan.command(step, "default", {"epochs": 3}, "results")
        == "python -m experiments.probe --preset=default --set=epochs=3 --results=results"
    )
    recorded = {"probe": {"preset": "default", "seeds": None, "rows": len(probe.ROWS), "wall_s": 60.0}}
    assert (
        reproduce_plan.estimate_s(step, "default", {}, recorded) == 60.0
    )  # the first manifest that recorded the preset
    assert reproduce_plan.estimate_s(
        reproduce_plan.Step("probe", rows=("proprio",)), "default", recorded
    ) == pytest.approx(60.0 / len(probe.ROWS))
    assert reproduce_plan.estimate_s(step, "smoke", recorded) is None
