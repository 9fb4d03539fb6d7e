import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats as sps

from fabricjax.reporting import stats


def test_mean_sd_one_seed_and_many():
    assert stats.mean_sd([0.9]) == (0.9, 0.0)
    m, s = stats.mean_sd([0.9, 0.95, 1.0])
    assert m == pytest.approx(0.95) and s == pytest.approx(np.std([0.9, 0.95, 1.0], ddof=1))
    assert stats.format_mean_sd([0.9, 1.0]) == "95.00 ± 7.07"
    with pytest.raises(ValueError):
        stats.mean_sd([])


def test_exact_small_example_matches_scipy():
    a = [0.95, 0.97, 0.96, 0.99, 0.98]
    b = [0.93, 0.94, 0.955, 0.95, 0.97]
    r = stats.wilcoxon(a, b, pairing="per seed")
    ref = sps.wilcoxon(a, b, method="exact")
    assert r.method == stats.EXACT and r.p_value == pytest.approx(ref.pvalue) and r.statistic == ref.statistic
    # all five differences positive: the floor of an exact test over 5 pairs
    assert r.p_value == pytest.approx(0.0625) == r.min_attainable_p
    assert "per seed" in r.describe() and "0.0625" in r.describe()


def test_ten_pairs_floor():
    r = stats.wilcoxon(np.arange(10) + 1.0, np.zeros(10), pairing="per seed")
    assert r.p_value == pytest.approx(2 / 2**10) == r.min_attainable_p


def test_all_zero_differences_do_not_crash():
    r = stats.wilcoxon([0.9] * 5, [0.9] * 5, pairing="per seed")
    assert r.p_value == 1.0 and r.n_nonzero == 0


def brute_force_p(a, b):
    """Two-sided signed-rank p by listing every sign pattern of the non-zero differences (zeros
    dropped, tied |differences| at their mean rank), written apart from fabricjax.reporting.stats."""
    d = np.asarray(a, float) - np.asarray(b, float)
    d = d[d != 0]
    ranks = sps.rankdata(np.abs(d))
    centre = ranks.sum() / 2
    observed = abs(ranks[d > 0].sum() - centre)
    patterns = list(itertools.product((0, 1), repeat=d.size))
    extreme = sum(abs(ranks[np.array(s, bool)].sum() - centre) >= observed - 1e-9 for s in patterns)
    return extreme / len(patterns)


TIED = [  # (a, b): tied |differences|, zero differences, both, every |difference| alike
    ([0.5, 0.6, 0.7, 0.9, 0.8], [0.4, 0.5, 0.75, 0.7, 0.85]),
    ([0.5, 0.6, 0.7, 0.9, 0.8, 0.3], [0.5, 0.6, 0.6, 0.7, 0.8, 0.1]),
    ([3, 1, 4, 1, 5, 9, 2, 6, 5, 3], [2, 7, 1, 8, 2, 8, 1, 8, 2, 8]),
    ([0.5] * 5, [0.4] * 5),
    ([1, 2, 3, 4, 5, 6, 7], [0, 1, 2, 5, 6, 6, 6]),
]


@pytest.mark.parametrize("a, b", TIED)
def test_exact_with_ties_and_zeros_matches_brute_force(a, b):
    r = stats.wilcoxon(a, b, pairing="x")
    assert r.method == stats.EXACT and r.p_value == pytest.approx(brute_force_p(a, b), rel=1e-12)
    assert r.min_attainable_p == pytest.approx(2 / 2**r.n_nonzero) and r.min_attainable_p <= r.p_value


def test_the_issue_case_two_tied_differences_over_five_seeds():
    """Two |differences| tie: scipy would switch to the normal approximation and its floor (0.042)
    would undercut the exact floor of five pairs; the sign-flip test keeps 0.0625 and says so."""
    a, b = [0.62, 0.60, 0.58, 0.66, 0.61], [0.60, 0.62, 0.55, 0.62, 0.60]
    r = stats.wilcoxon(a, b, pairing="per seed")
    assert r.method == "exact (sign-flip enumeration)" and r.min_attainable_p == pytest.approx(0.0625)
    assert r.p_value == pytest.approx(brute_force_p(a, b)) and "exact (sign-flip enumeration)" in r.describe()
    all_alike = stats.wilcoxon([0.5] * 5, [0.4] * 5, pairing="per seed")
    assert all_alike.p_value == pytest.approx(0.0625) == all_alike.min_attainable_p


@settings(max_examples=30, deadline=None)
@given(st.lists(st.integers(-20, 20), min_size=1, max_size=12, unique_by=abs), st.booleans())
def test_exact_matches_scipy_without_ties(diffs, zero_pad):
    """Tie-free, zero-free differences: scipy's exact test is the reference."""
    d = np.asarray([x for x in diffs if x != 0], float)
    if d.size == 0:
        return
    r = stats.wilcoxon(d, np.zeros_like(d), pairing="x")
    ref = sps.wilcoxon(d, method="exact")
    assert r.method == stats.EXACT and r.p_value == pytest.approx(ref.pvalue) and r.statistic == ref.statistic


def test_many_tied_pairs_use_the_normal_approximation_like_scipy():
    rng = np.random.default_rng(0)
    a = (rng.random(200) < 0.7).astype(float)  # per-sample correctness of model A
    b = (rng.random(200) < 0.5).astype(float)
    r = stats.wilcoxon(a, b, pairing="per test sample")
    assert r.n_nonzero > stats.EXACT_MAX_PAIRS
    ref = sps.wilcoxon(a, b, zero_method="wilcox", method="approx")
    assert r.method == stats.APPROX and r.p_value == pytest.approx(ref.pvalue)
    assert 0 < r.min_attainable_p < r.p_value


def test_unequal_lengths():
    with pytest.raises(ValueError, match="paired"):
        stats.wilcoxon([1, 2], [1], pairing="x")


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1, 1, allow_nan=False), min_size=1, max_size=30), st.integers(0, 10**6))
def test_p_value_always_valid(diffs, seed):
    b = np.random.default_rng(seed).uniform(size=len(diffs))
    r = stats.wilcoxon(b + np.asarray(diffs), b, pairing="x")
    assert 0.0 <= r.p_value <= 1.0 and np.isfinite(r.statistic)
    assert r.min_attainable_p <= r.p_value * (1 + 1e-9)


def test_percentiles_ms_of_timings_in_seconds():
    p = stats.percentiles_ms([0.001 * k for k in range(1, 101)])
    assert p == {"p50_ms": pytest.approx(50.5), "p99_ms": pytest.approx(99.01)}
