"""The plan a study prints before it starts (fabricjax/studies/machinery/plan.py)."""

import dataclasses
import json

import pytest

from fabricjax import catalog, presets
from fabricjax.config import Config
from fabricjax.sim import dataset as sim_dataset
from fabricjax.studies.machinery import plan


def rows(preset, *modalities):
    return [("+".join(m), Config.from_preset(preset, modalities=m)) for m in modalities]


def test_missing_trials_are_timed_on_this_host_and_their_disk_counted(tmp_path):
    spec = presets.get("smoke").dataset
    stages = plan.stages("smoke", rows("smoke", ("internal",), ("flow", "internal")), 2, tmp_path)
    sim, features, sequences, *training = stages
    n = len(spec.trials())
    assert sim.name.startswith(f"simulation ({n} of {n} trials missing)") and sim.seconds > 0
    assert sim.disk_bytes == n * sim_dataset.trial_bytes(spec, True)
    assert features.seconds > 0 and features.disk_bytes > 0 and "flow " in features.basis
    assert "does not fit" in plan.markdown("smoke", stages, 2, 2, free_bytes=1)
    assert sequences.disk_bytes == 0 and "held in memory" in sequences.basis
    assert len(training) == 2 and all(
        t.seconds is None for t in training
    )  # one stage per row; no published run of this model
    assert "peak host memory" in sequences.basis
    text = plan.markdown("smoke", stages, 2, 2, free_bytes=1e15)
    assert (
        text.startswith("Plan: 2 rows x 2 seeds on preset 'smoke'")
        and "stages unknown before the run (below), the others about" in text
    )


def test_training_is_extrapolated_from_the_published_sample_per_row(tmp_path, monkeypatch):
    """Seconds per sequence, epoch and seed of a published row of the same inputs and model, times
    this run's counts and grid points, plus their compilation; another model is not extrapolated."""
    sample = Config.from_preset("paper_sample", modalities=("internal",))
    doc = {
        "machine": {"cpu": "AMD EPYC", "cores": 2},
        "date": "2026-11-27",
        "dataset": {"sequences": {"train": 70}},
        "rows": [
            {
                "name": "internal",
                "config": dataclasses.replace(sample, n_classes=5).to_json(),
                "seeds": [0, 1],
                "wall_s": 10.0 + 70 * sample.epochs * 2 * 0.01,
                "time": {"compile_s": 10.0},
            }
        ],
    }
    path = tmp_path / "ablation.json"
    path.write_text(json.dumps(doc))
    monkeypatch.setattr(plan, "SAMPLE_RESULTS", path)
    monkeypatch.setattr(plan, "REPRODUCE_MANIFEST", tmp_path / "absent.json")
    (training,) = plan.training(rows("paper", ("internal",)), 5, 1000)
    assert abs(training.seconds - (10.0 + 1000 * sample.epochs * 5 * 0.01)) < 1e-6 and "AMD EPYC" in training.source
    assert plan.training(rows("default", ("internal",)), 5, 1000)[0].seconds is None  # another model: not extrapolated
    grid = dataclasses.replace(
        Config.from_preset("paper", modalities=("internal",)), lr_grid=(1e-3, 3e-3), width_grid=(32, 64)
    )
    (fitted,) = plan.training([("internal", grid)], 5, 1000)
    assert abs(fitted.seconds - 4 * training.seconds) < 1e-6 and "4 grid points" in fitted.basis


