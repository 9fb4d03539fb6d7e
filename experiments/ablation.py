"""The paper's modality ablation, all 13 rows (see fabricjax/studies/ablation.py).

    python -m experiments.ablation --seeds=5     # README main command: default preset, wall time per row in results/ablation.md
"""

from experiments import flags
from fabricjax.studies import ablation

flags.define_sweep()


def main(argv):
    del argv
    ablation.run(**flags.sweep_kwargs())


if __name__ == "__main__":
    flags.run(main)
