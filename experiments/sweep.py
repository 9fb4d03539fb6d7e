"""A recipe sweep: every grid point on the ablation's rows (see fabricjax/studies/diagnostics/sweep.py).

    python -m experiments.sweep --grid=width=32,64 --grid=epochs=2,4 --seeds=2          # the paper's rows
    python -m experiments.sweep --grid='cnn_features=4,8;8,16' --rows=image,flow --seeds=2
    python -m experiments.sweep --grid=learning_rate=1e-3,2e-3 --set=epochs=4 --results=results

--grid=field=v1,v2,... is repeatable over any `Config` field (the points are the cartesian
product); each value is read like --set. Separate a tuple field's values by ';' (their items
are comma-separated): --grid='cnn_features=4,8;8,16' is two points, (4, 8) and (8, 16).
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import sweep
from fabricjax.studies.paper import ablation

FLAGS = absl_flags.FLAGS
flags.define_rows(ablation.STUDY, sweep.N_SEEDS)
absl_flags.DEFINE_multi_string(
    "grid", [], f"a swept Config field, repeatable (the points are the cartesian product): {sweep.GRID_HELP}"
)
absl_flags.DEFINE_integer("latency_repeats", 100, "timed predict_one calls per point and row", lower_bound=1)


def main(argv):
    del argv
    sweep.run(grid=sweep.parse_grid(FLAGS.grid), latency_repeats=FLAGS.latency_repeats, **flags.rows_kwargs())


if __name__ == "__main__":
    flags.run(main)
