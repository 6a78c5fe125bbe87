"""The Gymnasium face of the task ports: ``gymnasium.make("dc_lesson/NAME-v0")``.

:class:`GymEnv` wraps the fast :class:`~dc_lesson.tasks.base.TaskEnv` (the same physics and
the same numbers):

* ``observation_space``: ``Box(-inf, inf, (obs_dim,), float32)``; ``action_space``: the
  actuators' bounds, ``Box(low, high, (act_dim,), float32)``; actions outside are clipped;
* ``reset(seed=s)`` starts the episode the fast engine starts with ``reset(seed=s)`` (and
  dm_env after seeding the task's RandomState with s); ``reset()`` without a seed continues
  the task's random stream;
* every episode lasts exactly ``spec.horizon`` steps and none terminates, so ``step`` returns
  ``terminated=False`` always and ``truncated=True`` at the horizon: the last state is not
  terminal, and a value function should bootstrap from it;
* ``info["mode_feature"]`` is the task's mode feature after the step (fingertip x-y, forward
  speed, ...), and ``info["t"]`` the step count.
"""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium import spaces

from dc_lesson import tasks as _tasks


class GymEnv(gymnasium.Env):
    """Task port ``task`` as a Gymnasium environment (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(self, task: str, render_mode: str | None = None):
        self._env = _tasks.make(task)
        spec = self._env.spec
        self.task_spec = spec
        self.observation_space = spaces.Box(-np.inf, np.inf, (spec.obs_dim,), np.float32)
        self.action_space = spaces.Box(self._env.action_low.astype(np.float32),
                                       self._env.action_high.astype(np.float32),
                                       (spec.act_dim,), np.float32)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1 / spec.control_timestep)}

    def _info(self) -> dict:
        return {"mode_feature": self._env.mode_feature(), "t": self._env.t}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        obs = self._env.reset(seed=seed)
        return obs, self._info()

    def step(self, action):
        obs, reward, done = self._env.step(np.asarray(action, dtype=np.float64))
        return obs, reward, False, done, self._info()

    def render(self):
        return self._env.render()

    @property
    def physics(self):
        return self._env.physics


__all__ = ["GymEnv"]
