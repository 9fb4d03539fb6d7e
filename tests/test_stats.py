import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats as sps

from fabricjax import stats


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
    assert r.method == "exact" and r.p_value == pytest.approx(ref.pvalue) and r.statistic == ref.statistic
    # all five differences positive: the floor of an exact test over 5 pairs
    assert r.p_value == pytest.approx(0.0625) == r.min_attainable_p
    assert "per seed" in r.describe() and "0.0625" in r.describe()


def test_ten_pairs_floor():
    r = stats.wilcoxon(np.arange(10) + 1.0, np.zeros(10), pairing="per seed")
    assert r.p_value == pytest.approx(2 / 2**10) == r.min_attainable_p


def test_all_zero_differences_do_not_crash():
    r = stats.wilcoxon([0.9] * 5, [0.9] * 5, pairing="per seed")
    assert r.p_value == 1.0 and r.n_nonzero == 0


def test_ties_and_zeros_use_normal_approximation_like_scipy():
    a = np.array([1, 1, 0, 1, 0, 1, 1, 1, 0, 1], float)  # per-sample correctness of model A
    b = np.array([1, 0, 0, 0, 0, 1, 0, 1, 1, 0], float)
    r = stats.wilcoxon(a, b, pairing="per test sample")
    ref = sps.wilcoxon(a, b, zero_method="wilcox", method="approx")
    assert r.method == "approx" and r.p_value == pytest.approx(ref.pvalue)
    assert 0 < r.min_attainable_p < 1


def test_unequal_lengths():
    with pytest.raises(ValueError, match="paired"):
        stats.wilcoxon([1, 2], [1], pairing="x")


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1, 1, allow_nan=False), min_size=1, max_size=30), st.integers(0, 10**6))
def test_p_value_always_valid(diffs, seed):
    b = np.random.default_rng(seed).uniform(size=len(diffs))
    r = stats.wilcoxon(b + np.asarray(diffs), b, pairing="x")
    assert 0.0 <= r.p_value <= 1.0 and np.isfinite(r.statistic)
    assert r.min_attainable_p <= r.p_value + 1e-12 or r.method != "exact"
