"""The linear probe: what a set of inputs carries about the fabric before any model of ours.

Each sequence is summarised by every dimension's mean and standard deviation over its steps
(`summarise`); each input's summaries are standardised on the training split and, above
`PCA_ABOVE` dimensions per step, reduced by PCA (`prepare`); a multinomial logistic regression
(scikit-learn, lbfgs) reads the concatenated features, its regularisation C chosen on the
validation split from `C_GRID` (`fit`). `steadiness` says how much of an input's variance lies
within sequences. The probe study (`studies.diagnostics.probe`) and the ablation's recorded-data rows
(`studies.paper.ablation`) both use it.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from typing import Any, Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from absl import logging
from sklearn.decomposition import PCA
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import LogisticRegression
from sklearn.preprocessing import StandardScaler
from threadpoolctl import threadpool_limits

from fabricjax.features import images
from fabricjax.studies.machinery import loading

C_GRID = (0.001, 0.01, 0.1, 1.0, 10.0)  # inverse L2 strength, chosen by validation accuracy
PCA_ABOVE = 400  # an input with more dimensions per step than this is reduced by PCA ...
PCA_DIMS = 200  # ... to at most this many components of its summaries
MAX_ITER = 1000  # lbfgs iterations per C (warm-started from the previous C); reported if reached
# BLAS threads of the PCA and the fits: one; on these small problems more threads only contend for
# the cores with the rest of the process.
BLAS_THREADS = 1
SUMMARY_CHUNK = 256  # sequences converted to float32 at a time (a default-preset image chunk: 184 MB)
# Angles drawn per training sequence where the probe reads frames rotated as training rotates them
# (`summarise_rotated`): the model sees a new angle every epoch; a few draws stand for that spread
# at a few times the summaries' memory.
ROTATION_DRAWS = 4
ROTATION_SEED = 0  # the rotated probe's angles: fixed, so that the probe stays deterministic


def summarise(x: np.ndarray) -> np.ndarray:
    """(S, N, ...) sequences -> (S, 2 D) float32: each of the D = prod(...) dimensions' mean over
    the N steps, then its standard deviation, converted in chunks so that a uint8 image set is
    never held as float32 whole."""
    flat = x.reshape(*x.shape[:2], int(np.prod(x.shape[2:])))
    d = flat.shape[2]
    out = np.empty((len(flat), 2 * d), np.float32)
    for i in range(0, len(flat), SUMMARY_CHUNK):
        part = flat[i : i + SUMMARY_CHUNK].astype(np.float32)
        out[i : i + SUMMARY_CHUNK, :d] = part.mean(axis=1)
        out[i : i + SUMMARY_CHUNK, d:] = part.std(axis=1)
    return out


def summarise_rotated(frames: np.ndarray, draws: int = ROTATION_DRAWS, seed: int = ROTATION_SEED) -> np.ndarray:
    """(S, N, H, W, C) frames -> (draws * S, 2 D) float32 summaries (`summarise`) of every
    sequence turned by `draws` angles, draw-major: one angle per sequence and draw, uniform in
    +-`images.MAX_DEGREES` and the same for all its frames, applied by the model's rotation path
    (`images.rotate_frames`, 0 filling what the turn brings in). Rotated a chunk at a time, so the
    float32 frames are never held whole."""
    s, d = len(frames), int(np.prod(frames.shape[2:]))
    turn = jax.jit(jax.vmap(images.rotate_frames))
    out = np.empty((draws * s, 2 * d), np.float32)
    for draw in range(draws):
        key = jax.random.fold_in(jax.random.key(seed), draw)
        degrees = np.asarray(images.random_angles(key, s))
        for i in range(0, s, SUMMARY_CHUNK):
            part = np.asarray(turn(jnp.asarray(frames[i : i + SUMMARY_CHUNK]), degrees[i : i + SUMMARY_CHUNK]))
            out[draw * s + i : draw * s + i + len(part)] = summarise(part)
    return out


@dataclasses.dataclass
class Input:
    """One input's probe features on every split: its summaries standardised (every dimension on
    the same scale for the L2 penalty), then PCA-reduced where the input is wide. The components
    are divided by one common factor to a mean variance of 1, like a standardised input's
    dimensions, so that in a fusion row a wide input's components are not cheaper to use than a
    narrow input's dimensions, while within the input the leading components keep their larger
    share (whitening each would weigh the trailing noise like the leading structure)."""

    step_dims: int
    summary_dims: int
    features: dict[str, np.ndarray]
    explained_variance: float | None  # fraction of the standardised summaries' variance the PCA keeps
    seconds: float

    def describe(self, modality: str) -> str:
        """One line in words: the input's dimensions from step to probe, and the time it took."""
        dims = self.to_json()
        kept = (
            ""
            if self.explained_variance is None
            else f" (PCA keeping {100 * self.explained_variance:.1f} % of the variance)"
        )
        return (
            f"{modality}: {dims['step_dims']} values per step, {dims['summary_dims']} per sequence summary, "
            f"{dims['probe_dims']} into the probe{kept}; {self.seconds:.2f} s"
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "step_dims": self.step_dims,
            "summary_dims": self.summary_dims,
            "probe_dims": next(iter(self.features.values())).shape[1],
            "explained_variance": self.explained_variance,
            "seconds": self.seconds,
        }


