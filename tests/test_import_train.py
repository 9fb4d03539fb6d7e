"""Imported recordings are a dataset like any other: a smoke-preset study trains on bags imported
for every trial the preset names."""

import numpy as np
import pytest

from fabricjax import presets
from fabricjax.importers import ros_bag
from fabricjax.store import archive
from fabricjax.store.workspace import Location
from fabricjax.studies.paper import ablation

pytest.importorskip("rosbags")

from tests.test_import_bag import MAPPING, recording, write_bag  # noqa: E402


@pytest.mark.slow  # ~25 s: 31 bags and one training run
def test_smoke_study_trains_on_imported_bags(tmp_path):
    data = tmp_path / "imported"
    for i, spec in enumerate(presets.get("smoke").dataset.trials()):
        bag = write_bag(tmp_path / "bags" / f"b{i}", recording(seed=i, n_frames=30))
        trial = {"fabric_id": spec.fabric_id, "day": spec.day, "trial": spec.trial, "condition": spec.condition}
        a = ros_bag.import_bag(bag, MAPPING, trial)
        archive.write_archive(data / archive.trial_filename(a.meta), a)
    doc = ablation.run(
        n_seeds=1,
        rows=["internal"],
        preset="smoke",
        overrides=dict(epochs=1, width=16, n_layers=1),
        where=Location(workdir=tmp_path / "ws", data_dir=data, results=tmp_path / "results", command="test"),
    )
    acc = doc["rows"][0]["accuracy"]["test"]["fabric"]
    assert len(acc) == 1 and np.isfinite(acc).all()


@pytest.mark.slow  # ~45 s: 31 MCAP bags resampled from 16 kHz, one training run
def test_smoke_study_trains_on_bags_recorded_as_a_ros2_lab_records(tmp_path):
    from tests.test_import_bag import write_messages
    from tests.test_ros_bags import LAB_MAPPING, lab_messages

    data = tmp_path / "imported"
    for i, spec in enumerate(presets.get("smoke").dataset.trials()):
        bag = write_messages(tmp_path / "bags" / f"b{i}", lab_messages(seed=i), storage="mcap")
        trial = {"fabric_id": spec.fabric_id, "day": spec.day, "trial": spec.trial, "condition": spec.condition}
        a = ros_bag.import_bag(bag, LAB_MAPPING, trial, resample=True)
        archive.read_archive(archive.write_archive(data / archive.trial_filename(a.meta), a))
    doc = ablation.run(
        n_seeds=1,
        rows=["internal"],
        preset="smoke",
        overrides=dict(epochs=1, width=16, n_layers=1),
        where=Location(workdir=tmp_path / "ws", data_dir=data, results=tmp_path / "results", command="test"),
    )
    acc = doc["rows"][0]["accuracy"]["test"]["fabric"]
    assert len(acc) == 1 and np.isfinite(acc).all()
