"""Confidence a robot can act on: calibrated probabilities, when to stop rubbing, unknown fabrics.

    t = fit_temperature(val_logits, val_labels)        # one scalar per model; argmax unchanged
    p = calibrated(logits, t)                          # softmax(logits / t)
    ece(p, labels), reliability(p, labels)             # how far a probability can be trusted
    sequential(p_windows, threshold, max_windows)      # accumulate evidence until confident
    Mahalanobis.fit(train_latents, labels).score(z)    # "not one of the trained classes"

Temperature scaling (Guo et al., "On Calibration of Modern Neural Networks", ICML 2017) divides
the logits by one scalar fitted by the negative log-likelihood on held-out data. The sequential
rule treats the trial's successive non-overlapping windows as independent evidence (a naive-Bayes
product of their calibrated probabilities under a uniform prior) and stops when the best class's
posterior reaches the threshold, or at the maximum touch time. The feature-space unknown score is
the Mahalanobis distance to the nearest class mean under one covariance shared by the classes
(Lee et al., "A Simple Unified Framework for Detecting Out-of-Distribution Samples and
Adversarial Attacks", NeurIPS 2018), fitted on the training split's pooled latents.

A model's temperatures (one per seed) are kept beside its checkpoint in `TEMPERATURE_FILE`, so
that every consumer of its probabilities (the decision study, the live stream, the viewer)
applies the same calibration.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Sequence

import numpy as np
from scipy import optimize, special, stats

from fabricjax.errors import UserError
from fabricjax.store import atomic

TEMPERATURE_FILE = "confidence.json"  # in a checkpoint folder: {"temperature": {seed: T}, "fitted_on": split}
ECE_BINS = 15  # equal-width confidence bins of the expected calibration error and the reliability diagram
LOG_T_RANGE = (-4.0, 4.0)  # the fit's search interval of log T: temperatures e^-4 .. e^4
DECISION_THRESHOLD = 0.99  # the posterior at which the live stream and the decision study's summary decide
KNOWN_RECALL = 0.95  # the false-accept rate of unknowns is read where this share of known fabrics is accepted


def calibrated(logits: np.ndarray, temperature: float = 1.0) -> np.ndarray:
    """softmax(logits / temperature) along the last axis, in float64."""
    return special.softmax(np.asarray(logits, np.float64) / temperature, axis=-1)


def nll(logits: np.ndarray, labels: np.ndarray, temperature: float) -> float:
    """Mean negative log-likelihood of `labels` under softmax(logits / temperature)."""
    z = np.asarray(logits, np.float64) / temperature
    return float(np.mean(special.logsumexp(z, axis=-1) - z[np.arange(len(z)), labels]))


def fit_temperature(logits: np.ndarray, labels: np.ndarray) -> float:
    """The temperature minimising the NLL of `labels` (bounded search over log T in `LOG_T_RANGE`)."""
    labels = np.asarray(labels)
    if len(labels) == 0:
        raise ValueError("no samples to fit a temperature on")
    res = optimize.minimize_scalar(
        lambda s: nll(logits, labels, float(np.exp(s))), bounds=LOG_T_RANGE, method="bounded"
    )
    return float(np.exp(res.x))


def reliability(probs: np.ndarray, labels: np.ndarray, bins: int = ECE_BINS) -> dict[str, list]:
    """Per equal-width confidence bin: sample count, mean confidence and accuracy of the argmax
    (None for empty bins)."""
    conf, correct = np.max(probs, axis=-1), np.argmax(probs, axis=-1) == np.asarray(labels)
    which = np.clip((conf * bins).astype(int), 0, bins - 1)
    count = np.bincount(which, minlength=bins)
    mean = lambda v: [float(v[which == b].mean()) if count[b] else None for b in range(bins)]  # noqa: E731
    return {"count": count.tolist(), "confidence": mean(conf), "accuracy": mean(correct.astype(np.float64))}


def ece(probs: np.ndarray, labels: np.ndarray, bins: int = ECE_BINS) -> float:
    """Expected calibration error: the sample-weighted mean |accuracy - confidence| over bins."""
    r = reliability(probs, labels, bins)
    n = sum(r["count"])
    return float(sum(c * abs(a - p) for c, a, p in zip(r["count"], r["accuracy"], r["confidence"]) if c) / max(n, 1))


@dataclasses.dataclass(frozen=True)
class Decision:
    """A sequential decision over one trial's windows: the class (argmax of the posterior), the
    number of windows it took, whether the threshold was reached (else the maximum time decided),
    and the posterior after each window seen."""

    label: int
    windows: int
    confident: bool
    posteriors: np.ndarray  # (windows, classes)


class Accumulator:
    """The running posterior of one trial: `add` one window's calibrated probabilities at a time."""

    def __init__(self, threshold: float, max_windows: int | None = None):
        self.threshold, self.max_windows = threshold, max_windows
        self.log_post: np.ndarray | None = None
        self.windows = 0

    def add(self, probs: np.ndarray) -> np.ndarray:
        """The posterior after this window (a uniform prior times every window's probabilities)."""
        lp = np.log(np.clip(np.asarray(probs, np.float64), 1e-300, None))
        self.log_post = lp if self.log_post is None else self.log_post + lp
        self.windows += 1
        return self.posterior

    @property
    def posterior(self) -> np.ndarray:
        return special.softmax(self.log_post)

    @property
    def decided(self) -> bool:
        """The best class's posterior has reached the threshold, or the maximum time is up."""
        return self.windows > 0 and (
            self.posterior.max() >= self.threshold
            or (self.max_windows is not None and self.windows >= self.max_windows)
        )


