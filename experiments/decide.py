"""Calibrated confidence, when to stop rubbing, unknown fabrics (see fabricjax/studies/diagnostics/decide.py).

    python -m experiments.decide --checkpoint=DIR[,DIR...]   # checkpoints of training studies (ablation, properties,
    ...)
    python -m experiments.decide                             # the quick model of --preset `experiments.stream` uses
    python -m experiments.decide --checkpoint=DIR --data_dir=PATH --unknown_labels=7,8

Writes results/decide.{md,json,png}, and each model's temperatures beside its checkpoint (which
`experiments.stream` and `experiments.view` then apply).
"""

from absl import flags as absl_flags

from experiments import flags
from fabricjax.errors import UserError
from fabricjax.studies.diagnostics import decide

CHECKPOINT = absl_flags.DEFINE_list(
    "checkpoint", [], "checkpoint directories (default: a quick model of --preset, as experiments.stream)"
)
UNKNOWN = absl_flags.DEFINE_list(
    "unknown_labels",
    [],
    "fabric ids (archives' meta.fabric_id; a rig's classes, meta.label) whose test trials are the unknowns, beside "
    "the model's excluded fabrics",
)
flags.define_preset()
flags.define_overrides()


def main(argv):
    del argv
    try:
        unknown = [int(x) for x in UNKNOWN.value]
    except ValueError:
        raise UserError(f"--unknown_labels: {UNKNOWN.value} are not all integers (fabric ids)") from None
    decide.run(
        CHECKPOINT.value,
        preset=flags.FLAGS.preset,
        overrides=flags.overrides(),
        unknown_labels=unknown,
        where=flags.location(),
    )


if __name__ == "__main__":
    flags.run(main)
