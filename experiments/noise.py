"""The cafe-noise table, Wilcoxon against the preceding row (see fabricjax/studies/noise.py).

    python -m experiments.noise --seeds=10
"""

from experiments import flags
from fabricjax.studies import noise

flags.define_sweep(noise.run)


def main(argv):
    del argv
    noise.run(**flags.sweep_kwargs())


if __name__ == "__main__":
    flags.run(main)
