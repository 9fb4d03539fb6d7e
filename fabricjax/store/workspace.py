"""Where things live on disk (see WORKSPACE.md). One root, overridable, no hidden global state."""

from __future__ import annotations

import dataclasses
import hashlib
import os
from pathlib import Path

ENV_VAR = "FABRICJAX_WORKDIR"
INDEX_NAME = "index.json"


@dataclasses.dataclass(frozen=True)
class Location:
    """Where a run reads and writes, and the command its results files record. Every default is the
    workspace's: `Location()` reads the preset's simulated dataset and writes <workspace>/results."""

    workdir: str | os.PathLike | None = None  # the workspace root (`root`)
    data_dir: str | os.PathLike | None = (
        None  # recorded trial archives, only read; None: the preset's simulated dataset
    )
    results: str | os.PathLike | None = None  # where results files go; None: <workspace>/results
    command: str | None = None  # the command line that started the run; None: called from Python

    def results_dir(self) -> Path:
        """The results folder (`results_dir`)."""
        return results_dir(self.results, self.workdir)


def root(workdir: str | os.PathLike | None = None) -> Path:
    """`workdir` if given, else $FABRICJAX_WORKDIR, else ./workspace."""
    return Path(workdir or os.environ.get(ENV_VAR) or "workspace").expanduser()


def dataset_dir(preset: str, workdir=None, data_dir=None) -> Path:
    """A real recorded dataset (`data_dir`) wins over the simulated one of `preset`."""
    return Path(data_dir).expanduser() if data_dir else root(workdir) / "datasets" / preset


def index_file(dataset, workdir=None) -> Path:
    """Where a dataset folder's index lives: beside the archives for the simulator's own datasets
    (`<root>/datasets/...`), else `<root>/indexes/<folder name>-<hash of its resolved path>.json`.
    A folder of recordings we are asked to read may be read-only, shared or under version control,
    so nothing is ever written into it, wherever it lies (inside the workspace too)."""
    folder = Path(dataset).expanduser().resolve()
    if folder.is_relative_to((root(workdir) / "datasets").resolve()):
        return folder / INDEX_NAME
    return root(workdir) / "indexes" / f"{folder.name}-{hashlib.sha256(str(folder).encode()).hexdigest()[:16]}.json"


def shown(path: str | os.PathLike) -> str:
    """`path` as results files and the commands they print name it: relative to the working
    directory when it lies inside it (`workspace/checkpoints/...` from the repository root), so a
    published command runs on any machine from the same folder; else as given."""
    p = Path(path).expanduser()
    try:
        return str(p.absolute().relative_to(Path.cwd()))
    except ValueError:
        return str(p)


def features_dir(workdir=None) -> Path:
    return root(workdir) / "features"


def sequences_dir(workdir=None) -> Path:
    """Loaded sequences too large for memory, as memory-mapped files (`fabricjax.sequences.sequence_store`)."""
    return root(workdir) / "sequences"


def checkpoints_dir(name: str, workdir=None) -> Path:
    return (root(workdir) / "checkpoints" / name).absolute()


def logs_dir(study: str, row: str, workdir=None) -> Path:
    """A study row's training curves (TensorBoard event files, one folder per seed, see
    `fabricjax.training.curves`): the latest run of the row, whatever its settings."""
    return (root(workdir) / "logs" / study / row).absolute()


def results_dir(results=None, workdir=None) -> Path:
    """`results` if given, else <root>/results. Runs write there, outside the repository; the tables
    published in the repository are regenerated with `--results=results`. The folder is made by the
    first file written into it (`atomic.atomic_open`), so a command refused before it writes leaves none."""
    return Path(results) if results else root(workdir) / "results"


def compilation_cache_dir(workdir=None) -> Path:
    return (root(workdir) / "jax_cache").absolute()
