"""The scripted experts: they solve their tasks, reach the target they chose, choose it as
documented (a fair coin, or the nearest target), and are deterministic given the seed."""

import numpy as np
import pytest

from dc_lesson.data import rollout
from dc_lesson import tasks
from dc_lesson.experts import scripted
from dc_lesson.tasks import reacher

TASKS = list(scripted.SCRIPTED_TASKS)
REACHERS = {"reacher1": 1, "reacher2": 2, "reacher4": 4}
N_EXPERT, N_RANDOM, SEED = 12, 8, 123
FLOOR = 900          # measured means over 50 episodes are above 975 for all four tasks
RANDOM_MARGIN = 400  # random actions score about 350 (cartpole) and 50-200 (reachers)


def reach_radius() -> float:
    """Distance from a target centre within which the reward is 1 (target + finger radius)."""
    env = tasks.make("reacher1")
    return reacher.TARGET_SIZE + float(env.physics.named.model.geom_size["finger", 0])


@pytest.fixture(scope="module")
def expert_runs():
    """The default experts (reachers: the nearest target) and the coin variants."""
    runs = {t: rollout.collect(t, scripted.expert_for(t), N_EXPERT, seed=SEED) for t in TASKS}
    for t in ("reacher2", "reacher4"):
        runs[f"{t}-coin"] = rollout.collect(t, scripted.expert_for(t, "coin"), N_EXPERT,
                                            seed=SEED)
    return runs


@pytest.mark.parametrize("task", TASKS)
def test_expert_beats_floor_and_random_policy(task, expert_runs):
    expert = rollout.returns(expert_runs[task])
    random = rollout.returns(
        rollout.collect(task, rollout.RandomPolicy(task, seed=0), N_RANDOM, seed=SEED))
    assert expert.mean() >= FLOOR, (task, expert)
    assert expert.mean() >= random.mean() + RANDOM_MARGIN, (task, expert.mean(), random.mean())
    assert all(np.all(np.abs(t.actions) <= 1) for t in expert_runs[task])


@pytest.mark.parametrize("task", ["reacher1", "reacher2-coin", "reacher4-coin"])
def test_reacher_episodes_end_inside_the_coin_flip_target(task, expert_runs):
    k = REACHERS[task.split("-")[0]]
    targets = reacher.target_positions(k)
    for traj in expert_runs[task]:
        chosen = scripted.coin_flip_targets([traj.seed], k)[0] if k > 1 else 0
        assert np.linalg.norm(traj.mode_features[-1] - targets[chosen]) < reach_radius()
        assert traj.mode == chosen            # the second half of the episode is spent there
        assert np.all(np.abs(traj.observations[-1, 6:]) < 1e-3)   # and it holds still


def test_chosen_attribute_matches_the_coin_of_the_last_batch():
    expert = scripted.ReacherExpert(4)
    trajs = rollout.collect("reacher4", expert, 3, seed=5, max_steps=100)
    np.testing.assert_array_equal(expert.chosen, [t.mode for t in trajs])
    np.testing.assert_array_equal(
        expert.chosen, scripted.coin_flip_targets(rollout.episode_seeds(5, 3), 4))


@pytest.mark.parametrize("k", [2, 4])
def test_coin_flip_shares_are_uniform(k):
    n = 400
    expert = scripted.ReacherExpert(k)
    expert.reset(rollout.episode_seeds(0, n))
    counts = np.bincount(expert.chosen, minlength=k)
    # Each count is Binomial(n, 1/k); 4 standard deviations make a false alarm ~1e-4 per count.
    p = 1 / k
    assert np.all(np.abs(counts - n * p) <= 4 * np.sqrt(n * p * (1 - p))), counts
    assert counts.min() > 0


def test_coin_flip_ignores_the_state_and_needs_reset():
    expert = scripted.ReacherExpert(4)
    seeds = rollout.episode_seeds(1, 16)
    expert.reset(seeds)
    first = expert.chosen.copy()
    expert.reset(seeds)   # same seeds: same choice, whatever the observations will be
    np.testing.assert_array_equal(expert.chosen, first)
    with pytest.raises(RuntimeError, match="reset"):
        scripted.ReacherExpert(2)(np.zeros((1, 8), np.float32))


def test_nearest_mode_goes_to_the_target_nearest_the_start():
    k = 4
    expert = scripted.ReacherExpert(k, mode_choice="nearest")
    trajs = rollout.collect("reacher4", expert, 8, seed=11, max_steps=100)
    targets = reacher.target_positions(k)
    start = np.stack([t.mode_features[0] for t in trajs]).astype(np.float64)
    nearest = np.argmin(np.linalg.norm(start[:, None] - targets[None], axis=-1), axis=1)
    np.testing.assert_array_equal(expert.chosen, nearest)
    for traj, c in zip(trajs, nearest):
        assert np.linalg.norm(traj.mode_features[-1] - targets[c]) < reach_radius()


@pytest.mark.parametrize("task", ["cartpole", "reacher4"])
def test_same_seed_gives_identical_trajectories(task):
    reused = scripted.expert_for(task)
    runs = [rollout.collect(task, policy, 3, seed=7, max_steps=150)
            for policy in (scripted.expert_for(task), scripted.expert_for(task), reused, reused)]
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            np.testing.assert_array_equal(a.observations, b.observations)
            np.testing.assert_array_equal(a.actions, b.actions)


def test_ik_solutions_put_the_fingertip_on_the_target():
    env = tasks.make("reacher2")
    upper, fore, wrist_limit = scripted.arm_geometry(env.physics)
    assert upper == pytest.approx(0.12) and fore == pytest.approx(0.12)
    for xy in reacher.target_positions(4):
        for q in scripted.two_link_ik(xy, upper, fore):
            env.physics.data.qpos[:] = q
            env.physics.forward()
            np.testing.assert_allclose(env.physics.fingertip(), xy, atol=1e-9)
            assert abs(q[1]) <= wrist_limit


@pytest.mark.parametrize("task", ["nope", "hopper"])
def test_expert_for_other_tasks_raises(task):
    with pytest.raises(ValueError, match="no scripted expert"):
        scripted.expert_for(task)
