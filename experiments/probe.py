"""A linear probe per row of the modality ablation: what each input carries before any model (see
fabricjax/studies/diagnostics/probe.py).

python -m experiments.probe                     # default preset, into workspace/results/
python -m experiments.probe --results=results   # regenerates the table published in the repository
"""

from experiments import flags
from fabricjax.studies.diagnostics import probe

if __name__ == "__main__":
    flags.rows_study_command(probe)
