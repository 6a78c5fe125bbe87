"""Which mode an episode took: realizable experts, arrival labels, mode shares."""

import numpy as np
import pytest

from dc_lesson import tasks
from dc_lesson.data import modes, rollout
from dc_lesson.experts import EXPECTED_SHARES, load_expert


def _first_choices(task: str, seeds) -> np.ndarray:
    """The expert's mode per episode, read from its choice after the first step."""
    expert, _ = load_expert(task)
    env = tasks.load_vec(task, len(seeds))
    obs, _ = env.reset(seeds)
    if hasattr(expert, "reset"):
        expert.reset(seeds)
    expert(obs)
    return np.asarray(expert.chosen)


@pytest.mark.parametrize("task", ["reacher2", "reacher4", "halfcheetah2"])
def test_realizable_experts_choose_from_the_start_state_in_the_documented_shares(task):
    seeds = rollout.episode_seeds(7, 200)
    chosen = _first_choices(task, seeds)
    # the same start gives the same mode: the choice is a function of the first observation
    again = _first_choices(task, seeds[::-1])[::-1]
    np.testing.assert_array_equal(chosen, again)
    # ... and of nothing else: a copy of a start state under another seed takes the same mode
    expert, _ = load_expert(task)
    if hasattr(expert, "reset"):
        expert.reset([123456789] * 4)
    env = tasks.load_vec(task, 4)
    obs, _ = env.reset(seeds[:4])
    expert(obs)
    np.testing.assert_array_equal(expert.chosen, chosen[:4])
    shares = np.bincount(chosen, minlength=len(EXPECTED_SHARES[task])) / len(seeds)
    # 200 Bernoulli draws per share: sd <= 0.035; 0.11 is more than 3 sd
    np.testing.assert_allclose(shares, EXPECTED_SHARES[task], atol=0.11)


def test_coin_variants_ignore_the_start_state():
    """The coin expert picks different modes for the same start (seeded by the episode)."""
    expert, info = load_expert("reacher4", "coin")
    assert info["variant"] == "coin"
    env = tasks.load_vec("reacher4", 2)
    seeds = rollout.episode_seeds(3, 64)
    picks = []
    for s in seeds:
        obs, _ = env.reset([s, s])
        expert.reset([s, s + 1])              # same start state, two coins
        expert(obs)
        picks.append(tuple(expert.chosen))
    assert any(a != b for a, b in picks)
    with pytest.raises(ValueError, match="no expert variant"):
        load_expert("cartpole", "coin")


def test_an_episode_that_never_arrives_has_mode_none():
    for task in ("reacher4", "halfcheetah2"):
        trajs = rollout.collect(task, rollout.RandomPolicy(task, 0), 4, seed=1)
        assert [t.mode for t in trajs] == [tasks.NO_MODE] * 4
        shares = modes.mode_shares(task, trajs)
        assert shares["none"] == 1.0 and list(shares)[-1] == "none"


def test_arriving_and_leaving_is_no_mode_and_staying_is():
    task = tasks.make("reacher2").task
    targets = task.targets
    stay = np.repeat(targets[1:2], 1001, axis=0)
    assert task.episode_mode(stay) == 1
    leave = stay.copy()
    leave[-200:] = 0.0                       # left for the centre in the last fifth
    assert task.episode_mode(leave) == tasks.NO_MODE
    near = stay + [0.06, 0.0]                # hovering outside the reward radius
    assert task.episode_mode(near) == tasks.NO_MODE
    cheetah = tasks.make("halfcheetah2").task
    assert cheetah.episode_mode(np.full((1001, 1), 3.0)) == 0
    assert cheetah.episode_mode(np.full((1001, 1), -3.0)) == 1
    assert cheetah.episode_mode(np.full((1001, 1), 0.3)) == tasks.NO_MODE
    single = tasks.make("reacher1").task
    assert single.episode_mode(np.zeros((1001, 2))) == 0     # one mode: always taken


def test_total_variation_of_mode_shares():
    p = {"red": 0.5, "blue": 0.5, "none": 0.0}
    assert modes.total_variation(p, p) == 0
    assert modes.total_variation(p, {"red": 1.0, "blue": 0.0, "none": 0.0}) == 0.5
    assert modes.total_variation({"red": 1.0}, {"blue": 1.0}) == 1.0


def test_both_evaluations_side_by_side():
    """Mean-action and sampled evaluation of one policy: the same start states, different
    actions; sampled episodes repeat for the same seed; mode TV is measured against the
    reference's shares."""
    import torch

    from dc_lesson import data, evaluation
    from dc_lesson.nn.policies import GaussianPolicy
    spec = tasks.spec("reacher2")
    torch.manual_seed(0)
    pi = GaussianPolicy(spec.obs_dim, spec.act_dim, log_std_init=0.0)
    ref = data.load_demos("reacher2", n_trajectories=6)
    both = evaluation.evaluate_both("reacher2", pi, ref, n_episodes=3)
    again = evaluation.evaluate_policy("reacher2", pi, ref, n_episodes=3, actions="sampled")
    assert both["sampled"]["returns"] == again["returns"]
    assert both["mean"]["returns"] != both["sampled"]["returns"]
    for ev in both.values():
        assert 0 <= ev["mode_tv"] <= 1
        assert ev["mode_tv"] == modes.total_variation(ev["mode_shares"],
                                                      modes.mode_shares("reacher2",
                                                                        ref.trajectories))
    with pytest.raises(ValueError, match="actions must be one of"):
        evaluation.evaluate_policy("reacher2", pi, ref, n_episodes=1, actions="greedy")


def test_an_evaluation_without_divergences_reads_no_reference(monkeypatch):
    """``divergences=False``: the same episodes and returns as a full evaluation, EMD / KL /
    RKL and mode TV None, and no demonstrations loaded (never a silent stand-in reference)."""
    import torch

    from dc_lesson import data, evaluation
    from dc_lesson.evaluation import evaluate as _evaluate
    from dc_lesson.nn.policies import GaussianPolicy
    spec = tasks.spec("reacher2")
    torch.manual_seed(0)
    pi = GaussianPolicy(spec.obs_dim, spec.act_dim)
    full = evaluation.evaluate_policy("reacher2", pi, data.load_demos("reacher2"), n_episodes=2)

    def refuse(*a, **k):
        raise AssertionError("a reference was loaded")
    monkeypatch.setattr(_evaluate._data, "load_demos", refuse)
    bare = evaluation.evaluate_policy("reacher2", pi, n_episodes=2, divergences=False)
    assert bare["returns"] == full["returns"] and bare["scaled_return"] == full["scaled_return"]
    assert bare["emd"] is None and bare["kl"] is None and bare["rkl"] is None
    assert bare["mode_tv"] is None and bare["mode_shares"] == full["mode_shares"]
