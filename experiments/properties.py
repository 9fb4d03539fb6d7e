"""Property perception on training and holdout fabrics, checkpointed (see fabricjax/studies/properties.py).

    python -m experiments.properties --seeds=5
"""

from experiments import flags
from fabricjax.studies import properties

if __name__ == "__main__":
    flags.study_command(properties.STUDY)
