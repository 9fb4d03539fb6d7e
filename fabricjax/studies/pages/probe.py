"""The linear probe's page, drawn from its result (`results.Probe`) as its results JSON holds
it, and the probe beside the ablation's rows that REPORT.md shows.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from fabricjax.reporting import results_files, stats
from fabricjax.sequences import data
from fabricjax.studies.machinery import documents, findings
from fabricjax.studies.machinery.probing import SPLITS, row_for
from fabricjax.studies.machinery.results import Probe


def _pct(accuracy: Mapping[str, float], split: str) -> str:
    return f"{100 * accuracy[split]:.2f}" if accuracy.get(split) is not None else "–"


def table(result: Probe) -> str:
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
        for r in result.rows
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


def inputs_table(result: Probe) -> str:
    """One line per input: its dimensions per step, its summary and what the probe reads of it."""
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
        for m, i in result.inputs.items()
    ]
    return results_files.markdown_table(
        ["Input", "Dimensions per step", "Summary (mean, SD)", "Probe features", "Time [s]"], body
    )


def markdown(doc: Mapping[str, Any]) -> str:
    """The page of the results JSON `doc`: how the probe reads each input, then both tables."""
    result = Probe.from_json(doc)
    m = result.method
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
            f"Chance: {100 / len(result.classes):.2f} % ({len(result.classes)} classes in the training split). "
            "One probe per distinct set of inputs of the modality ablation; REPORT.md sets it beside the "
            "ablation's rows."
            + (
                f" The rotated probe is fitted on {m['rotation_draws']} rotations of every training sequence "
                "(one angle per sequence and draw, uniform in ±90°, the same for all its frames, through the "
                "model's rotation path, 0 filling what the turn brings in); it chooses C and is scored on the "
                "other splits' frames unrotated, as the image row trained under the rotation is."
                if "rotation_draws" in m
                else ""
            ),
            "",
            table(result),
            inputs_table(result),
        ]
    )


def beside_ablation(probe_doc: Mapping[str, Any], ablation_doc: Mapping[str, Any]) -> str:
    """The ablation's rows in its order, each beside the probe of the same inputs: probe test
    accuracy, the model's (mean ± SD over seeds) and model − probe; a line on how many rows reach
    their probe, and a warning when the two ran on different data."""
    body, reached = [], 0
    for r in ablation_doc["rows"]:
        p = row_for(
            r["modalities"],
            probe_doc["rows"],
            r.get("config", {}).get("image_reference"),
            rotated=r.get("config", {}).get("augment_rotation", False),
        )
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
