"""The plan a study prints before it starts (fabricjax/studies/common/plan.py)."""

import dataclasses
import json

from fabricjax import presets
from fabricjax.config import Config
from fabricjax.sim import dataset as sim_dataset
from fabricjax.studies.common import plan


def rows(preset, *modalities):
    return [("+".join(m), Config.from_preset(preset, modalities=m)) for m in modalities]


def test_missing_trials_are_timed_on_this_host_and_their_disk_counted(tmp_path):
    spec = presets.get("smoke").dataset
    stages = plan.stages("smoke", rows("smoke", ("internal",), ("flow", "internal")), 2, tmp_path)
    sim, features, sequences, training = stages
    n = len(spec.trials())
    assert sim.name.startswith(f"simulation ({n} of {n} trials missing)") and sim.seconds > 0
    assert sim.disk_bytes == n * sim_dataset.trial_bytes(spec, True)
    assert features.seconds > 0 and features.disk_bytes > 0 and "flow " in features.basis
    assert "does not fit" in plan.markdown("smoke", stages, 2, 2, free_bytes=1)
    assert sequences.disk_bytes == 0 and "held in memory" in sequences.basis
    assert training.seconds is None  # no published run of this recipe
    assert "peak host memory" in sequences.basis
    text = plan.markdown("smoke", stages, 2, 2, free_bytes=1e15)
    assert text.startswith("Plan: 2 rows x 2 seeds on preset 'smoke'") and "and more (a stage is unknown)" in text


def test_training_is_extrapolated_from_the_published_sample_per_row(tmp_path, monkeypatch):
    """Seconds per sequence, epoch and seed of the same row and recipe, times this run's counts, plus its compilation."""
    sample = Config.from_preset("paper_sample", modalities=("internal",))
    doc = {
        "machine": {"cpu": "AMD EPYC", "cores": 2}, "date": "2026-11-27", "dataset": {"sequences": {"train": 70}},
        "rows": [{"name": "internal", "config": dataclasses.replace(sample, n_classes=5).to_json(), "seeds": [0, 1],
                  "wall_s": 10.0 + 70 * sample.epochs * 2 * 0.01, "time": {"compile_s": 10.0}}],
    }
    path = tmp_path / "ablation.json"
    path.write_text(json.dumps(doc))
    monkeypatch.setattr(plan, "SAMPLE_RESULTS", path)
    training = plan._training(rows("paper", ("internal",)), 5, 1000)
    assert abs(training.seconds - (10.0 + 1000 * sample.epochs * 5 * 0.01)) < 1e-6 and "AMD EPYC" in training.basis
    assert plan._training(rows("default", ("internal",)), 5, 1000).seconds is None  # another recipe: not extrapolated
