"""What each input carries before any model: a linear probe per row of the modality ablation.

    python -m experiments.probe                               # default preset, every ablation row's inputs
    python -m experiments.probe --rows=image,internal --data_dir=DIR

A row of the ablation at chance can mean a sensor that carries nothing about the fabric or a
model that cannot read it. This study answers the first half without any model of ours: for every
distinct set of inputs among the ablation's rows (`ablation.ROWS`, so the two tables line up row
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

import time
from typing import Any, Mapping, Sequence

import numpy as np
from threadpoolctl import threadpool_limits

from fabricjax.reporting import results_files, stats
from fabricjax.sequences import data
from fabricjax.store import archive
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents, findings, loading
from fabricjax.studies.machinery.linear_probe import (
    BLAS_THREADS,
    C_GRID,
    MAX_ITER,
    PCA_ABOVE,
    PCA_DIMS,
    Input,
    fit,
    prepare_inputs,
)
from fabricjax.studies.machinery.progress import Progress
from fabricjax.studies.machinery.rows import RowSpec
from fabricjax.studies.paper import ablation

TITLE, PAPER = "Linear probe of every ablation row's inputs", "not in the paper"
SPLITS = (*loading.TRAIN_VAL_TEST, "cafe")  # the ablation's, and the cafe condition where the data has it


SESSION = "session:"  # the name prefix of a probe that reads frames minus their session's reference


def _rows() -> tuple[RowSpec, ...]:
    """One probe per distinct set of inputs among the ablation's rows, named like its first row;
    with the image, a second reading its frames against their session's reference."""
    seen: dict[frozenset, RowSpec] = {}
    session = []
    for r in ablation.ROWS:
        mods, label = r.modalities, ablation.label(r.modalities, "attention")
        if frozenset(mods) in seen:
            continue
        if "image" not in mods:
            seen[frozenset(mods)] = RowSpec("+".join(mods), {"modalities": mods}, label)
            continue
        seen[frozenset(mods)] = RowSpec(
            "+".join(mods), {"modalities": mods, "image_reference": "training_mean"}, f"{label}, frames as they are"
        )
        session.append(
            RowSpec(
                SESSION + "+".join(mods),
                {"modalities": mods, "image_reference": "session"},
                f"{label}, frames − session reference",
            )
        )
    return (*seen.values(), *session)


ROWS = _rows()


def reading(image_reference: str | None) -> str:
    """How a probe row reads the frames: "session" (minus the session's reference) or "frame"
    (as they are: the other readings differ from it by a per-pixel constant the probe removes)."""
    return "session" if image_reference == "session" else "frame"


def row_for(
    modalities: Sequence[str], rows: Sequence[Mapping[str, Any]], image_reference: str | None = None
) -> Mapping[str, Any] | None:
    """The probe row (as JSON) that reads exactly `modalities`, in any order, with the image (if
    any) read as `image_reference` reads it (`reading`); None if not probed."""
    want = reading(image_reference) if "image" in modalities else "frame"
    return next(
        (r for r in rows if set(r["modalities"]) == set(modalities) and reading(r.get("image_reference")) == want), None
    )


def run(
    *,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    where: Location = Location(),
) -> dict[str, Any]:
    """Probe the chosen rows' inputs (all by default) and write results/probe.{md,json}; returns the JSON."""
    chosen, configs, datasets, present = loading.load_chosen_rows("probe", ROWS, rows, preset, overrides, where, SPLITS)
    ds = datasets[0]
    for split in ("train", "val"):
        if split not in present:
            raise archive.ArchiveError(
                ds.folder,
                "<folder>",
                f"no {split} sequences (check days and conditions): the probe fits on train and chooses C on val",
            )
    labels = {s: ds.sets[s].labels["fabric"] for s in present}
    if len(np.unique(labels["train"])) < 2:
        raise archive.ArchiveError(
            ds.folder, "label", "the training split holds fewer than two fabrics: nothing to probe"
        )

    t0 = time.perf_counter()
    loads = {}  # per load (rows that read the frames alike share one): the load and its first row's config
    for c, d in zip(configs, datasets):
        loads.setdefault(id(d), (d, c))
    inputs = {
        key: prepare_inputs(d.sets, loading.union_modalities([c for c, e in zip(configs, datasets) if e is d]), present)
        for key, (d, _) in loads.items()
    }
    with threadpool_limits(BLAS_THREADS):
        progress = Progress("probe", len(chosen))
        names = ds.sets["train"].names if ds.recorded else {}  # recorded data: its own names for its streams
        out_rows = [
            _probe_row(r, c, inputs[id(d)], labels, present, progress, names)
            for r, c, d in zip(chosen, configs, datasets)
        ]

    doc = {
        **documents.header(
            "probe", module=__name__, command=where.command, preset=preset, dataset=ds, probe_s=time.perf_counter() - t0
        ),
        "method": {
            "summaries": ["mean", "sd"],
            "pca_above_step_dims": PCA_ABOVE,
            "pca_dims": PCA_DIMS,
            "c_grid": list(C_GRID),
            "solver": "lbfgs",
            "max_iter": MAX_ITER,
        },
        "splits": present,
        "classes": sorted(np.unique(labels["train"]).tolist()),
        "inputs": {name: i for key, (_, c) in loads.items() for name, i in _inputs_doc(inputs[key], c, names).items()},
        "rows": [{k: v for k, v in r.items() if k != "predictions"} for r in out_rows],
    }
    samples = {
        "rows": {r["name"]: r["predictions"] for r in out_rows},
        "sequences": {s: documents.samples_doc(ds.sets[s]) for s in present if s != "train"},
    }
    return results_files.write(where.results_dir(), doc, markdown, samples=samples)


def _inputs_doc(inputs: Mapping[str, Input], config, names: Mapping[str, str]) -> dict[str, Any]:
    """The inputs of one load as the JSON's "inputs": keyed by modality, the image read against
    its session's reference as "session:image"."""
    out = {}
    for m, i in inputs.items():
        session = m == "image" and config.image_reference == "session"
        out[SESSION + m if session else m] = {
            **i.to_json(),
            "display_name": data.inputs_name((m,), names) + (" − session reference" if session else ""),
        }
    return out


def _probe_row(
    r: RowSpec,
    config,
    inputs: Mapping[str, Input],
    labels,
    splits: Sequence[str],
    progress: Progress,
    names: Mapping[str, str],
) -> dict[str, Any]:
    """Row `r`'s probe on its inputs' features, concatenated, as the JSON row; `names`: the data's
    names for its streams (recorded data), else the paper's."""
    name = ablation.label(r.modalities, "attention", names=names) if names else r.label
    progress.start(name)
    t0 = time.perf_counter()
    features = {s: np.concatenate([inputs[m].features[s] for m in r.modalities], axis=1) for s in splits}
    result = fit(features, labels)
    seconds = time.perf_counter() - t0
    progress.finish(name, seconds, f"C={result['C']:g}, test {100 * result['accuracy'].get('test', np.nan):.1f} %")
    return {
        "name": r.name,
        "modalities": list(r.modalities),
        "display_name": name,
        **({"image_reference": config.image_reference} if "image" in r.modalities else {}),
        "probe_dims": int(features["train"].shape[1]),
        "wall_s": seconds,
        **result,
        "collapsed": {s: findings.collapsed(p) for s, p in result["predictions"].items()},
    }


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
