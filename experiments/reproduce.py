"""Every study of the paper in order, skipping those up to date, and one report (see
fabricjax/studies/release/reproduce.py).

python -m experiments.reproduce                      # default preset, into workspace/results/REPORT.md
python -m experiments.reproduce --results=results    # regenerates the repository's results/REPORT.md
python -m experiments.reproduce --set=epochs=4       # any Config field, for every study
python -m experiments.reproduce --check --results=results   # runs nothing: lists the stale studies and their files,
exit 1 if any
"""

import sys

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.release import reproduce, reproduce_plan, staleness

flags.define_preset()
flags.define_overrides("a field a study's rows set themselves is refused")
STUDIES = absl_flags.DEFINE_list(
    "studies",
    None,
    f"comma-separated studies to run (with --check: to check), from: {', '.join(reproduce_plan.STUDIES)} "
    "(default: all, in that order)",
)
FORCE = absl_flags.DEFINE_bool("force", False, "rerun every study, even those whose results are up to date")
CHECK = absl_flags.DEFINE_bool(
    "check",
    False,
    "run nothing: list the studies of --results whose fingerprints (their code, the simulator and its "
    "estimates, --data_dir's data) no longer match today's, with their files; exit status 1 if any",
)


def main(argv):
    del argv
    if CHECK.value:
        sys.exit(1 if staleness.check(flags.location(), studies=STUDIES.value) else 0)
    reproduce.run(
        preset=absl_flags.FLAGS.preset,
        plan=reproduce_plan.chosen(STUDIES.value),
        overrides=flags.overrides(),
        force=FORCE.value,
        where=flags.location(),
    )


if __name__ == "__main__":
    flags.run(main)
