"""The paper's modality ablation, its 13 rows and our 9 fusion-variant rows (see fabricjax/studies/paper/ablation.py).

python -m experiments.ablation --seeds=5                    # README main command: default preset, into
workspace/results/
python -m experiments.ablation --seeds=5 --results=results  # regenerates the table published in the repository
"""

from experiments import flags
from fabricjax.studies.paper import ablation

if __name__ == "__main__":
    flags.study_command(ablation.STUDY)
