"""Validation and test accuracy for PSD bandwidths 2.5 / 10 / 15 / 24 kHz, Minsound only (see
fabricjax/studies/paper/bandwidth.py).

python -m experiments.bandwidth --seeds=5
"""

from experiments import flags
from fabricjax.studies.paper import bandwidth

if __name__ == "__main__":
    flags.study_command(bandwidth.STUDY)
