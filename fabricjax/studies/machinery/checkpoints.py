"""Where a trained row's models are kept: one folder per row, config, seeds, data and code."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Mapping, Sequence

from fabricjax import source
from fabricjax.config import Config
from fabricjax.store import workspace
from fabricjax.training import checkpoint


def checkpoint_dir(
    study: str, row: str, config: Config, seeds: Sequence[int], dataset: Mapping[str, str], workdir=None
) -> Path:
    """A checkpoint directory per (row, config, seeds, data, code): reruns resume; other settings,
    other data (`dataset`: `DatasetIndex.identity`, by content) or other code (`source.training`)
    start afresh instead of reusing what was trained on something else."""
    key = f"{config.dumps()}{list(seeds)}{checkpoint.STATE_VERSION}{dataset.get('content')}{source.training()}"
    return workspace.checkpoints_dir(f"{study}/{row}-{hashlib.sha1(key.encode()).hexdigest()[:8]}", workdir)
