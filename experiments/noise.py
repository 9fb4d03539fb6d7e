"""The cafe-noise table, Wilcoxon against the preceding row (see fabricjax/studies/paper/noise.py).

python -m experiments.noise --seeds=10
"""

from experiments import flags
from fabricjax.studies.paper import noise

if __name__ == "__main__":
    flags.study_command(noise.STUDY)
