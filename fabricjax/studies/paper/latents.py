"""t-SNE of latents (one point per fabric: its first test-day trial's mean) from a restored checkpoint (the paper's Fig.
latent_features).

    python -m experiments.properties --seeds=5          # prints and records its checkpoints
    python -m experiments.latents --checkpoint=workspace/checkpoints/properties/internal+proprio+image-<tag>

The checkpoint's own config says which preset, modalities and fabric exclusions to load. One seed
is used: the one with the best validation score, or `seed`. For each fabric 1-23 on the test day
(training fabrics and holdouts alike) its first test trial is encoded; the backbone's latents
(`FabricNet.latents`) are averaged over the steps and over the trial's sequences, and the points
are embedded with t-SNE (perplexity scaled to the number of points).

The paper reads its figure as: holdout fabrics land near training fabrics with the same property
levels. `neighbour_agreement` makes that a number, in the latent space itself (t-SNE preserves
neighbourhoods only loosely): for each holdout, the fraction of the three properties on which it
agrees with its nearest training fabric, against the agreement with a training fabric drawn at
random (its chance level); and, per holdout and property, whether the training fabrics sharing
its level are nearer on average than those that do not. `checklist` states both as findings.

On recorded data (`--data_dir`) the fabrics are the data's classes (every class on its test and
holdout splits), their names and property levels the data's own (`recorded_fabrics`: never the
catalog's), the holdouts the classes of its holdout split; the neighbour numbers are reported as
measurements, without the paper's reading as a checklist.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import jax
import numpy as np
from flax import nnx
from sklearn.manifold import TSNE

from fabricjax import catalog
from fabricjax.errors import UserError
from fabricjax.reporting import plots, results_files
from fabricjax.sequences import data
from fabricjax.store import atomic, workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents, findings, loading
from fabricjax.training import checkpoint, train

TITLE, PAPER = "Latent space", "Fig. latent_features"
BATCH = 32  # sequences per latent evaluation


def trial_means(
    graphdef, params, ss: data.SequenceSet, modalities, fabric_ids
) -> tuple[np.ndarray, list[int], list[str], list[int]]:
    """Per fabric of `fabric_ids` in `ss`, its first test trial's latent mean: (points, fabric ids,
    trial keys, sequences per trial)."""
    encode = jax.jit(lambda p, x: nnx.merge(graphdef, p).latents(x).mean(axis=1))
    points, fabrics, keys, counts = [], [], [], []
    for fid in sorted(set(ss.info["fabric_id"].tolist()) & set(fabric_ids)):
        mine = ss.info["fabric_id"] == fid
        first = min(zip(ss.info["trial"][mine].tolist(), ss.info["trial_key"][mine].tolist()))[1]
        idx = np.flatnonzero(ss.info["trial_key"] == first)
        steps = [
            np.asarray(encode(params, {m: ss.inputs[m][idx[i : i + BATCH]] for m in modalities}))
            for i in range(0, idx.size, BATCH)
        ]
        points.append(np.concatenate(steps).mean(axis=0))
        fabrics.append(int(fid))
        keys.append(str(first))
        counts.append(int(idx.size))
    return np.stack(points), fabrics, keys, counts


def tsne(points: np.ndarray, seed: int = 0) -> tuple[np.ndarray, float | None]:
    """2-D t-SNE coordinates and the perplexity used (min(30, (n - 1) / 3), at least 1).

    Fewer than three points, or points that are all the same, have no neighbourhood structure to
    embed: they map to the origin (finite) and the perplexity is None.
    """
    x = np.asarray(points, np.float64)
    x = x - x.mean(axis=0)
    if len(x) < 3 or np.abs(x).max() < 1e-12:
        return np.zeros((len(x), 2)), None
    perplexity = max(1.0, min(30.0, (len(x) - 1) / 3))
    xy = TSNE(n_components=2, perplexity=perplexity, init="pca", random_state=seed).fit_transform(x)
    if not np.isfinite(xy).all():
        raise FloatingPointError("t-SNE produced non-finite coordinates")
    return xy, perplexity


def run(checkpoint_dir, *, seed: int | None = None, where: Location = Location()) -> dict[str, Any]:
    """Restore, encode, embed, plot: writes results/latents.{png,json}; returns the JSON."""
    graphdef, state, config, seeds, for_, trained_on = train.restore(
        checkpoint_dir
    )  # under the checkpoint's own config
    if where.data_dir is None:  # the simulated hand's holdouts: the model must not have trained on them
        trained_holdouts = sorted(
            set(catalog.PROPERTY_HOLDOUTS) - set(catalog.NEW_FABRICS) - set(for_["unseen_fabrics"])
        )
        checkpoint.require(
            checkpoint_dir,
            for_,
            "latents",
            f"a model that never saw the holdout fabrics {', '.join(map(str, catalog.PROPERTY_HOLDOUTS))} "
            "(a properties-study checkpoint, listed in its properties.md)",
            not trained_holdouts,
        )
    best_val = np.asarray(state.best_val, np.float64)
    if seed is None:
        index = int(np.argmax(best_val))
    elif seed in seeds:
        index = seeds.index(seed)
    else:
        raise UserError(f"seed {seed} is not in the checkpoint in {checkpoint_dir} (seeds {seeds})")
    params = checkpoint.select_seed(state.best_params, index)

    ds = loading.load_dataset(config, data_dir=where.data_dir, workdir=where.workdir, split_names=("test", "holdout"))
    checkpoint.require_data(checkpoint_dir, trained_on, ds.sets["test"].dataset)
    test_day = _concat([ds.sets["test"], ds.sets["holdout"]])
    if ds.recorded:
        known, holdouts = (
            recorded_fabrics(test_day, ds.classes),
            sorted(set(ds.sets["holdout"].info["fabric_id"].tolist())),
        )
    else:  # the hand's fabrics 1-23: class 0 (no fabric) has no properties
        known, holdouts = catalog_fabrics(set(test_day.info["fabric_id"].tolist()) - {0}), catalog.PROPERTY_HOLDOUTS
    points, fabrics, keys, counts = trial_means(graphdef, params, test_day, config.modalities, known)
    xy, perplexity = tsne(points)
    agreement = neighbour_agreement(points, fabrics, known, holdouts)
    with atomic.together():  # the figure, Markdown and JSON of this run, or none of them
        png = plots.plot_latents(
            where.results_dir() / "latents.png",
            xy,
            fabrics,
            known,
            holdouts,
            title=f"t-SNE of latents, one point per fabric: its first test-day trial's mean\n"
            f"({data.inputs_name(config.modalities, ds.sets['test'].names if ds.recorded else None)}, seed "
            f"{seeds[index]}; holdouts outlined)",
            neighbours={p["holdout"]: p["nearest"] for p in agreement["pairs"]},
        )
        doc = {
            **documents.header("latents", module=__name__, command=where.command, preset=config.preset, dataset=ds),
            "checkpoint": workspace.shown(checkpoint_dir),
            "config": config.to_json(),
            "checkpoint_seeds": seeds,
            "best_val_per_seed": best_val.tolist(),
            "seed": seeds[index],
            "perplexity": perplexity,
            "points": [
                {"fabric_id": f, "trial_key": k, "sequences": c, "xy": p.tolist()}
                for f, k, c, p in zip(fabrics, keys, counts, xy)
            ],
            "holdouts": list(holdouts),
            "neighbours": agreement,
            # the checklist holds the paper's reading of its figure: recorded data is not the paper's
            "findings": [] if ds.recorded else [f.to_json() for f in checklist(agreement)],
        }
        return results_files.write(where.results_dir(), doc, markdown, [png])


def catalog_fabrics(ids) -> dict[int, tuple[str, dict[str, int | None]]]:
    """Per fabric id of the hand: its name and property levels, from the catalog."""
    return {int(f): (catalog.fabric(f).name, catalog.fabric(f).properties) for f in ids}


def recorded_fabrics(ss: data.SequenceSet, classes: Sequence[str]) -> dict[int, tuple[str, dict[str, int | None]]]:
    """Per class of recorded data: its name and the property levels its trials give (None where
    none does: a rig's levels are its own, only where the manifest gives them); a class whose
    trials give two levels of one property has no place in the figure's encoding, an error."""
    out = {}
    for fid in sorted(set(ss.info["fabric_id"].tolist())):
        mine = ss.info["fabric_id"] == fid
        levels = {p: sorted(set(ss.labels[p][mine].tolist()) - {-1}) for p in catalog.PROPERTY_LEVELS}
        for p, v in levels.items():
            if len(v) > 1:
                raise UserError(
                    f"class {classes[fid]!r}: its trials give {p} levels {v}; one class, one level (the "
                    f"manifest's {p} column)"
                )
        out[int(fid)] = (classes[fid], {p: v[0] if v else None for p, v in levels.items()})
    return out


def _agreement(
    a: int, b: int, fabrics: Mapping[int, tuple[str, Mapping[str, int | None]]] | None = None
) -> float | None:
    """Fraction of the properties known for both fabrics on which their levels are equal (levels
    from `fabrics`, id -> name and levels; None: the catalog's)."""
    fabrics = fabrics if fabrics is not None else catalog_fabrics((a, b))
    pa, pb = fabrics[a][1], fabrics[b][1]
    known = [p for p in pa if pa[p] is not None and pb[p] is not None]
    return None if not known else float(np.mean([pa[p] == pb[p] for p in known]))


def neighbour_agreement(
    points: np.ndarray,
    fabric_ids: list[int],
    fabrics: Mapping[int, tuple[str, Mapping[str, int | None]]] | None = None,
    holdouts=catalog.PROPERTY_HOLDOUTS,
) -> dict[str, Any]:
    """How well the latent space groups unseen fabrics with trained fabrics of the same property
    levels (Euclidean distance between the fabrics' points; fabrics without properties skipped;
    levels from `fabrics` as in `_agreement`).

    pairs: per holdout, its nearest training fabric, their agreement (fraction of properties with
    equal levels) and the chance level (mean agreement with every training fabric);
    agreement / chance: their means over holdouts; nearer_when_shared: per property, for each
    holdout whose level some but not all training fabrics share, whether the sharing ones are
    nearer on average; nearer_fraction: the fraction of those cases, 0.5 by chance.
    """
    x = np.asarray(points, np.float64)
    ids = [int(f) for f in fabric_ids]
    fabrics = fabrics if fabrics is not None else catalog_fabrics(ids)
    agreement = lambda a, b: _agreement(a, b, fabrics)  # noqa: E731
    known = [i for i, f in enumerate(ids) if agreement(f, f) is not None]
    train = [i for i in known if ids[i] not in holdouts]
    held = [i for i in known if ids[i] in holdouts]
    dist = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=-1)
    pairs, nearer = [], {p: [] for p in catalog.PROPERTY_LEVELS}
    for h in held:
        t = train[int(np.argmin(dist[h, train]))] if train else None
        if t is None:
            break
        chance = float(np.mean([agreement(ids[h], ids[j]) for j in train]))
        pairs.append(
            {
                "holdout": ids[h],
                "nearest": ids[t],
                "distance": float(dist[h, t]),
                "agreement": agreement(ids[h], ids[t]),
                "chance": chance,
            }
        )
        for prop, level in fabrics[ids[h]][1].items():
            if level is None:  # unknown (a rig's level not given): nothing to share
                continue
            share = [j for j in train if fabrics[ids[j]][1][prop] == level]
            other = [j for j in train if fabrics[ids[j]][1][prop] not in (None, level)]
            if share and other:
                nearer[prop].append(
                    {
                        "holdout": ids[h],
                        "shared_mean_distance": float(dist[h, share].mean()),
                        "other_mean_distance": float(dist[h, other].mean()),
                    }
                )
    cases = [c["shared_mean_distance"] < c["other_mean_distance"] for v in nearer.values() for c in v]
    return {
        "pairs": pairs,
        "agreement": float(np.mean([p["agreement"] for p in pairs])) if pairs else None,
        "chance": float(np.mean([p["chance"] for p in pairs])) if pairs else None,
        "nearer_when_shared": nearer,
        "nearer_fraction": float(np.mean(cases)) if cases else None,
        "nearer_cases": len(cases),
    }


