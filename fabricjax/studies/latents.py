"""t-SNE of per-trial mean latents from a restored checkpoint (the paper's Fig. latent_features).

    python -m experiments.properties --seeds=5          # prints and records its checkpoints
    python -m experiments.latents --checkpoint=workspace/checkpoints/properties/minsound+minsight-<tag>

The checkpoint's own config says which preset, modalities and fabric exclusions to load. One seed
is used: the one with the best validation score, or `seed`. For each fabric 1-23 on the test day
(training fabrics and holdouts alike) its first test trial is encoded; the backbone's latents
(`FabricNet.latents`) are averaged over the steps and over the trial's sequences, and the points
are embedded with t-SNE (perplexity scaled to the number of points).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np
from flax import nnx
from sklearn.manifold import TSNE

from fabricjax import checkpoint, data, plots, report, train
from fabricjax.config import Config
from fabricjax.studies import common

BATCH = 32  # sequences per latent evaluation


def trial_means(graphdef, params, ss: data.SequenceSet, modalities) -> tuple[np.ndarray, list[int], list[str], list[int]]:
    """Per fabric (>= 1), its first test trial's latent mean: (points, fabric ids, trial keys, sequences per trial)."""
    encode = jax.jit(lambda p, x: nnx.merge(graphdef, p).latents(x).mean(axis=1))
    points, fabrics, keys, counts = [], [], [], []
    for fid in sorted(set(ss.info["fabric_id"].tolist()) - {0}):
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


def run(checkpoint_dir, *, seed: int | None = None, workdir=None, data_dir=None, results="results", command: str | None = None) -> dict[str, Any]:
    """Restore, encode, embed, plot: writes results/latents.{png,json}; returns the JSON."""
    saved = checkpoint.read_meta(checkpoint.manager(checkpoint_dir))
    config = Config.from_json(saved["config"])
    graphdef, state = train.restore(checkpoint_dir, config)
    best_val = np.asarray(state["best_val"], np.float64)
    if seed is None:
        index = int(np.argmax(best_val))
    elif seed in saved["seeds"]:
        index = saved["seeds"].index(seed)
    else:
        raise KeyError(f"seed {seed} is not in the checkpoint in {checkpoint_dir} (seeds {saved['seeds']})")
    params = checkpoint.select_seed(state["best_params"], index)

    ds = common.load_dataset(config, data_dir=data_dir, workdir=workdir, split_names=("test", "holdout"))
    test_day = _concat([ds.sets["test"], ds.sets["holdout"]])
    points, fabrics, keys, counts = trial_means(graphdef, params, test_day, config.modalities)
    xy, perplexity = tsne(points)
    png = plots.plot_latents(
        common.results_path(results) / "latents.png", xy, fabrics,
        title=f"t-SNE of per-trial mean latents ({'+'.join(config.modalities)}, seed {saved['seeds'][index]})",
    )
    doc = {
        "study": "latents",
        "command": command or common.command_line(),
        "checkpoint": str(checkpoint_dir),
        "config": config.to_json(),
        "seeds": saved["seeds"],
        "best_val_per_seed": best_val.tolist(),
        "seed": saved["seeds"][index],
        "machine": report.machine(),
        "dataset": common.dataset_doc(ds),
        "perplexity": perplexity,
        "points": [
            {"fabric_id": f, "trial_key": k, "sequences": c, "xy": p.tolist()}
            for f, k, c, p in zip(fabrics, keys, counts, xy)
        ],
        "png": str(png),
    }
    report.write_json(common.results_path(results) / "latents.json", doc)
    return doc


def _concat(sets: list[data.SequenceSet]) -> data.SequenceSet:
    join = lambda get: {k: np.concatenate([get(s)[k] for s in sets]) for k in get(sets[0])}  # noqa: E731
    return data.SequenceSet(join(lambda s: s.inputs), join(lambda s: s.labels), join(lambda s: s.info))
