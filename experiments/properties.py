"""Property perception on training and holdout fabrics, checkpointed (see fabricjax/studies/paper/properties.py).

python -m experiments.properties --seeds=5
"""

from experiments import flags
from fabricjax.studies.paper import properties

if __name__ == "__main__":
    flags.study_command(properties.STUDY)
