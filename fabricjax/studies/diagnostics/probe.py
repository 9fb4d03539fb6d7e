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

REPORT.md puts this table beside the ablation's, row by row (`beside_ablation`).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from fabricjax.reporting import results_files, stats
from fabricjax.sequences import data
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents, findings, probing
from fabricjax.studies.machinery.probing import SPLITS, row_for

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
        **probed.body,
    }
    return results_files.write(where.results_dir(), doc, markdown, samples=probed.samples)


def _pct(accuracy: Mapping[str, float], split: str) -> str:
    return f"{100 * accuracy[split]:.2f}" if accuracy.get(split) is not None else "–"


def table(doc: Mapping[str, Any]) -> str:
    """One line per probe: its inputs, features, chosen C and accuracy on every split."""
    body = [
        [
            r["display_name"],
            r["probe_dims"],
            f"{r['C']:g}" + ("" if r["converged"] else " (not converged)"),
            *[
                _pct(r["accuracy"], s) + findings.collapse_text(r.get("collapsed", {}).get(s, [])) * (s != "train")
                for s in SPLITS
            ],
            f"{r['wall_s']:.1f}",
        ]
        for r in doc["rows"]
    ]
    header = [
        "Inputs",
        "Probe features",
        "C (by validation)",
        "Train [%]",
        "Validation [%]",
        "Test [%]",
        "Cafe [%]",
        "Fit time [s]",
    ]
    return results_files.markdown_table(header, body)


def inputs_table(doc: Mapping[str, Any]) -> str:
    body = [
        [
            i["display_name"] if "display_name" in i else data.inputs_name((m,)),
            i["step_dims"],
            i["summary_dims"],
            f"{i['probe_dims']} (PCA, {100 * i['explained_variance']:.1f} % of the variance)"
            if i["explained_variance"] is not None
            else i["probe_dims"],
            f"{i['seconds']:.1f}",
        ]
        for m, i in doc["inputs"].items()
    ]
    return results_files.markdown_table(
        ["Input", "Dimensions per step", "Summary (mean, SD)", "Probe features", "Time [s]"], body
    )


def markdown(doc: Mapping[str, Any]) -> str:
    m = doc["method"]
    return "\n".join(
        [
            "# Linear probe: what each input carries before any model",
            "",
            documents.header_markdown(
                doc,
                f"probes {doc['probe_s']:.0f} s in all (summaries and PCA included); "
                f"{documents.data_time_markdown(doc['dataset'])}",
            ),
            "Logistic regression (scikit-learn, lbfgs, L2) on each sequence's per-dimension mean and SD over "
            "its steps, "
            "standardised on the training split; "
            f"inputs with more than {m['pca_above_step_dims']} dimensions per step reduced to at most "
            f"{m['pca_dims']} principal "
            f"components fitted on the training split; C from {', '.join(f'{c:g}' for c in m['c_grid'])} by "
            f"validation accuracy. "
            f"Chance: {100 / len(doc['classes']):.2f} % ({len(doc['classes'])} classes in the training split). "
            "One probe per distinct set of inputs of the modality ablation; REPORT.md sets it beside the "
            "ablation's rows.",
            "",
            table(doc),
            inputs_table(doc),
        ]
    )


def beside_ablation(probe_doc: Mapping[str, Any], ablation_doc: Mapping[str, Any]) -> str:
    """The ablation's rows in its order, each beside the probe of the same inputs: probe test
    accuracy, the model's (mean ± SD over seeds) and model − probe; a line on how many rows reach
    their probe, and a warning when the two ran on different data."""
    body, reached = [], 0
    for r in ablation_doc["rows"]:
        p = row_for(r["modalities"], probe_doc["rows"], r.get("config", {}).get("image_reference"))
        test = 100 * np.asarray(r["accuracy"]["test"]["fabric"], np.float64)
        mean, sd = stats.mean_sd(test)
        probe_test = None if p is None or p["accuracy"].get("test") is None else 100 * p["accuracy"]["test"]
        reached += probe_test is not None and mean >= probe_test
        probe_note = "" if p is None else findings.collapse_text(p.get("collapsed", {}).get("test", []))
        body.append(
            [
                r["display_name"],
                "–" if probe_test is None else f"{probe_test:.2f}{probe_note}",
                f"{mean:.2f} ± {sd:.2f}{findings.collapse_text(r['collapsed']['test'])}",
                "–" if probe_test is None else f"{mean - probe_test:+.2f}",
            ]
        )
    n_seeds = len(ablation_doc["seeds"])
    compared = sum(b[1] != "–" for b in body)
    lines = [
        results_files.markdown_table(
            ["Ablation row", "Linear probe, test [%]", f"Model, test [%] ({n_seeds} seeds)", "Model − probe [pp]"], body
        ),
        f"{reached} of {compared} rows at or above their probe's test accuracy (model: mean over seeds).",
        "",
    ]
    a, p = ablation_doc["dataset"], probe_doc["dataset"]
    if (ablation_doc["preset"], a["folder"]) != (probe_doc["preset"], p["folder"]):
        lines += [
            f"**Not the same data**: ablation on {ablation_doc['preset']} `{a['folder']}`, probe on "
            f"{probe_doc['preset']} `{p['folder']}`.",
            "",
        ]
    return "\n".join(lines)
