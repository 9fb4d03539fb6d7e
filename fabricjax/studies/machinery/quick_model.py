"""A quick model of a preset: one seed trained once and checkpointed, for a command that needs a
model and was given no checkpoint (the live stream, the decision study).
"""

from __future__ import annotations

from typing import Any, Mapping

from fabricjax.config import Config
from fabricjax.studies.machinery import loading, row_training
from fabricjax.studies.machinery.checkpoints import checkpoint_dir

# The quick model's inputs unless overridden: both microphones, what the streamer updates per step.
QUICK_MODALITIES = ("internal", "external")


def quick_model(preset: str, overrides: Mapping[str, Any] | None = None, *, workdir=None, data_dir=None):
    """(graphdef, params, config, checkpoint dir): one seed of the preset's config (inputs
    `QUICK_MODALITIES`, `overrides` on top), trained on its dataset and checkpointed, so a rerun
    restores it instead of training again."""
    config = Config.from_preset(preset, **{"modalities": QUICK_MODALITIES, **(overrides or {})})
    ds = loading.load_dataset(config, data_dir=data_dir, workdir=workdir)
    config = ds.config_for(config)  # the data's classes and step window
    directory = checkpoint_dir("stream", "quick", config, [0], ds.sets["train"].dataset, workdir)
    row = row_training.train_row(
        "quick", config, row_training.place_row(config, ds.sets, []), [0], checkpoint_dir=directory
    )
    return row.results.graphdef, row.results.params(0), config, directory
