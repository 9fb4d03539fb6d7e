"""The linear probe of the ablation's inputs: its rows, and what it measures of them.

The probe study publishes it (`diagnostics.probe`); the day shift reads its rows beside its
own, and the sensitivity screening measures it again at every point of the simulator's
estimates. One probe per distinct set of inputs among the ablation's rows
(`ablation_rows.ROWS`), named like its first row; every set with the Minsight image probed twice,
frames as they are and frames minus their session's no-contact reference (`SESSION`).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Mapping, Sequence

import numpy as np
from absl import logging
from threadpoolctl import threadpool_limits

from fabricjax.sequences import data
from fabricjax.store import archive
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import ablation_rows, documents, findings, loading
from fabricjax.studies.machinery.linear_probe import (
    BLAS_THREADS,
    C_GRID,
    MAX_ITER,
    PCA_ABOVE,
    PCA_DIMS,
    ROTATION_DRAWS,
    Input,
    fit,
    prepare,
    prepare_inputs,
)
from fabricjax.studies.machinery.progress import Progress
from fabricjax.studies.machinery.results import Probe
from fabricjax.studies.machinery.rows import RowSpec

SPLITS = (*loading.TRAIN_VAL_TEST, "cafe")  # the ablation's, and the cafe condition where the data has it


SESSION = "session:"  # the name prefix of a probe that reads frames minus their session's reference
# ... and of the probe that also reads the training frames rotated as the paper's training rotates
# them (`linear_probe.summarise_rotated`): what the augmentation leaves of the fabric
ROTATED = "rotated:"


def _rows() -> tuple[RowSpec, ...]:
    """One probe per distinct set of inputs among the ablation's rows, named like its first row;
    with the image, a second reading its frames against their session's reference."""
    seen: dict[frozenset, RowSpec] = {}
    session = []
    for r in ablation_rows.ROWS:
        mods, label = r.modalities, ablation_rows.label(r.modalities, "attention")
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
    image = ablation_rows.label(("image",), "attention")
    rotated = RowSpec(
        ROTATED + "image",
        {"modalities": ("image",), "image_reference": "session"},
        f"{image}, frames − session reference, rotated as in training",
    )
    return (*seen.values(), *session, rotated)


ROWS = _rows()


def reading(image_reference: str | None) -> str:
    """How a probe row reads the frames: "session" (minus the session's reference) or "frame"
    (as they are: the other readings differ from it by a per-pixel constant the probe removes)."""
    return "session" if image_reference == "session" else "frame"


def row_for(
    modalities: Sequence[str],
    rows: Sequence[Mapping[str, Any]],
    image_reference: str | None = None,
    rotated: bool = False,
) -> Mapping[str, Any] | None:
    """The probe row (as JSON) that reads exactly `modalities`, in any order, with the image (if
    any) read as `image_reference` reads it (`reading`); None if not probed. `rotated` (a row
    trained under the rotation augmentation): the probe of rotated frames where one was probed
    for these inputs, else the unrotated one."""
    want = reading(image_reference) if "image" in modalities else "frame"
    same = [r for r in rows if set(r["modalities"]) == set(modalities) and reading(r.get("image_reference")) == want]
    turned = [r for r in same if r.get("rotated")] if rotated and "image" in modalities else []
    return next(iter(turned or [r for r in same if not r.get("rotated")]), None)


@dataclasses.dataclass(frozen=True)
class Probed:
    """What probing the chosen rows gave: the data read, the seconds the probes took (summaries
    and PCA included), what they measured (`result`) and the per-sample records (`samples`)."""

    dataset: loading.Dataset
    seconds: float
    result: Probe
    samples: dict[str, Any]


def measure(
    *,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: dict[str, Any] | None = None,
    where: Location = Location(),
) -> Probed:
    """Probe the chosen rows' inputs (all by default) on the data `where` names; writes nothing."""
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
    for r, d in zip(chosen, datasets):
        if r.name.startswith(ROTATED):
            with threadpool_limits(BLAS_THREADS):
                inputs[id(d)][ROTATED + "image"] = prepare(
                    {s: d.sets[s].inputs["image"] for s in present}, rotated=True
                )
            logging.info("probe: rotated %s", inputs[id(d)][ROTATED + "image"].describe("image"))
    with threadpool_limits(BLAS_THREADS):
        progress = Progress("probe", len(chosen))
        names = ds.sets["train"].names if ds.recorded else {}  # recorded data: its own names for its streams
        out_rows = [
            _probe_row(r, c, inputs[id(d)], labels, present, progress, names)
            for r, c, d in zip(chosen, configs, datasets)
        ]

    seconds = time.perf_counter() - t0
    result = Probe(
        method={
            "summaries": ["mean", "sd"],
            "pca_above_step_dims": PCA_ABOVE,
            "pca_dims": PCA_DIMS,
            "c_grid": list(C_GRID),
            "solver": "lbfgs",
            "max_iter": MAX_ITER,
            **({"rotation_draws": ROTATION_DRAWS} if any(r.name.startswith(ROTATED) for r in chosen) else {}),
        },
        splits=tuple(present),
        classes=tuple(sorted(np.unique(labels["train"]).tolist())),
        inputs={name: i for key, (_, c) in loads.items() for name, i in _inputs_doc(inputs[key], c, names).items()},
        rows=tuple({k: v for k, v in r.items() if k != "predictions"} for r in out_rows),
    )
    samples = {
        "rows": {r["name"]: r["predictions"] for r in out_rows},
        "sequences": {s: documents.samples_doc(ds.sets[s]) for s in present if s != "train"},
    }
    return Probed(ds, seconds, result, samples)


def _inputs_doc(inputs: Mapping[str, Input], config, names: Mapping[str, str]) -> dict[str, Any]:
    """The inputs of one load as the JSON's "inputs": keyed by modality, the image read against
    its session's reference as "session:image"."""
    out = {}
    for m, i in inputs.items():
        rotated, base = m.startswith(ROTATED), m.removeprefix(ROTATED)
        session = base == "image" and config.image_reference == "session" and not rotated
        out[SESSION + m if session else m] = {
            **i.to_json(),
            "display_name": data.inputs_name((base,), names)
            + (" − session reference" if session or rotated else "")
            + (f", training frames rotated ({ROTATION_DRAWS} angles each)" if rotated else ""),
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
    name = ablation_rows.label(r.modalities, "attention", names=names) if names else r.label
    rotated = r.name.startswith(ROTATED)
    progress.start(name)
    t0 = time.perf_counter()
    features = {
        s: np.concatenate([inputs[ROTATED + m if rotated else m].features[s] for m in r.modalities], axis=1)
        for s in splits
    }
    if rotated:  # every training sequence once per angle drawn
        labels = {**labels, "train": np.tile(labels["train"], ROTATION_DRAWS)}
    result = fit(features, labels)
    seconds = time.perf_counter() - t0
    progress.finish(name, seconds, f"C={result['C']:g}, test {100 * result['accuracy'].get('test', np.nan):.1f} %")
    return {
        "name": r.name,
        "modalities": list(r.modalities),
        "display_name": name,
        **({"image_reference": config.image_reference} if "image" in r.modalities else {}),
        **({"rotated": True, "rotation_draws": ROTATION_DRAWS} if rotated else {}),
        "probe_dims": int(features["train"].shape[1]),
        "wall_s": seconds,
        **result,
        "collapsed": {s: findings.collapsed(p) for s, p in result["predictions"].items()},
    }
