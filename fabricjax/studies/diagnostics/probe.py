"""What each input carries before any model: a linear probe per row of the modality ablation.

    python -m experiments.probe                               # default preset, every ablation row's inputs
    python -m experiments.probe --rows=image,internal --data_dir=DIR

A row of the ablation at chance can mean a sensor that carries nothing about the fabric or a
model that cannot read it. This study answers the first half without any model of ours: for every
distinct set of inputs among the ablation's rows (`ablation_rows.ROWS`, so the two tables line up row
by row; the TCN and fusion-variant rows share their inputs with a paper row and so its probe), a
multinomial logistic regression (scikit-learn, lbfgs) reads each sequence's per-dimension mean
and standard deviation over its N steps. Images are every frame's pixels as floats, optical flow
its pooled cells, PSDs their bins, proprioception its 18 joint channels. Each input's summaries
are standardised on the training split; an input with more than `PCA_ABOVE` dimensions per step
(the camera's) is reduced to at most `PCA_DIMS` principal components fitted on the training
split; a row's inputs' features are concatenated and the regularisation C is chosen on the
validation split from `C_GRID`. Every input set with the Minsight image is probed twice: frames
as they are (what the "none" and "training_mean" readings give: a per-pixel constant, which the
standardised summaries remove) and frames minus their session's no-contact reference
(`Config.image_reference="session"`; left out, with a warning, where the data has no reference).
The sequences and splits are the ablation's own
(`loading.load_for_rows`: the simulated preset, or `data_dir`), plus the cafe split where the
data has one. Deterministic: no seeds.

REPORT.md puts this table beside the ablation's, row by row (`pages.probe.beside_ablation`); the page
is drawn from what the probe measured (`probing.measure`, a `Probe`) by `pages.probe`.
"""

from __future__ import annotations

from typing import Any, Sequence


from fabricjax.reporting import results_files
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents, probing
from fabricjax.studies.pages import probe as page

TITLE, PAPER = "Linear probe of every ablation row's inputs", "not in the paper"
ROWS = probing.ROWS  # what --rows and the plan choose from


def run(
    *,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    where: Location = Location(),
) -> dict[str, Any]:
    """Probe the chosen rows' inputs (all by default) and write results/probe.{md,json}; returns the JSON."""
    probed = probing.measure(preset=preset, rows=rows, overrides=overrides, where=where)
    doc = {
        **documents.header(
            "probe",
            module=__name__,
            command=where.command,
            preset=preset,
            dataset=probed.dataset,
            probe_s=probed.seconds,
        ),
        **probed.result.to_json(),
    }
    return results_files.write(where.results_dir(), doc, page.markdown, samples=probed.samples)
