"""What a new recording day changes in each input, and the probe's gap from the training days to it (see
fabricjax/studies/diagnostics/day_shift.py).

python -m experiments.day_shift                     # default preset, into workspace/results/
python -m experiments.day_shift --results=results   # regenerates the table published in the repository
"""

from experiments import flags
from fabricjax.studies.diagnostics import day_shift

if __name__ == "__main__":
    flags.rows_study_command(day_shift)
