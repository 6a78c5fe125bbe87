"""Rollouts into typed trajectories: determinism, validation, exact replay, rendering."""

import numpy as np
import pytest

from dc_lesson.viz import render
from dc_lesson.data import rollout
from dc_lesson import tasks
from dc_lesson.data import Trajectory, TrajectoryError


def test_collect_is_deterministic_and_prefix_stable():
    pol = lambda: rollout.RandomPolicy("reacher2", seed=3)  # noqa: E731
    a = rollout.collect("reacher2", pol(), 3, seed=11, max_steps=50, batch=2)
    b = rollout.collect("reacher2", pol(), 3, seed=11, max_steps=50, batch=2)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.observations, y.observations)
        np.testing.assert_array_equal(x.actions, y.actions)
    c = rollout.collect("reacher2", pol(), 3, seed=12, max_steps=50, batch=2)
    assert not np.array_equal(a[0].observations[0], c[0].observations[0])
    # The first episode's initial state depends only on the seed, not on how many episodes.
    d = rollout.collect("reacher2", pol(), 1, seed=11, max_steps=5)
    np.testing.assert_array_equal(a[0].observations[0], d[0].observations[0])


@pytest.mark.parametrize("name", ["reacher4", "hopper", "ant", "humanoid"])
def test_replaying_stored_actions_reproduces_the_episode_exactly(name):
    traj = rollout.collect(name, rollout.RandomPolicy(name, 0), 1, seed=4, max_steps=200)[0]
    obs, rews = rollout.replay(traj)
    np.testing.assert_array_equal(obs, traj.observations)
    np.testing.assert_array_equal(rews, traj.rewards)


def test_torch_modules_and_policies_with_reset_are_supported():
    import torch

    class Zero(torch.nn.Module):
        def forward(self, obs):
            return torch.zeros(obs.shape[0], 2)

    class Remembers:
        def __init__(self):
            self.seen = []

        def reset(self, seeds):
            self.seen.append(seeds.copy())

        def __call__(self, obs):
            return np.zeros((len(obs), 2))

    t = rollout.collect("reacher1", Zero(), 2, seed=0, max_steps=10)
    assert np.all(t[0].actions == 0)
    r = Remembers()
    rollout.collect("reacher1", r, 3, seed=0, max_steps=5, batch=2)
    np.testing.assert_array_equal(np.concatenate(r.seen), rollout.episode_seeds(0, 3))


def _good(**over):
    spec = tasks.spec("reacher1")
    T = 4
    kw = dict(task="reacher1", observations=np.zeros((T + 1, spec.obs_dim), np.float32),
              actions=np.zeros((T, spec.act_dim), np.float32), rewards=np.zeros(T),
              mode_features=np.zeros((T + 1, 2), np.float32), initial_state=np.zeros(7),
              seed=0)
    kw.update(over)
    return kw


def test_trajectories_are_validated_and_immutable():
    t = Trajectory(**_good())
    with pytest.raises(ValueError):
        t.actions[0, 0] = 1.0
    bad_obs = np.zeros((5, 8), np.float32)
    bad_obs[2, 3] = np.nan
    for over, msg in [({"observations": bad_obs}, "NaN"),
                      ({"actions": np.zeros((4, 3), np.float32)}, "shape"),
                      ({"actions": np.zeros((4, 2), np.float64)}, "dtype"),
                      ({"rewards": np.zeros(3)}, "shape"),
                      ({"task": "nope"}, "unknown task"),
                      ({"mode": 2}, "mode")]:
        with pytest.raises((TrajectoryError, KeyError), match=msg):
            Trajectory(**_good(**over))


def test_frames_and_videos_render_headless():
    img = render.frame("reacher4", height=60, width=80)
    assert img.shape == (60, 80, 3) and img.dtype == np.uint8
    assert img.std() > 5, "a blank frame"
    frames = render.episode_frames("cartpole", rollout.RandomPolicy("cartpole"), n_steps=6,
                                   every=3, height=40, width=50)
    assert len(frames) == 3
    html = render.video(frames)._repr_html_()
    assert html.startswith('<img src="data:image/gif;base64,')
