"""Where things live on disk (see WORKSPACE.md). One root, overridable, no hidden global state."""

from __future__ import annotations

import os
from pathlib import Path

ENV_VAR = "FABRICJAX_WORKDIR"


def root(workdir: str | os.PathLike | None = None) -> Path:
    """`workdir` if given, else $FABRICJAX_WORKDIR, else ./workspace."""
    return Path(workdir or os.environ.get(ENV_VAR) or "workspace").expanduser()


def dataset_dir(preset: str, workdir=None, data_dir=None) -> Path:
    """A real recorded dataset (`data_dir`) wins over the simulated one of `preset`."""
    return Path(data_dir).expanduser() if data_dir else root(workdir) / "datasets" / preset


def features_dir(workdir=None) -> Path:
    return root(workdir) / "features"


def checkpoints_dir(name: str, workdir=None) -> Path:
    return (root(workdir) / "checkpoints" / name).absolute()


def results_dir(results=None) -> Path:
    p = Path(results or "results")
    p.mkdir(parents=True, exist_ok=True)
    return p
