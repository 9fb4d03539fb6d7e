"""Honest statistics for the tables: mean +- SD over seeds and paired Wilcoxon signed-rank tests.

Every test result says what was paired (the pairing unit), which variant ran (exact or normal
approximation, always two-sided) and the smallest p-value the pairing could ever give, so
nobody reads p = 0.0625 over five seeds as "not significant" without knowing it is the floor.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats as sps


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


@dataclasses.dataclass(frozen=True)
class WilcoxonResult:
    statistic: float
    p_value: float
    n_pairs: int
    n_nonzero: int
    method: str  # "exact" | "approx" | "none (all differences zero)"
    pairing: str
    min_attainable_p: float

    def describe(self) -> str:
        p = "n/a" if math.isnan(self.p_value) else f"{self.p_value:.4g}"
        return (
            f"Wilcoxon signed-rank, two-sided, {self.method}; pairs = {self.pairing} (n={self.n_pairs}, "
            f"{self.n_nonzero} non-zero differences); p = {p}; smallest attainable p = {self.min_attainable_p:.4g}"
        )


def min_exact_p(n_nonzero: int) -> float:
    """Smallest two-sided exact p-value over n non-zero, untied differences: 2 / 2^n."""
    return 1.0 if n_nonzero == 0 else min(1.0, 2.0 / 2.0**n_nonzero)


def min_approx_p(nonzero: np.ndarray) -> float:
    """Smallest two-sided p of the normal approximation over these non-zero |differences|: every
    sign alike, with scipy's tie correction of the variance (ties shrink it, so the floor drops)."""
    n = nonzero.size
    _, t = np.unique(nonzero, return_counts=True)
    var = n * (n + 1) * (2 * n + 1) / 24 - float(np.sum(t**3 - t)) / 48
    return float(2 * sps.norm.sf(n * (n + 1) / 4 / math.sqrt(var)))


def wilcoxon(a, b, *, pairing: str) -> WilcoxonResult:
    """Paired two-sided test of a against b. Exact when n <= 50 without ties or zeros
    (scipy's own rule), else the normal approximation; all-zero differences give p = 1."""
    a, b = np.asarray(a, np.float64).ravel(), np.asarray(b, np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"wilcoxon needs paired samples of equal length, got {a.size} and {b.size}")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError(f"wilcoxon ({pairing}) of non-finite values: {a.tolist()} against {b.tolist()}")
    d = a - b
    nz = int(np.count_nonzero(d))
    if nz == 0:
        return WilcoxonResult(0.0, 1.0, d.size, 0, "none (all differences zero)", pairing, 1.0)
    nonzero = np.abs(d[d != 0])
    ties = np.unique(nonzero).size < nonzero.size
    exact = nz <= 50 and not ties and nz == d.size
    method = "exact" if exact else "approx"
    res = sps.wilcoxon(a, b, zero_method="wilcox", alternative="two-sided", method=method)
    floor = min_exact_p(nz) if exact else min_approx_p(nonzero)
    return WilcoxonResult(float(res.statistic), float(res.pvalue), d.size, nz, method, pairing, floor)
