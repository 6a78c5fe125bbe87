"""What every task port shares: its spec, and the flat-vector environment the library steps.

A port is written the dm_control way (an XML model, a ``Physics`` subclass with named helpers,
a ``Task`` whose randomness comes only from ``self.random``).  :class:`TaskEnv` wraps the pair
with the conventions the rest of ``dc_lesson`` relies on:

* observations are flat ``float32`` vectors (the task's observation dict, concatenated in order);
* every episode lasts exactly ``spec.horizon`` control steps (no early termination), so returns
  are on dm_control's 0..1000 scale;
* actions are checked (shape, finiteness) and clipped to the action bounds, exactly what MuJoCo's
  ``ctrllimited`` clamping would do, so the recorded action is the applied one;
* ``reset(seed=...)`` re-seeds the task's ``RandomState``, so one integer decides an episode.

``TaskEnv.step`` performs the same calls as ``dm_control.rl.control.Environment.step``
(``before_step``, ``physics.step(n_sub_steps)``, ``after_step``, reward, observation) without
building a ``TimeStep`` and an observation dict per step; ``TaskEnv.dm_env`` is the genuine
dm_control environment on the same physics for readers who want the dm_env API, and a test
checks that the two give identical trajectories.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np
from dm_control.rl import control
from dm_control.suite import base as suite_base


@dataclasses.dataclass(frozen=True)
class TaskSpec:
    """Static facts about a task port; ``tasks.SPECS`` holds one per task and a test checks
    each against the live environment."""

    name: str
    paper_task: str          # the Gym task of the paper this port stands for
    base: str                # which dm_control model and objective it builds on
    obs_dim: int
    act_dim: int
    horizon: int             # control steps per episode (fixed)
    control_timestep: float  # seconds per control step
    n_sub_steps: int         # physics steps per control step
    mode_feature_names: tuple[str, ...]
    modes: tuple[str, ...] = ()   # names of the behaviour modes of a multi-mode task
    differs: str = ""        # what differs from the paper's Gym task

    @property
    def mode_dim(self) -> int:
        return len(self.mode_feature_names)

    @property
    def multimodal(self) -> bool:
        return len(self.modes) > 1


class PortTask(suite_base.Task):
    """Mixin for the Task classes of the ports: the low-dimensional mode feature.

    ``mode_feature`` is what coverage plots, EMD and KL are computed on (fingertip x-y for the
    reachers, forward velocity for the cheetahs, ...).  ``classify_mode`` maps mode features to
    the index of the behaviour mode (for multi-mode tasks), or zeros.
    """

    def mode_feature(self, physics) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def classify_mode(self, features: np.ndarray) -> np.ndarray:
        features = np.asarray(features)
        return np.zeros(features.shape[:-1], dtype=np.int64)


def flatten_observation(obs_dict) -> np.ndarray:
    """Concatenates an observation dict into one float32 vector, in the dict's order."""
    return np.concatenate([np.ravel(v) for v in obs_dict.values()]).astype(np.float32)


class ActionError(ValueError):
    """An action of the wrong shape or with non-finite entries."""


class TaskEnv:
    """One task port, stepped with flat float32 observations and a fixed horizon."""

    def __init__(self, spec: TaskSpec, physics, task: PortTask):
        self.spec = spec
        self.physics = physics
        self.task = task
        self.n_sub_steps = spec.n_sub_steps
        action_spec = task.action_spec(physics)
        self.action_low = np.asarray(action_spec.minimum, dtype=np.float64)
        self.action_high = np.asarray(action_spec.maximum, dtype=np.float64)
        self.t = 0
        self._needs_reset = True
        self._dm_env = None

    # -- dm_env view -------------------------------------------------------------------------
    @property
    def dm_env(self) -> control.Environment:
        """The genuine dm_control environment on this env's physics and task (shared state)."""
        if self._dm_env is None:
            self._dm_env = control.Environment(
                self.physics, self.task,
                time_limit=self.spec.horizon * self.spec.control_timestep,
                control_timestep=self.spec.control_timestep,
                flat_observation=True)
        return self._dm_env

    # -- stepping ----------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> np.ndarray:
        """Starts an episode; with ``seed`` the task's RandomState is re-seeded first."""
        if seed is not None:
            self.task.random.seed(int(seed) % (2**32))
        with self.physics.reset_context():
            self.task.initialize_episode(self.physics)
        self.t = 0
        self._needs_reset = False
        return self.observation()

    def observation(self) -> np.ndarray:
        return flatten_observation(self.task.get_observation(self.physics))

    def check_action(self, action) -> np.ndarray:
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (self.spec.act_dim,):
            raise ActionError(
                f"task {self.spec.name!r} takes actions of shape ({self.spec.act_dim},), "
                f"got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ActionError(f"task {self.spec.name!r} got a non-finite action: {a}")
        return np.clip(a, self.action_low, self.action_high)

    def step(self, action) -> tuple[np.ndarray, float, bool]:
        """Applies ``action`` for one control step: returns (observation, reward, done).

        ``done`` is True exactly at the horizon; stepping past it is an error.
        """
        if self._needs_reset:
            raise RuntimeError("call reset() before step(): the episode is over or not started")
        a = self.check_action(action)
        # The same sequence as dm_control.rl.control.Environment.step.
        self.task.before_step(a, self.physics)
        self.physics.step(self.n_sub_steps)
        self.task.after_step(self.physics)
        reward = float(self.task.get_reward(self.physics))
        obs = self.observation()
        self.t += 1
        done = self.t >= self.spec.horizon
        self._needs_reset = done
        return obs, reward, done

    def mode_feature(self) -> np.ndarray:
        return np.asarray(self.task.mode_feature(self.physics), dtype=np.float32)

    # -- state, for replaying demonstrations -------------------------------------------------
    def get_state(self) -> np.ndarray:
        """The full MuJoCo simulation state (``mjSTATE_INTEGRATION``), float64."""
        import mujoco
        sig = mujoco.mjtState.mjSTATE_INTEGRATION
        m, d = self.physics.model.ptr, self.physics.data.ptr
        state = np.empty(mujoco.mj_stateSize(m, sig))
        mujoco.mj_getState(m, d, state, sig)
        return state

    def set_state(self, state: np.ndarray) -> np.ndarray:
        """Restores a state from :meth:`get_state` at the start of an episode; returns the obs."""
        import mujoco
        sig = mujoco.mjtState.mjSTATE_INTEGRATION
        m, d = self.physics.model.ptr, self.physics.data.ptr
        state = np.asarray(state, dtype=np.float64)
        if state.shape != (mujoco.mj_stateSize(m, sig),):
            raise ValueError(f"state of shape {state.shape} does not fit task {self.spec.name!r}")
        mujoco.mj_setState(m, d, state, sig)
        # dm_control keeps position-dependent quantities up to date after every step.
        mujoco.mj_forward(m, d)
        self.t = 0
        self._needs_reset = False
        return self.observation()

    def render(self, height: int = 240, width: int = 320, camera_id=None) -> np.ndarray:
        cam = self.default_camera if camera_id is None else camera_id
        return self.physics.render(height=height, width=width, camera_id=cam)

    @property
    def default_camera(self):
        return getattr(self.task, "camera", 0)


Factory = Callable[[np.random.RandomState], tuple]