def checklist(agreement: dict[str, Any]) -> list[findings.Finding]:
    """The paper's reading of its t-SNE figure as predicates over `neighbour_agreement`'s numbers."""
    claim = (
        "a holdout's nearest training fabric in latent space shares more of its property levels than a random "
        "training fabric"
    )
    if agreement["agreement"] is None:
        out = [findings.Finding(claim, None, "needs holdout and training fabrics with properties, not in the data")]
    else:
        pairs = ", ".join(f"{p['holdout']}->{p['nearest']} {100 * p['agreement']:.0f} %" for p in agreement["pairs"])
        out = [
            findings.Finding(
                claim,
                bool(agreement["agreement"] > agreement["chance"]),
                f"nearest-neighbour property agreement {100 * agreement['agreement']:.1f} % against chance "
                f"{100 * agreement['chance']:.1f} % (holdout->nearest: {pairs})",
            )
        ]
    claim = (
        "holdouts lie nearer to the training fabrics sharing a property level than to those that do not (most "
        "holdout-property cases)"
    )
    if agreement["nearer_fraction"] is None:
        out.append(
            findings.Finding(claim, None, "no holdout-property case with both sharing and other training fabrics")
        )
    else:
        out.append(
            findings.Finding(
                claim,
                bool(agreement["nearer_fraction"] > 0.5),
                f"sharing fabrics nearer on average in {100 * agreement['nearer_fraction']:.0f} % of "
                f"{agreement['nearer_cases']} holdout-property cases (chance 50 %)",
            )
        )
    return out


