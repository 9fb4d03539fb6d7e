"""Flags shared by the study commands; every sweep dimension is a flag.

    --seeds --preset --rows --backbone --seq_len --bandwidth --epochs   (define_sweep)
    --workdir --data_dir --results --cpu_devices                        (always)

Unset sweep flags keep the study's defaults (`fabricjax.studies.common.PRESET_TRAINING`).
Results go to <workspace>/results unless --results says otherwise, so a run leaves the repository
clean; `--results=results` regenerates the tables published in the repository.
"""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any, Callable, Sequence

from absl import flags

from fabricjax import cli, runtime, splits, workspace
from fabricjax.config import BACKBONES
from fabricjax.studies import common

FLAGS = flags.FLAGS

flags.DEFINE_string("workdir", None, "workspace root: datasets, features, checkpoints (default $FABRICJAX_WORKDIR or ./workspace)")
flags.DEFINE_string(
    "data_dir", None,
    "a folder of real recorded trial archives, only read (its index is kept under the workspace); default: the preset's simulated dataset",
)
flags.DEFINE_string(
    "results", None,
    "where <study>.md/.json and figures are written (default: <workspace>/results; --results=results regenerates "
    "the tables published in the repository)",
)
flags.DEFINE_integer(
    "cpu_devices", None,
    "CPU devices for JAX (default: one per core, so that seeds or minibatch samples train on separate cores; "
    "1, the default of experiments.stream and experiments.cost: a single device whose ops share the cores, "
    "the lowest latency for one sequence)",
)


def run(main, cpu_devices: int | None = None) -> None:
    """`cli.run(main)` with JAX configured before it starts (`runtime.configure_jax`): its CPU
    devices (--cpu_devices, else `cpu_devices`, else one per core) and XLA's compilation cache
    under the workspace (jax_cache/, so a rerun of a study skips compilation); at the end, the
    files the command wrote into the results folder are listed."""

    def start(argv):
        folder = results_dir()
        before = _snapshot(folder)
        main(argv)
        written = sorted(p for p, st in _snapshot(folder).items() if before.get(p) != st)
        if written:
            print("wrote " + ", ".join(str(p) for p in written))

    def setup():
        runtime.configure_jax(
            cpu_devices=FLAGS.cpu_devices or cpu_devices or runtime.CORES,
            compilation_cache_dir=workspace.compilation_cache_dir(FLAGS.workdir),
        )

    cli.run(start, before=setup)


def _snapshot(folder: Path) -> dict[Path, tuple[int, int, int]]:
    """Identity of every file in `folder` (inode, size, mtime): atomic writes change the inode."""
    files = {p: p.stat() for p in folder.iterdir() if p.is_file()}
    return {p: (st.st_ino, st.st_size, st.st_mtime_ns) for p, st in files.items()}


def results_dir() -> Path:
    """--results, else <workspace>/results (created)."""
    return workspace.results_dir(FLAGS.results, FLAGS.workdir)


def define_sweep(study_run: Callable[..., Any], row_names: Sequence[str] | None = None) -> None:
    """The sweep flags of a training study (ablation, bandwidth, noise, properties). The --seeds
    default is the `n_seeds` default of `study_run`; --rows lists `row_names` where given."""
    n_seeds = inspect.signature(study_run).parameters["n_seeds"].default
    rows = f"rows, from: {', '.join(row_names)}" if row_names else "row names"
    flags.DEFINE_integer("seeds", n_seeds, "number of seeds (0..n-1) trained together (the study's count by default)", lower_bound=1)
    flags.DEFINE_enum("preset", "default", sorted(splits.PRESETS), "dataset and training preset")
    flags.DEFINE_list("rows", None, f"comma-separated {rows} (default: every row of the table)")
    flags.DEFINE_enum("backbone", None, list(BACKBONES), "override every row's backbone")
    flags.DEFINE_integer("seq_len", None, "steps per sequence (default: the preset's N)")
    flags.DEFINE_float("bandwidth", None, "PSD bandwidth in kHz (default 15)")
    flags.DEFINE_integer("epochs", None, "training epochs (default: the preset's)")


def sweep_kwargs() -> dict[str, Any]:
    """The keyword arguments of a study's `run` from the parsed flags."""
    overrides = {
        k: v
        for k, v in (("backbone", FLAGS.backbone), ("seq_len", FLAGS.seq_len), ("bandwidth_khz", FLAGS.bandwidth), ("epochs", FLAGS.epochs))
        if v is not None
    }
    return dict(n_seeds=FLAGS.seeds, preset=FLAGS.preset, rows=FLAGS.rows, overrides=overrides, **location_kwargs())


def location_kwargs() -> dict[str, Any]:
    """Where data and results live, and the command line (recorded in every results file)."""
    return dict(workdir=FLAGS.workdir, data_dir=FLAGS.data_dir, results=results_dir(), command=common.command_line())
