"""Honest statistics for the tables: mean +- SD over seeds and paired Wilcoxon signed-rank tests;
and the one summary of repeated timings (`percentiles_ms`: p50 / p99 in milliseconds).

Every test result says what was paired (the pairing unit), which variant ran (exact sign-flip
enumeration, which stays exact with tied and zero differences, or the normal approximation for
many pairs; always two-sided) and the smallest p-value that test could ever give, so nobody reads
p = 0.0625 over five seeds as "not significant" without knowing it is the floor.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats as sps


def confusion_matrix(labels, predictions, n_classes: int) -> np.ndarray:
    """Counts of (true class, predicted class), true class by row."""
    cm = np.zeros((n_classes, n_classes), np.int64)
    np.add.at(cm, (np.asarray(labels), np.asarray(predictions)), 1)
    return cm


def mean_sd(values) -> tuple[float, float]:
    """Mean and sample SD (ddof=1); the SD of a single value is 0, not NaN."""
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size == 0:
        raise ValueError("mean_sd of no values")
    if not np.isfinite(v).all():
        raise ValueError(f"mean_sd of non-finite values {v.tolist()}")
    return float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else 0.0


def format_mean_sd(values, scale: float = 100.0, digits: int = 2) -> str:
    m, s = mean_sd(np.asarray(values) * scale)
    return f"{m:.{digits}f} ± {s:.{digits}f}"


def percentiles_ms(seconds) -> dict[str, float]:
    """p50 / p99 in milliseconds of repeated timings (seconds): {"p50_ms": ..., "p99_ms": ...}."""
    ms = 1e3 * np.asarray(seconds)
    return {"p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99))}


EXACT = "exact (sign-flip enumeration)"
APPROX = "normal approximation"
NONE = "none (all differences zero)"
# Up to this many non-zero differences the p-value is exact (scipy's own limit for its exact
# test); beyond it the 2^n sign patterns are many and the normal approximation is close.
EXACT_MAX_PAIRS = 50


@dataclasses.dataclass(frozen=True)
class WilcoxonResult:
    statistic: float
    p_value: float
    n_pairs: int
    n_nonzero: int
    method: str  # EXACT | APPROX | NONE
    pairing: str
    min_attainable_p: float

    def describe(self) -> str:
        p = "n/a" if math.isnan(self.p_value) else f"{self.p_value:.4g}"
        return (
            f"Wilcoxon signed-rank, two-sided, {self.method}; pairs = {self.pairing} (n={self.n_pairs}, "
            f"{self.n_nonzero} non-zero differences); p = {p}; smallest attainable p = {self.min_attainable_p:.4g}"
        )


def min_exact_p(n_nonzero: int) -> float:
    """Smallest two-sided p of the sign-flip test over n non-zero differences, ties or not: only
    the two patterns with every sign alike are as extreme as themselves, so 2 / 2^n."""
    return 1.0 if n_nonzero == 0 else min(1.0, 2.0 / 2.0**n_nonzero)


def min_approx_p(nonzero: np.ndarray) -> float:
    """Smallest two-sided p of the normal approximation over these non-zero |differences|: every
    sign alike, with scipy's tie correction of the variance (ties shrink it, so the floor drops)."""
    n = nonzero.size
    _, t = np.unique(nonzero, return_counts=True)
    var = n * (n + 1) * (2 * n + 1) / 24 - float(np.sum(t**3 - t)) / 48
    return float(2 * sps.norm.sf(n * (n + 1) / 4 / math.sqrt(var)))


def sign_flip_p(nonzero_differences) -> tuple[float, float]:
    """Exact two-sided p of the signed-rank statistic under H0 (each difference's sign is + or -
    with probability 1/2, given the observed |differences|), and the statistic min(W+, W-).

    Tied |differences| get their mean rank, zeros must already be dropped. The 2^n sign patterns
    are counted, not listed: doubled mid-ranks are integers, so the null distribution of 2 W+ is a
    convolution of n two-point distributions {0, 2 r_i}. p = P(|W+ - S/2| >= |w+ - S/2|)."""
    d = np.asarray(nonzero_differences, np.float64).ravel()
    if d.size == 0 or not np.all(d != 0):
        raise ValueError(f"sign_flip_p needs non-zero differences, got {d.tolist()}")
    ranks2 = np.rint(2 * sps.rankdata(np.abs(d))).astype(np.int64)  # mid-ranks are multiples of 1/2
    total = int(ranks2.sum())
    counts = np.zeros(total + 1, dtype=np.float64)  # counts[k]: sign patterns with 2 W+ = k (exact below 2^53)
    counts[0] = 1.0
    for r in ranks2:
        counts[r:] = counts[r:] + counts[: total + 1 - r]
    observed = int(ranks2[d > 0].sum())
    k = np.arange(total + 1)
    extreme = np.abs(2 * k - total) >= abs(2 * observed - total)
    p = float(counts[extreme].sum() / 2.0**d.size)
    return min(1.0, p), min(observed, total - observed) / 2


def wilcoxon(a, b, *, pairing: str) -> WilcoxonResult:
    """Paired two-sided test of a against b. Zero differences are dropped (Wilcoxon's rule); up to
    `EXACT_MAX_PAIRS` non-zero ones the p-value is exact by sign-flip enumeration, ties included,
    else the normal approximation with tie correction; all-zero differences give p = 1."""
    a, b = np.asarray(a, np.float64).ravel(), np.asarray(b, np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"wilcoxon needs paired samples of equal length, got {a.size} and {b.size}")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError(f"wilcoxon ({pairing}) of non-finite values: {a.tolist()} against {b.tolist()}")
    d = a - b
    nonzero = d[d != 0]
    nz = nonzero.size
    if nz == 0:
        return WilcoxonResult(0.0, 1.0, d.size, 0, NONE, pairing, 1.0)
    if nz <= EXACT_MAX_PAIRS:
        p, statistic = sign_flip_p(nonzero)
        return WilcoxonResult(statistic, p, d.size, nz, EXACT, pairing, min_exact_p(nz))
    res = sps.wilcoxon(a, b, zero_method="wilcox", alternative="two-sided", method="approx")
    return WilcoxonResult(
        float(res.statistic), float(res.pvalue), d.size, nz, APPROX, pairing, min_approx_p(np.abs(nonzero))
    )
