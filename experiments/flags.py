"""Flags shared by the study commands; every sweep dimension is a flag.

    --seeds --preset --rows --backbone --seq_len --bandwidth --epochs   (define_sweep)
    --workdir --data_dir --results --cpu_devices                        (always)

Unset sweep flags keep the study's defaults (`fabricjax.studies.common.PRESET_TRAINING`).
"""

from __future__ import annotations

from typing import Any

from absl import app, flags

from fabricjax import sharding, splits
from fabricjax.config import BACKBONES
from fabricjax.studies import common

FLAGS = flags.FLAGS

flags.DEFINE_string("workdir", None, "workspace root: datasets, features, checkpoints (default $FABRICJAX_WORKDIR or ./workspace)")
flags.DEFINE_string("data_dir", None, "a folder of real recorded trial archives; default: the preset's simulated dataset")
flags.DEFINE_string("results", "results", "where <study>.md/.json and figures are written")
flags.DEFINE_integer(
    "cpu_devices", None,
    "CPU devices for JAX (default: one per core, so that seeds or minibatch samples train on separate cores; "
    "1, the default of experiments.stream and experiments.cost: a single device whose ops share the cores, "
    "the lowest latency for one sequence)",
)


def run(main, cpu_devices: int | None = None) -> None:
    """`absl.app.run(main)`, with JAX's CPU devices set before JAX starts: --cpu_devices, else
    `cpu_devices`, else one per core."""

    def start(argv):
        sharding.use_cpu_cores(FLAGS.cpu_devices or cpu_devices)
        return main(argv)

    app.run(start)


def define_sweep() -> None:
    """The sweep flags of a training study (ablation, bandwidth, noise, properties)."""
    flags.DEFINE_integer("seeds", None, "number of seeds (0..n-1) trained together; default: the study's (paper's) count")
    flags.DEFINE_enum("preset", "default", sorted(splits.PRESETS), "dataset and training preset")
    flags.DEFINE_list("rows", None, "comma-separated row names (default: every row of the table)")
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
    kwargs = dict(preset=FLAGS.preset, rows=FLAGS.rows, overrides=overrides, **location_kwargs())
    if FLAGS.seeds is not None:
        kwargs["n_seeds"] = FLAGS.seeds
    return kwargs


def location_kwargs() -> dict[str, Any]:
    """Where data and results live, and the command line (recorded in every results file)."""
    return dict(workdir=FLAGS.workdir, data_dir=FLAGS.data_dir, results=FLAGS.results, command=common.command_line())
