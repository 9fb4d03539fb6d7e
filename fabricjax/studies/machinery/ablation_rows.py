"""The modality ablation's rows: the paper's Table ablation_table and our step-LayerNorm variant.

The ablation trains them, the linear probe reads each distinct set of their inputs and the
recipe sweep trains its grid on them, so that the three tables line up row by row.
"""

from __future__ import annotations

from typing import Mapping, Sequence

from fabricjax.sequences import data
from fabricjax.studies.machinery.rows import RowSpec, select_rows

STEP_LAYERNORM = "step_layernorm"  # our fusion normalisation (config.FUSION_NORMS), beside the paper's sequence_minmax
CONFUSION_ROWS = ("proprio", "flow")  # the rows whose confusion matrices the study counts and its page draws


def label(
    modalities: Sequence[str],
    backbone: str,
    fusion_norm: str = "sequence_minmax",
    names: Mapping[str, str] | None = None,
    rotated: bool = True,
) -> str:
    """How the table names a row: 'TCN: Minsound + palm mic', '... (our step-LayerNorm fusion)',
    'Minsight image (our step-LayerNorm fusion, frames unrotated)' where a row reading frames trains
    without the paper's rotation (`rotated` False); with `names` (recorded data: modality -> the
    data's name for its stream) the data's names."""
    text = data.inputs_name(modalities, names)
    text = f"TCN: {text}" if backbone == "tcn" else text
    notes = ["our step-LayerNorm fusion"] if fusion_norm == STEP_LAYERNORM else []
    notes += ["frames unrotated"] if "image" in modalities and not rotated else []
    return f"{text} ({', '.join(notes)})" if notes else text


def _row(
    modalities: Sequence[str], mean: float, sd: float, backbone: str = "attention", fusion_norm: str = "sequence_minmax"
) -> RowSpec:
    """A row and the paper's test accuracy [%] (mean, SD over its seeds) for the same inputs. Our
    variant's rows read Minsight frames without the paper's rotation: under it the image rows fall
    to a fraction of what they learn unrotated, on validation (docs/usage.md, "What the camera rows
    learn")."""
    name = ("tcn:" if backbone == "tcn" else "") + "+".join(modalities)
    if fusion_norm != "sequence_minmax":
        name = f"{fusion_norm}:{name}"
    settings = {"backbone": backbone, "modalities": tuple(modalities), "fusion_norm": fusion_norm}
    rotated = fusion_norm != STEP_LAYERNORM or "image" not in modalities
    if not rotated:
        settings["augment_rotation"] = False
    return RowSpec(name, settings, label(modalities, backbone, fusion_norm, rotated=rotated), {"mean": mean, "sd": sd})


# The paper's Table ablation_table: 12 transformer rows and the TCN row.
PAPER_ROWS = (
    _row(("image",), 41.15, 5.74),
    _row(("flow",), 47.16, 5.12),
    _row(("internal",), 95.06, 1.85),
    _row(("external",), 59.22, 2.43),
    _row(("proprio",), 47.10, 3.72),
    _row(("image", "internal"), 73.94, 5.73),
    _row(("image", "internal", "external", "proprio"), 85.59, 3.87),
    _row(("flow", "internal"), 87.44, 5.88),
    _row(("flow", "internal", "external", "proprio"), 91.34, 2.47),
    _row(("internal", "proprio"), 94.63, 2.78),
    _row(("internal", "external", "proprio"), 96.10, 1.26),
    _row(("internal", "external"), 97.75, 1.27),
    _row(("internal", "external", "proprio"), 75.41, 11.2, backbone="tcn"),
)
# Every camera row and the fusion rows without camera inputs, again under our step-LayerNorm fusion:
# the paper's rescale over the sequence removes a stream's steady level, which is where a camera
# frame's contact patch and a joint's load show, so a row at chance under it alone is no verdict.
# Their paper numbers are the paper's row with the same inputs, for reference.
STEP_LAYERNORM_ROWS = tuple(
    _row(r.modalities, r.paper["mean"], r.paper["sd"], fusion_norm=STEP_LAYERNORM)
    for r in PAPER_ROWS
    if r.name
    in (
        "image",
        "flow",
        "image+internal",
        "image+internal+external+proprio",
        "flow+internal",
        "flow+internal+external+proprio",
        "internal+proprio",
        "internal+external+proprio",
        "internal+external",
    )
)
ROWS = PAPER_ROWS + STEP_LAYERNORM_ROWS
# What --rows takes as one word. Without --rows the study trains the paper's table alone: our fusion
# variant would nearly double the main command's time, and its rows are asked for by name or as "ours".
ROW_GROUPS = {"paper": tuple(r.name for r in PAPER_ROWS), "ours": tuple(r.name for r in STEP_LAYERNORM_ROWS)}
# Minsound (no fusion) against our fused variant of Minsound + palm mic


def select(names: Sequence[str] | None) -> list[RowSpec]:
    """The rows `names` stand for, as the ablation's --rows reads them (None: the paper's table)."""
    return select_rows(ROWS, names, ROW_GROUPS, ROW_GROUPS["paper"])


def display_name(row_name: str) -> str:
    """The label of row `row_name` of `ROWS`."""
    return next(r for r in ROWS if r.name == row_name).label
