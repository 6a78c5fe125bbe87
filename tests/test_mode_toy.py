"""The mode toy: the three objectives do to the modes what chapter 04 says they do."""

import math
import warnings

import pytest

from dc_lesson.experiments import mode_toy as toy


@pytest.fixture(scope="module")
def results():
    return {(r.family, r.objective): r for r in toy.table(steps=1500)}


def test_forward_kl_covers_both_modes(results):
    g = results[("gaussian", "forward_kl")]
    assert abs(g.means[0]) < 0.3 and g.stds[0] > 1.5        # one wide Gaussian between them
    assert toy.covers_both(g, 0.15)
    m = results[("mixture", "forward_kl")]
    assert toy.covers_both(m, 0.4)                           # a component on each mode
    assert sorted(round(x) for x in m.means) == [-2, 2]
    assert min(m.weights) > 0.4


def test_reverse_kl_seeks_one_mode_with_a_width(results):
    g = results[("gaussian", "reverse_kl")]
    assert abs(abs(g.means[0]) - 2) < 0.2 and abs(g.stds[0] - toy.MODE_STD) < 0.15
    assert not toy.covers_both(g)


def test_reverse_kl_with_a_mixture_keeps_both_modes(results):
    # the entropy term pays for the second component (chapter 04 says so beside the table)
    m = results[("mixture", "reverse_kl")]
    assert toy.covers_both(m, 0.4) and min(m.weights) > 0.4


@pytest.mark.parametrize("family", toy.FAMILIES)
def test_the_cross_entropy_term_collapses_onto_one_point(results, family):
    r = results[(family, "cross_entropy")]
    assert not toy.covers_both(r, 0.05)                      # all of q on one mode ...
    heavy = max(range(len(r.weights)), key=lambda k: r.weights[k])
    assert r.stds[heavy] < 0.1                               # ... shrinking to a point
    assert max(r.mass_near) > 0.95


def test_the_target_density_is_normalised():
    import torch
    x = torch.linspace(-8, 8, 20001, dtype=torch.float64)
    assert float(toy.log_p(x).exp().sum() * (x[1] - x[0])) == pytest.approx(1, abs=1e-6)
    with pytest.raises(ValueError, match="objective one of"):
        toy.fit("gaussian", "wasserstein")
    late = toy.fit("gaussian", "forward_kl", steps=40).curve[-1]
    assert math.isfinite(late) and late < toy.fit("gaussian", "forward_kl", steps=1).curve[0]


@pytest.mark.parametrize("objective", toy.OBJECTIVES)
def test_a_fit_warns_nothing(objective):
    """Chapter 04 prints the toy in the Lab: a warning there is a pink box (issue 19; torch
    warned when the loss curve took float() of a tensor that requires grad)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        toy.fit("gaussian", objective, steps=21, n=64)