def sequential(window_probs: np.ndarray, threshold: float, max_windows: int | None = None) -> Decision:
    """Decide over a trial's windows in order ((windows, classes) calibrated probabilities): stop
    at the first window where the posterior's maximum reaches `threshold`, else at `max_windows`
    (None: the trial's last window)."""
    acc, posts = Accumulator(threshold, max_windows), []
    for p in window_probs:
        posts.append(acc.add(p))
        if acc.decided:
            break
    return Decision(int(np.argmax(posts[-1])), acc.windows, bool(posts[-1].max() >= threshold), np.stack(posts))


@dataclasses.dataclass(frozen=True)
class Mahalanobis:
    """Class means and one shared (shrunk) covariance of training latents; `score` is the squared
    Mahalanobis distance to the nearest class mean (larger: less like any trained class)."""

    means: np.ndarray  # (classes present, D)
    precision: np.ndarray  # (D, D)

    @classmethod
    def fit(cls, latents: np.ndarray, labels: np.ndarray, shrinkage: float = 1e-3) -> "Mahalanobis":
        """Fit on training latents (N, D); the covariance gets `shrinkage` x its mean variance on
        the diagonal so that it is invertible with fewer samples than dimensions."""
        x, labels = np.asarray(latents, np.float64), np.asarray(labels)
        classes = np.unique(labels)
        means = np.stack([x[labels == c].mean(axis=0) for c in classes])
        centred = x - means[np.searchsorted(classes, labels)]
        cov = centred.T @ centred / max(len(x) - len(classes), 1)
        cov += shrinkage * max(float(np.trace(cov)) / len(cov), 1e-12) * np.eye(len(cov))
        return cls(means, np.linalg.pinv(cov, hermitian=True))

    def score(self, latents: np.ndarray) -> np.ndarray:
        d = np.asarray(latents, np.float64)[:, None, :] - self.means[None]
        return np.einsum("nkd,de,nke->nk", d, self.precision, d).min(axis=1)


def auroc(known: np.ndarray, unknown: np.ndarray) -> float:
    """Area under the ROC of telling `unknown` from `known` by score (higher: unknown); ties count half."""
    k, u = np.asarray(known, np.float64), np.asarray(unknown, np.float64)
    if not len(k) or not len(u):
        raise ValueError("AUROC needs known and unknown samples")
    r = stats.rankdata(np.concatenate([k, u]))
    return float((r[len(k) :].sum() - len(u) * (len(u) + 1) / 2) / (len(k) * len(u)))


def false_accept_rate(known: np.ndarray, unknown: np.ndarray, recall: float = KNOWN_RECALL) -> tuple[float, float]:
    """(share of unknowns accepted, threshold) where a score at or below the threshold is accepted
    as known and the threshold accepts `recall` of the known samples."""
    threshold = float(np.quantile(np.asarray(known, np.float64), recall))
    return float(np.mean(np.asarray(unknown) <= threshold)), threshold


def save_temperatures(directory: str | os.PathLike, temperatures: dict[int, float], fitted_on: str) -> Path:
    """Write the per-seed temperatures beside the checkpoint in `directory` (atomically)."""
    path = Path(directory) / TEMPERATURE_FILE
    doc = {"temperature": {str(s): float(t) for s, t in temperatures.items()}, "fitted_on": fitted_on}
    with atomic.atomic_open(path, "w") as f:
        f.write(json.dumps(doc, indent=1) + "\n")
    return path


def load_temperature(directory: str | os.PathLike, seed: int) -> float | None:
    """The temperature fitted for `seed` of the checkpoint in `directory`, None where none was."""
    path = Path(directory) / TEMPERATURE_FILE
    if not path.exists():
        return None
    try:
        t = json.loads(path.read_text())["temperature"].get(str(seed))
    except (ValueError, KeyError, AttributeError) as e:
        raise UserError(f"{path}: field 'temperature': not a JSON object of per-seed temperatures ({e})") from None
    if t is not None and not (isinstance(t, (int, float)) and np.isfinite(t) and t > 0):
        raise UserError(f"{path}: field 'temperature.{seed}': {t!r} is not a positive number")
    return None if t is None else float(t)


def decision_curve(
    trials: Sequence[np.ndarray],
    labels: Sequence[int],
    thresholds: Sequence[float],
    max_windows: int | None,
    window_s: float,
) -> list[dict[str, float]]:
    """Per threshold: accuracy of the sequential decisions over `trials` ((windows, classes)
    calibrated probabilities each, with their true `labels`) and the mean touch time to decision
    (windows x `window_s`)."""
    out = []
    for th in thresholds:
        ds = [sequential(p, th, max_windows) for p in trials]
        out.append(
            {
                "threshold": float(th),
                "accuracy": float(np.mean([d.label == y for d, y in zip(ds, labels)])),
                "mean_touch_s": float(np.mean([d.windows for d in ds]) * window_s),
                "confident": float(np.mean([d.confident for d in ds])),
            }
        )
    return out
