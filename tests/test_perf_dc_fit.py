"""``dc-lesson perf dc-fit``: whole DC runs with today's density fit and the cheaper one,
paired by seed; the variant really changes the training solver (and only it), and the rule
that turns the paired difference into words."""

import dataclasses

import pytest

from dc_lesson import budget
from dc_lesson.algorithms import dc
from dc_lesson.density import softflow
from dc_lesson.perf import dc_fit


def test_each_variant_fits_with_its_own_solver_step_and_the_reward_keeps_todays(monkeypatch):
    seen = []
    real = softflow.fit

    def spy(states, config, **kw):
        seen.append((config.step_size, config.eval_step_size))
        return real(states, config, **kw)

    monkeypatch.setattr(softflow, "fit", spy)
    result = dc_fit.run("reacher1", seeds=[0, 1], b=budget.get("smoke"), n_episodes=2,
                        log=lambda s: None)
    # seed 0 runs today's first, seed 1 the cheaper first: the order alternates
    assert seen == [(0.25, 0.25), (0.5, 0.25), (0.5, 0.25), (0.25, 0.25)]
    assert [set(r) for r in result["rows"]] == [{"seed", "today", "cheaper"}] * 2
    assert result["summary"]["time_ratio"] > 0
    seen.clear()
    dc_fit.run("reacher1", seeds=[0], b=budget.get("smoke"), n_episodes=2, log=lambda s: None,
               variant="fit+reward")
    assert seen == [(0.25, 0.25), (0.5, 0.5)]     # the reward's step changes too


@pytest.mark.parametrize("variant", list(dc_fit.VARIANTS))
def test_each_variant_is_the_stored_numerics_but_for_its_own_change(variant):
    b = budget.get("lesson")
    arms = dc_fit.arms(b, 3, variant)
    today, cheaper = arms["today"], arms["cheaper"]
    assert today == dc.preset(b, 3).with_flow(**dc.STORED_NUMERICS)
    flow = today.flow
    assert (flow.step_size, flow.eval_step_size, flow.eval_quadrature, flow.tanh) == (
        0.25, 0.25, 4, "torch")
    assert cheaper.with_flow(**dc.STORED_NUMERICS) == today
    if variant == "defaults":           # DC as it is: its own numerics, NumPy's tanh
        assert cheaper == dc.preset(b, 3) and cheaper.flow.tanh == "numpy"
    else:                               # the stored numerics with one change, torch's tanh
        want = dict(dc.STORED_NUMERICS, **dc_fit.VARIANTS[variant])
        flow = cheaper.flow
        assert (flow.step_size, flow.eval_step_size, flow.tanh) == (
            want["step_size"], want["eval_step_size"], "torch")


def test_the_stored_arm_fits_with_torchs_tanh_and_the_defaults_with_numpys(monkeypatch):
    seen = []
    real = softflow.fit

    def spy(states, config, **kw):
        seen.append((config.step_size, config.eval_quadrature, config.tanh))
        flow, log = real(states, config, **kw)
        assert flow.net.tanh_kernel == config.tanh
        return flow, log

    monkeypatch.setattr(softflow, "fit", spy)
    dc_fit.run("reacher1", seeds=[1], b=budget.get("smoke"), n_episodes=2, log=lambda s: None,
               variant="defaults")
    assert seen == [(0.5, 3, "numpy"), (0.25, 4, "torch")]     # seed 1: the defaults first


def test_an_unknown_variant_is_refused_with_the_choices():
    with pytest.raises(ValueError, match="fit, fit\\+reward, defaults; not 'reward'"):
        dc_fit.main(["reacher1"], seeds=[0], variant="reward")


def _rows(today, cheaper):
    return [{"seed": i, "today": {"seconds": 2.0, "scaled_return": a},
             "cheaper": {"seconds": 1.0, "scaled_return": b}}
            for i, (a, b) in enumerate(zip(today, cheaper))]


@pytest.mark.parametrize("shift, kept", [(0.001, True), (0.3, False)])
def test_learning_is_kept_only_within_the_seed_spread(shift, kept):
    today = [0.5, 0.6, 0.7, 0.55, 0.65]                 # spread (SD) about 0.08
    s = dc_fit.summarise(_rows(today, [t + shift + 0.001 * i for i, t in enumerate(today)]))
    assert s["time_ratio"] == 2.0 and s["seed_spread"] == pytest.approx(0.079, abs=1e-3)
    assert s["answer"].startswith("learning kept") is kept
