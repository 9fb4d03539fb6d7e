"""A variant of a training study against its baseline, row by row (see fabricjax/studies/diagnostics/variant.py).

    python -m experiments.ablation --seeds=5 --set=compute_dtype=bfloat16 --results=results/bfloat16
    python -m experiments.variant --baseline=results/ablation.json --variant=results/bfloat16/ablation.json \\
        --results=results/bfloat16
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.studies.diagnostics import variant

BASELINE = absl_flags.DEFINE_string(
    "baseline", None, "the baseline's results JSON (e.g. results/ablation.json)", required=True
)
VARIANT = absl_flags.DEFINE_string(
    "variant", None, "the variant's results JSON, the same study rerun with --set changes", required=True
)


def main(argv):
    del argv
    variant.run(BASELINE.value, VARIANT.value, where=flags.location())


if __name__ == "__main__":
    flags.run(main)
