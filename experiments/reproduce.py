"""Every study of the paper in order, skipping those up to date, and one report (see fabricjax/studies/tools/reproduce.py).

    python -m experiments.reproduce                      # default preset, into workspace/results/REPORT.md
    python -m experiments.reproduce --results=results    # regenerates the repository's results/REPORT.md
    python -m experiments.reproduce --set=epochs=4       # any Config field, for every study
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.errors import UserError
from fabricjax.studies.tools import reproduce

flags.define_preset()
flags.define_overrides()
STUDIES = absl_flags.DEFINE_list("studies", None, f"comma-separated studies to run, from: {', '.join(reproduce.STUDIES)} (default: all, in that order)")
FORCE = absl_flags.DEFINE_bool("force", False, "rerun every study, even those whose results are up to date")


def main(argv):
    del argv
    plan = reproduce.PLAN
    if STUDIES.value:
        known = [s.study for s in plan]
        unknown = [s for s in STUDIES.value if s not in known]
        if unknown:
            raise UserError(f"--studies: unknown {unknown}; choose from {known}")
        plan = tuple(s for s in plan if s.study in STUDIES.value)
    reproduce.run(preset=absl_flags.FLAGS.preset, plan=plan, overrides=flags.overrides(), force=FORCE.value, where=flags.location())


if __name__ == "__main__":
    flags.run(main)
