"""Property perception on training and holdout fabrics, checkpointed (see fabricjax/studies/properties.py).

    python -m experiments.properties --seeds=5
"""

from experiments import flags
from fabricjax.studies import properties

flags.define_sweep(properties.run)


def main(argv):
    del argv
    properties.run(**flags.sweep_kwargs())


if __name__ == "__main__":
    flags.run(main)