def test_the_published_manifest_gives_each_rows_rate_and_a_step_budget_its_epochs(tmp_path, monkeypatch):
    """A row of the default preset's fitted recipe: at most the epochs that cover its step budget
    on this run's sequences, at the rate the published reproduce manifest recorded for its inputs."""
    config = Config.from_preset("default", modalities=("proprio",))
    doc = {
        "dataset": {"sequences": {"train": 1600}},
        "rows": [
            {
                "config": config.to_json(),
                "seeds": [0, 1],
                "wall_s": 5.0 + 1600 * 3 * 2 * 1e-4,
                "time": {"compile_s": 5.0},
                "recipe": {"grid": [{"epochs_trained": [2, 3]}]},
            }
        ],
    }
    manifest = {
        "ablation": {"rates": plan.rates(doc), "machine": "AMD EPYC, 2 cores", "finished": "2026-11-27 12:00 UTC"}
    }
    (tmp_path / "reproduce.json").write_text(json.dumps(manifest))
    monkeypatch.setattr(plan, "REPRODUCE_MANIFEST", tmp_path / "reproduce.json")
    monkeypatch.setattr(plan, "SAMPLE_RESULTS", tmp_path / "absent.json")
    (stage,) = plan.training([("proprio", config)], 5, 1600)
    epochs = -(-config.train_steps // (1600 // config.batch_size))
    assert abs(stage.seconds - (5.0 + 1e-4 * 1600 * epochs * 5)) < 1e-6
    assert f"at most {epochs} epochs" in stage.basis and "AMD EPYC" in stage.source
    said = plan.markdown("default", [stage, stage], 2, 5, free_bytes=1e15)
    assert said.count("AMD EPYC") == 1 and said.endswith(f"Training rates as measured by {stage.source}.")


def test_each_feature_says_its_bytes_per_step():
    """`Feature.step_bytes` is one step of the array the feature computes, for every camera reading
    and a microphone window other than the paper's: what the plan sizes the cache and sequences by."""
    import types

    from fabricjax.features import extract
    from fabricjax.sim.trial import simulate

    spec = dataclasses.replace(presets.get("smoke").dataset, cycles_per_trial=1)
    trial = simulate(sim_dataset.scene_for(spec.trials()[0], spec, ("audio", "proprio", "images")))
    frames = types.SimpleNamespace(images=trial.images[:3], reference=trial.reference)
    features = [extract.feature_for("internal", window=1024)]
    for reference in ("session", "none"):
        for resolution in ("down", "full"):
            config = Config.from_preset(
                "smoke",
                modalities=("internal", "proprio", "flow", "image"),
                image_reference=reference,
                image_resolution=resolution,
            )
            features += extract.features_for(config).values()
    for f in features:
        computed = f.compute(frames if f.needs_images else trial)
        assert computed[0].nbytes == f.step_bytes(spec.image_size), f.name


def test_the_training_sequences_are_those_the_splits_train_on(tmp_path, monkeypatch):
    """The plan counts the trials `splits` and `data` put in the training split: a fabric the rows
    exclude (the property holdouts) trains on none, and a day of one trial keeps it for training."""
    from fabricjax.store import splits

    spec = presets.get("smoke").dataset
    counted = {}

    def training(configs, n_seeds, train_sequences):
        counted[configs[0][1].exclude_fabrics] = train_sequences
        return []

    monkeypatch.setattr(plan, "probe", lambda dataset, config: {"simulate": 0.0})
    monkeypatch.setattr(plan, "training", training)
    for exclude in ((), (spec.fabrics[0],)):
        plan.stages(
            "smoke",
            [("internal", Config.from_preset("smoke", modalities=("internal",), exclude_fabrics=exclude))],
            2,
            tmp_path,
        )
    trained = [f for f in spec.fabrics if f not in catalog.NEW_FABRICS]  # the new fabrics are only tested
    per_fabric = counted[()] // len(trained)
    assert counted[()] == per_fabric * len(trained) > 0
    assert counted[(spec.fabrics[0],)] == counted[()] - per_fabric
    one = dataclasses.replace(spec, train_trials_per_day=1)
    roles = [
        role
        for meta, role in splits.dataset_roles(one)
        if meta["condition"] == "lab" and meta["day"] in one.splits.train_days
    ]
    assert roles and set(roles) == {"train"}


def test_the_paper_presets_rows_say_early_stopping_only_when_it_is_on(tmp_path, monkeypatch):
    monkeypatch.setattr(
        plan,
        "_published_rates",
        lambda: [
            (
                "a run",
                {
                    plan.rate_key(c.to_json()): {"per_unit_s": 1e-3, "compile_s": 1.0}
                    for _, c in rows("paper", ("internal",))
                },
            )
        ],
    )
    config = rows("paper", ("internal",))[0][1]
    (off,) = plan.training([("internal", dataclasses.replace(config, patience=0, patience_steps=0))], 2, 100)
    (on,) = plan.training([("internal", dataclasses.replace(config, patience=3))], 2, 100)
    assert "early stopping" not in off.basis and "(early stopping ends sooner)" in on.basis


def test_a_row_with_early_stopping_is_planned_at_the_epochs_its_published_run_went_through(monkeypatch):
    """The cap of a row's epochs overstates a run that stops early: where its published rate says
    how many epochs the row went through under the same cap, the plan counts those, and says so;
    under another cap (other data, another budget), the cap."""
    config = dataclasses.replace(rows("paper", ("internal",))[0][1], epochs=13, patience=3)
    rate = {"per_unit_s": 1e-3, "compile_s": 1.0, "epochs_run": 9.0, "epochs_cap": 13}
    monkeypatch.setattr(plan, "_published_rates", lambda: [("a run", {plan.rate_key(config.to_json()): rate})])
    (stage,) = plan.training([("internal", config)], 2, 100)
    assert stage.seconds == pytest.approx(1.0 + 1e-3 * 100 * 9 * 2)
    assert "9 epochs as it ran when published (at most 13)" in stage.basis
    (capped,) = plan.training([("internal", dataclasses.replace(config, epochs=5))], 2, 100)
    assert capped.seconds == pytest.approx(1.0 + 1e-3 * 100 * 5 * 2) and "at most 5 epochs" in capped.basis


def test_the_peak_memory_counts_minsight_frames_again_as_trainings_rows(tmp_path):
    """Training holds an image row's frames twice (as loaded and as pixel rows): the plan's peak says
    so and counts both; without image rows the peak is the loaded sequences."""
    with_image = plan.stages("smoke", rows("smoke", ("image", "internal")), 1, tmp_path)[2]
    without = plan.stages("smoke", rows("smoke", ("internal",)), 1, tmp_path)[1]
    assert "Minsight frames a second time" in with_image.basis and "second time" not in without.basis