def markdown(doc: dict[str, Any]) -> str:
    c = doc["config"]
    recorded = documents.recorded(doc)
    points = "classes of the test and holdout splits" if recorded else "fabrics on the test day"
    lines = [
        documents.title(doc, TITLE, PAPER),
        "",
        documents.header_markdown(doc).rstrip("\n"),
        f"- checkpoint: `{doc['checkpoint']}` ({'+'.join(c['modalities'])}; seed {doc['seed']}, the best by "
        f"validation of seeds {doc['checkpoint_seeds']})",
        f"- points: {len(doc['points'])} {points}, one trial each; t-SNE perplexity {doc['perplexity'] or 0:.2f}",
        "",
        "![t-SNE of latents, one point per fabric: its first test-day trial's mean](latents.png)",
        "",
    ]
    if recorded:  # the measurements `checklist` would judge, without the paper's reading
        lines += [
            "## Holdout classes and their neighbours in latent space",
            "",
            *[f"- {f.evidence}" for f in checklist(doc["neighbours"])],
            "",
        ]
    else:
        lines += [
            "## Findings checklist (the paper's reading of its figure)",
            "",
            findings.markdown(doc["findings"], counted=not documents.counts_no_claims(doc)),
        ]
    return "\n".join(lines)


def _concat(sets: list[data.SequenceSet]) -> data.SequenceSet:
    join = lambda get: {k: np.concatenate([get(s)[k] for s in sets]) for k in get(sets[0])}  # noqa: E731
    return data.SequenceSet(join(lambda s: s.inputs), join(lambda s: s.labels), join(lambda s: s.info))
