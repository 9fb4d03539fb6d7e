"""Which of the simulator's estimates each finding depends on (see fabricjax/studies/diagnostics/sensitivity.py).

    python -m experiments.sensitivity                       # every group of estimates, into workspace/results/
    python -m experiments.sensitivity --results=results     # regenerates results/sensitivity.{md,json,png}
    python -m experiments.sensitivity --groups="servo noise,camera day" --trajectories=2

Each point simulates the reduced `sensitivity` preset anew and probes it (a minute or two on 2 cores); k groups and
r trajectories are r (k + 1) points. Resumable: rerun the same command after an interruption.
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import sensitivity

PRESET = absl_flags.DEFINE_string("preset", sensitivity.PRESET, "the preset simulated at every point")
TRAJECTORIES = absl_flags.DEFINE_integer("trajectories", sensitivity.TRAJECTORIES, "Morris trajectories", lower_bound=1)
GROUPS = absl_flags.DEFINE_list(
    "groups", None, "the groups of estimates screened (default: every group of fabricjax/sim/estimates.py)"
)
SEED = absl_flags.DEFINE_integer("seed", 0, "seed of the Morris design")


def main(argv):
    del argv
    sensitivity.run(
        preset=PRESET.value,
        trajectories=TRAJECTORIES.value,
        groups=GROUPS.value,
        seed=SEED.value,
        where=flags.location(),
    )


if __name__ == "__main__":
    flags.run(main)
