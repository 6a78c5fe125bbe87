"""The intervals of evaluation.stats: they cover the truth at about the nominal rate, pairing
helps where runs are correlated, and the IQM's stratified bootstrap keeps every task."""

import numpy as np
import pytest
from scipy import stats as sps

from dc_lesson.evaluation import stats


def test_the_95_interval_covers_the_true_mean_at_about_the_nominal_rate():
    rng = np.random.default_rng(1)
    hits = 0
    for r in range(200):
        x = rng.normal(1.0, 1.0, 20)
        ci = stats.mean_ci(x, n_resamples=2000, seed=r)
        hits += ci.lo <= 1.0 <= ci.hi
    assert 0.88 <= hits / 200 <= 0.99


def test_an_interval_that_is_too_narrow_would_fail_the_coverage_check():
    """The check above can fail: a 50% interval covers far less often."""
    rng = np.random.default_rng(1)
    hits = sum(stats.mean_ci(x, level=0.5, n_resamples=2000, seed=r).lo <= 1.0
               <= stats.mean_ci(x, level=0.5, n_resamples=2000, seed=r).hi
               for r, x in enumerate(rng.normal(1.0, 1.0, (100, 20))))
    assert hits / 100 < 0.7


def test_paired_beats_unpaired_on_correlated_runs():
    """Seeds move both learners alike (shared warm start); the paired interval sees a true
    gain of 0.1 that the unpaired one cannot tell from zero."""
    rng = np.random.default_rng(0)
    seed_effect = rng.normal(0, 1.0, 10)
    a = seed_effect + 0.1 + rng.normal(0, 0.02, 10)
    b = seed_effect + rng.normal(0, 0.02, 10)
    p, u = stats.paired_diff(a, b), stats.unpaired_diff(a, b)
    assert p.excludes_zero() == 1 and u.excludes_zero() == 0
    assert (p.hi - p.lo) < 0.1 * (u.hi - u.lo)
    assert p.mean == pytest.approx(u.mean)


def test_one_value_has_no_interval_and_equal_values_a_point():
    one = stats.mean_ci([0.3])
    assert np.isnan(one.lo) and one.excludes_zero() == 0
    same = stats.mean_ci([0.2, 0.2, 0.2])
    assert same.lo == same.hi == pytest.approx(0.2)
    with pytest.raises(ValueError, match="non-finite"):
        stats.mean_ci([1.0, np.nan])
    with pytest.raises(ValueError, match="one of each per seed"):
        stats.paired_diff([1, 2], [1, 2, 3])


def test_the_same_values_give_the_same_interval():
    x = [0.1, 0.5, 0.3, 0.9, 0.2]
    assert stats.mean_ci(x) == stats.mean_ci(x)
    assert stats.mean_ci(x, seed=1) != stats.mean_ci(x, seed=2)


def test_iqm_trims_a_quarter_each_side_and_its_bootstrap_is_stratified():
    x = np.array([[0.0, 10.0], [1.0, 11.0], [2.0, 12.0], [3.0, 13.0]])
    assert stats.iqm(x) == pytest.approx(sps.trim_mean(x.ravel(), 0.25))
    ci = stats.iqm_ci(x, seed=0)
    assert ci.lo <= ci.mean <= ci.hi
    # Stratified: every replicate keeps 4 scores of each task, so no replicate's IQM can fall
    # below that of the lowest possible draw (all seeds at each task's minimum).
    assert ci.lo >= stats.iqm([[0.0, 10.0]] * 4) - 1e-12
    # One outlying run moves the mean by its size, the IQM by one rank.
    y = x.copy()
    y[3, 1] = 1e6
    assert stats.iqm(y) == pytest.approx(stats.iqm(x)) and y.mean() - x.mean() > 1e5


def test_tv_and_its_multinomial_floor():
    assert stats.tv({"a": 0.5, "b": 0.5}, {"a": 1.0, "b": 0.0}) == pytest.approx(0.5)
    floor = stats.multinomial_tv_floor({"a": 0.5, "b": 0.5}, 50)
    # For two modes TV = |k/n - 1/2|: its mean is E|Bin(50, .5) - 25| / 50.
    k = np.arange(51)
    exact = float((sps.binom.pmf(k, 50, 0.5) * np.abs(k / 50 - 0.5)).sum())
    assert floor["mean"] == pytest.approx(exact, abs=0.003)
    assert stats.multinomial_tv_floor({"a": 0.5, "b": 0.5}, 500)["mean"] < floor["mean"] / 2
