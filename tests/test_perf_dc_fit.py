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


def test_the_variant_is_todays_config_but_for_the_fit():
    today = dc.preset(budget.get("lesson"), 3)
    cheaper = dc_fit.CheaperFit(**{f.name: getattr(today, f.name)
                                   for f in dataclasses.fields(today)})
    assert cheaper.to_json() == today.to_json()       # the same run in every other respect
    assert dataclasses.replace(cheaper.flow_config(), step_size=0.25) == today.flow_config()


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