def prepare(sequences: Mapping[str, np.ndarray], rotated: bool = False) -> Input:
    """An input's sequences per split (`sequences["train"]` fits the scaling and the PCA) -> `Input`.
    `rotated` (frames only): the training split is read as `summarise_rotated` turns it,
    `ROTATION_DRAWS` rows per sequence, the other splits unrotated, as the model is trained and scored."""
    t0 = time.perf_counter()
    train = sequences["train"]
    step_dims = int(np.prod(train.shape[2:]))
    summaries = {s: summarise_rotated(x) if rotated and s == "train" else summarise(x) for s, x in sequences.items()}
    scaler = StandardScaler().fit(summaries["train"])
    features = {s: scaler.transform(v).astype(np.float32) for s, v in summaries.items()}
    explained = None
    if step_dims > PCA_ABOVE:
        pca = PCA(n_components=min(PCA_DIMS, *features["train"].shape), random_state=0).fit(features["train"])
        unit = np.sqrt(np.mean(pca.explained_variance_))  # one factor for all components: mean variance 1
        features = {s: (pca.transform(v) / unit).astype(np.float32) for s, v in features.items()}
        explained = float(pca.explained_variance_ratio_.sum())
    return Input(step_dims, 2 * step_dims, features, explained, time.perf_counter() - t0)


def steadiness(x: np.ndarray) -> float:
    """How much an input's dimensions change within sequences compared with across them: per
    dimension, the mean within-sequence variance over the total (within + the variance of the
    sequence means), the median over dimensions (constant dimensions left out; 1.0 when all are).
    Near 0, the input is steady within a sequence: its information is its level, which the paper's
    per-sequence [0, 1] rescale erases."""
    summaries = summarise(x).astype(np.float64)
    d = summaries.shape[1] // 2
    within, across = (summaries[:, d:] ** 2).mean(axis=0), summaries[:, :d].var(axis=0)
    total = within + across
    varying = total > 0
    return float(np.median(within[varying] / total[varying])) if varying.any() else 1.0


def prepare_inputs(sets: Mapping[str, Any], modalities: Sequence[str], splits: Sequence[str]) -> dict[str, Input]:
    """Each of `modalities`' probe features on `splits` of `sets` (split -> `data.SequenceSet`)."""
    inputs = {}
    with threadpool_limits(BLAS_THREADS):
        for m in modalities:
            inputs[m] = prepare({s: sets[s].inputs[m] for s in splits})  # every row has the same bandwidth
            logging.info("probe: %s", inputs[m].describe(m))
    return inputs


def fit_rows(sets: Mapping[str, Any], modality_sets: Sequence[Sequence[str]]) -> dict[frozenset, dict[str, Any]]:
    """The probe (`fit`) of every distinct set of inputs in `modality_sets`, on the train, val and
    test splits of `sets`: what a study trained on these sequences sets beside its rows."""
    splits = list(loading.TRAIN_VAL_TEST)
    wanted = {frozenset(m): tuple(m) for m in modality_sets}
    inputs = prepare_inputs(sets, sorted({m for ms in wanted.values() for m in ms}), splits)
    labels = {s: sets[s].labels["fabric"] for s in splits}
    with threadpool_limits(BLAS_THREADS):
        return {
            k: fit({s: np.concatenate([inputs[m].features[s] for m in ms], axis=1) for s in splits}, labels)
            for k, ms in wanted.items()
        }


def fit(
    x: Mapping[str, np.ndarray], labels: Mapping[str, np.ndarray], c_grid: Sequence[float] = C_GRID
) -> dict[str, Any]:
    """Logistic regression on the features `x` of every split (fitted on `x["train"]`) for every
    C of `c_grid`, ascending, each fit warm-started from the last; the chosen C is the one with
    the best validation accuracy (the smallest on a tie). Returns every C's accuracy on every
    split, the chosen C and its predictions on every split but train."""
    model = LogisticRegression(solver="lbfgs", max_iter=MAX_ITER, warm_start=True)
    per_c, predictions = [], []
    for c in sorted(c_grid):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)  # reported below instead
            model.set_params(C=c).fit(x["train"], labels["train"])
        iterations = int(np.max(model.n_iter_))
        predicted = {s: model.predict(v) for s, v in x.items()}
        per_c.append(
            {
                "C": c,
                "iterations": iterations,
                "converged": iterations < MAX_ITER,
                "accuracy": {s: float(np.mean(p == labels[s])) for s, p in predicted.items()},
            }
        )
        predictions.append(predicted)
    best = int(np.argmax([e["accuracy"]["val"] for e in per_c]))  # argmax: the first, i.e. the smallest C, on a tie
    chosen = per_c[best]
    return {
        "C": chosen["C"],
        "converged": chosen["converged"],
        "accuracy": chosen["accuracy"],
        "per_c": per_c,
        "predictions": {s: p.tolist() for s, p in predictions[best].items() if s != "train"},
    }
