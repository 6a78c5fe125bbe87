"""A policy of another task is refused with a clear message before any episode runs
(issue 19: a torch shape error 11 frames deep)."""

import numpy as np
import pytest

from dc_lesson import evaluation
from dc_lesson.data import rollout
from dc_lesson.data.rollout import PolicyMismatchError
from dc_lesson.experts.trained import CoinFlipMixture, DeterministicPolicy
from dc_lesson.nn.policies import GaussianPolicy, StochasticPolicy
from dc_lesson.viz import render

CARTPOLE_POLICY = GaussianPolicy(5, 1)     # cartpole: obs 5, act 1
WRAPPED = [CARTPOLE_POLICY, StochasticPolicy(CARTPOLE_POLICY, seed=0),
           DeterministicPolicy(CARTPOLE_POLICY),
           CoinFlipMixture([DeterministicPolicy(CARTPOLE_POLICY)] * 2),
           rollout.RandomPolicy("cartpole")]


@pytest.mark.parametrize("policy", WRAPPED, ids=lambda p: type(p).__name__)
@pytest.mark.parametrize("run", [
    lambda p: rollout.collect("reacher4", p, 2),
    lambda p: evaluation.evaluate_policy("reacher4", p, n_episodes=2),
    lambda p: render.episode_frames("reacher4", p, n_steps=2),
], ids=["collect", "evaluate_policy", "episode_frames"])
def test_a_policy_of_another_task_is_refused(policy, run, monkeypatch):
    # Prove nothing is stepped: the environments would fail if they were built.
    monkeypatch.setattr(rollout._tasks, "load_vec", lambda *a: pytest.fail("stepped"))
    monkeypatch.setattr(render._tasks, "make", lambda *a: pytest.fail("stepped"))
    with pytest.raises(PolicyMismatchError) as e:
        run(policy)
    msg = str(e.value)
    assert "reacher4" in msg and ("size 5" in msg or "'cartpole'" in msg)


def test_the_right_policy_passes_and_a_bad_function_is_caught_at_its_first_step():
    assert len(rollout.collect("cartpole", CARTPOLE_POLICY, 1, max_steps=3)) == 1
    with pytest.raises(PolicyMismatchError, match=r"shape \(1, 3\).*needs \(1, 1\)"):
        rollout.collect("cartpole", lambda obs: np.zeros((len(obs), 3)), 1, max_steps=3)


@pytest.mark.parametrize("n", [0, -1, 2.5, True])
def test_episode_counts_must_be_whole_and_positive(n):
    with pytest.raises(ValueError, match="n_episodes must be a whole number"):
        rollout.collect("cartpole", CARTPOLE_POLICY, n)
