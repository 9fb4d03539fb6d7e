"""t-SNE of per-trial mean latents from a checkpoint (see fabricjax/studies/paper/latents.py).

python -m experiments.latents --checkpoint=DIR [--seed=1]    # DIR: listed in results/properties.md; default seed: the
best by validation
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.paper import latents

CHECKPOINT = absl_flags.DEFINE_string(
    "checkpoint", None, "checkpoint directory written by a training study", required=True
)
SEED = absl_flags.DEFINE_integer("seed", None, "seed to use (default: the one with the best validation score)")


def main(argv):
    del argv
    latents.run(CHECKPOINT.value, seed=SEED.value, where=flags.location())


if __name__ == "__main__":
    flags.run(main)
