"""Every speed benchmark in one command, side by side in one process; prints the table and writes
bench.md and bench.json into workspace/results/ (--results=DIR: into DIR).

    python -m experiments.bench                       # everything (README's speed section says how long it takes)
    python -m experiments.bench --quick               # a small model, fewer repeats: a smoke check, not a measurement
    python -m experiments.bench --only=training,inference
    python -m experiments.bench --only=training --train_seeds=1,4,5 --cpu_devices=1 --results=/tmp/b
                                                      # other seed counts, on one CPU device sharing the cores

The benchmarks (names for --only) and what they measure: fabricjax/bench/suite.py.
"""

from __future__ import annotations

import dataclasses

from absl import app
from absl import flags as absl_flags

from acquisition.simulated_signals import bench_acquisition
from experiments import flags
from fabricjax.bench import suite as bench

FLAGS = absl_flags.FLAGS
absl_flags.DEFINE_list("only", None, f"benchmarks to run (default all): {','.join(bench.BENCHMARKS)}")
absl_flags.DEFINE_bool(
    "quick",
    False,
    "a small model (fabricjax/bench/suite.QUICK_WORKLOAD), smaller sizes and fewer repeats: a smoke check",
)
absl_flags.DEFINE_list(
    "train_seeds",
    ["1", "5"],
    "seed counts of the training benchmark (must include 1); each is split over the CPU devices as training "
    "splits it (sharding.training_mesh)",
)


def main(argv):
    del argv
    seeds = tuple(sorted({int(s) for s in FLAGS.train_seeds}))
    if 1 not in seeds or min(seeds) < 1:
        raise app.UsageError(f"--train_seeds must be positive and include 1, got {FLAGS.train_seeds}")
    workload = dataclasses.replace(bench.QUICK_WORKLOAD if FLAGS.quick else bench.Workload(), seeds=seeds)
    bench.run(
        only=FLAGS.only,
        quick=FLAGS.quick,
        workload=workload,
        acquisition=bench_acquisition,
        where=flags.location(),
    )


if __name__ == "__main__":
    flags.run(main)
