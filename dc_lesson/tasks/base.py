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

import collections
import dataclasses
from typing import Callable

import mujoco
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


class Batch:
    """MjData arrays of B environments stacked on a first axis: what a task's batch functions
    read.  ``ids`` holds the task's named indices (body, geom, sensor addresses)."""

    def __init__(self, datas, fields, ids):
        self.ids = ids
        for f in fields:
            setattr(self, f, np.stack([getattr(d, f) for d in datas]))

    @classmethod
    def of_arrays(cls, arrays: dict, n: int, ids) -> "Batch":
        """The batch of the first ``n`` rows of ``(n_envs, ...)`` arrays already stacked (a
        ``mujoco.batch.Batch``'s bound fields): views, nothing copied."""
        b = cls.__new__(cls)
        b.ids = ids
        for f, arr in arrays.items():
            setattr(b, f, arr[:n])
        return b


class PortTask(suite_base.Task):
    """Base of the ports' Task classes: observations, rewards and mode features computed for a
    whole batch of environments at once.

    A port lists the MjData ``fields`` it reads and resolves the names it needs into indices
    once (``resolve``); then ``batch_observation``, ``batch_reward`` and ``batch_mode_feature``
    compute from a :class:`Batch` with NumPy, for one environment or for many.  dm_control's
    per-environment ``get_observation`` and ``get_reward`` are these with a batch of one, so
    the single and the batched paths run the same code and agree to the bit.  For ports of
    suite tasks a test checks that they equal the suite's own functions.

    The *mode feature* is what coverage plots, EMD and KL are computed on (fingertip x-y for
    the reachers, forward velocity for the cheetahs, ...); ``classify_mode`` maps mode features
    to the index of the behaviour mode (for multi-mode tasks), or zeros.
    """

    fields: tuple[str, ...] = ("qpos", "qvel")
    _ids = None

    def resolve(self, model) -> dict:
        """Named indices the batch functions use (override in a port)."""
        return {}

    def ids(self, model) -> dict:
        """The named indices, resolved on first use."""
        if self._ids is None:
            self._ids = self.resolve(model)
        return self._ids

    def gather(self, datas, model) -> Batch:
        return Batch(datas, self.fields, self.ids(model))

    def batch_observation(self, b: Batch) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError

    def batch_reward(self, b: Batch) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def batch_mode_feature(self, b: Batch) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def outputs(self, datas, model):
        """(observations (B, obs_dim) float32, rewards (B,) float64, mode features (B, k))."""
        return self.outputs_of(self.gather(datas, model), len(datas))

    def outputs_of(self, b: Batch, n: int):
        """:meth:`outputs` of a gathered batch of ``n`` environments."""
        # cast to float32 as it is concatenated (one copy, the same rounding as astype)
        obs = np.concatenate([v.reshape(n, -1) for v in self.batch_observation(b).values()],
                             axis=1, dtype=np.float32)
        # fresh arrays: a batch may view live simulation memory that the next step rewrites
        return (obs, np.array(self.batch_reward(b), dtype=np.float64),
                np.array(self.batch_mode_feature(b), dtype=np.float32))

    # dm_control's per-environment interface, as a batch of one.
    def get_observation(self, physics):
        b = self.gather([physics.data.ptr], physics.model.ptr)
        return collections.OrderedDict((k, v[0]) for k, v in self.batch_observation(b).items())

    def get_reward(self, physics):
        return float(self.batch_reward(self.gather([physics.data.ptr], physics.model.ptr))[0])

    def mode_feature(self, physics) -> np.ndarray:
        return self.batch_mode_feature(self.gather([physics.data.ptr], physics.model.ptr))[0]

    def classify_mode(self, features: np.ndarray) -> np.ndarray:
        features = np.asarray(features)
        return np.zeros(features.shape[:-1], dtype=np.int64)

    def episode_mode(self, mode_features: np.ndarray) -> int:
        """The mode a whole episode took, from its (T+1, k) mode features: the index of the
        mode it arrived at and stayed in, or :data:`NO_MODE` (-1) when it reached none.  A
        single-mode task's episodes all take mode 0; multi-mode ports override this."""
        return 0


NO_MODE = -1   # an episode that arrived at no mode (the "none" class of mode shares)


def name_id(model, kind: str, name: str) -> int:
    """Index of a named body / geom / sensor / joint; an error if the model lacks it."""
    obj = {"body": mujoco.mjtObj.mjOBJ_BODY, "geom": mujoco.mjtObj.mjOBJ_GEOM,
           "sensor": mujoco.mjtObj.mjOBJ_SENSOR, "joint": mujoco.mjtObj.mjOBJ_JOINT}[kind]
    i = mujoco.mj_name2id(model, obj, name)
    if i < 0:
        raise ValueError(f"the model has no {kind} named {name!r}")
    return i


def sensor_slice(model, name: str) -> slice:
    i = name_id(model, "sensor", name)
    adr = model.sensor_adr[i]
    return slice(adr, adr + model.sensor_dim[i])


# dm_control's ``rewards.tolerance`` in the three forms the ports use, as the same NumPy
# expressions without its argument checks and the ``np.where``s that only pick 1.0 at a single
# point: on a batch of 16 the tolerance's calls were most of a one-substep task's outputs.  Each
# returns the same floats as ``tolerance`` (tests/test_tasks.py, edge cases included).
_GAUSSIAN_AT_01 = np.sqrt(-2 * np.log(0.1))   # tolerance's gaussian scale, 0.1 at the margin


def gaussian_tolerance(x, margin: float) -> np.ndarray:
    """``tolerance(x, bounds=(0, 0), margin=margin)``: the gaussian sigmoid of |x| / margin
    (1 at x = 0, as the bounds give)."""
    d = np.abs(x) / margin
    return np.exp(-0.5 * (d * _GAUSSIAN_AT_01) ** 2)


def quadratic_tolerance(x) -> np.ndarray:
    """``tolerance(x, bounds=(0, 0), margin=1, value_at_margin=0, sigmoid="quadratic")``."""
    d = np.abs(x)
    return np.where(d < 1, 1 - d ** 2, 0.0)


def gaussian_tolerance_above(x, lower: float, margin: float) -> np.ndarray:
    """``tolerance(x, bounds=(lower, inf), margin=margin)``: 1 from ``lower`` up, the gaussian
    sigmoid below it (0.1 at ``margin`` below)."""
    d = (lower - x) / margin
    return np.where(x >= lower, 1.0, np.exp(-0.5 * (d * _GAUSSIAN_AT_01) ** 2))


def linear_tolerance_above(x, lower: float, margin: float,
                           value_at_margin: float = 0.0) -> np.ndarray:
    """``tolerance(x, bounds=(lower, inf), margin=margin, value_at_margin=value_at_margin,
    sigmoid="linear")``: 1 from ``lower`` up, falling linearly to ``value_at_margin``
    ``margin`` below it (and on to 0)."""
    d = (lower - x) / margin
    if value_at_margin:
        d = d * (1 - value_at_margin)
    return np.where(x >= lower, 1.0, np.where(d < 1, 1 - d, 0.0))


def step_physics(model, data, n_sub_steps: int) -> None:
    """``n_sub_steps`` physics steps exactly as dm_control's ``Physics.step`` takes them
    (legacy stepping: finish the pending ``mj_step1``, step, then ``mj_step1`` so that
    positions, velocities and sensors are up to date for the observation)."""
    if model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4:
        mujoco.mj_step2(model, data)
        if n_sub_steps > 1:
            mujoco.mj_step(model, data, n_sub_steps - 1)
    else:
        mujoco.mj_step(model, data, n_sub_steps)
    mujoco.mj_step1(model, data)


class PhysicsDiverged(RuntimeError):
    """The simulation produced non-finite numbers."""


class ActionError(ValueError):
    """An action of the wrong shape or with non-finite entries."""


def flatten_observation(obs_dict) -> np.ndarray:
    """Concatenates an observation dict into one float32 vector, in the dict's order."""
    return np.concatenate([np.ravel(v) for v in obs_dict.values()]).astype(np.float32)


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
        """The genuine dm_control environment on this env's physics and task (shared state).

        Its time limit is half a step short of ``horizon`` steps, so that dm_control's step
        limit (time limit / control timestep, a float) ends the episode after exactly
        ``horizon`` steps whatever the rounding of the division."""
        if self._dm_env is None:
            dt = self.spec.control_timestep
            self._dm_env = control.Environment(
                self.physics, self.task, time_limit=(self.spec.horizon - 0.5) * dt,
                control_timestep=dt)
        return self._dm_env

    # -- stepping ----------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> np.ndarray:
        """Starts an episode; with ``seed`` the task's RandomState is re-seeded first."""
        if seed is not None:
            self.task.random.seed(int(seed) % (2**32))
        # As dm_control's Environment.reset: initialise inside reset_context (mj_forward after).
        with self.physics.reset_context():
            self.task.initialize_episode(self.physics)
        return self._start()

    def _start(self) -> np.ndarray:
        self.t = 0
        self._needs_reset = False
        obs, _, _ = self.task.outputs([self.physics.data.ptr], self.physics.model.ptr)
        return obs[0]

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
        step_physics(self.physics.model.ptr, self.physics.data.ptr, self.n_sub_steps)
        self.task.after_step(self.physics)
        obs, reward, _ = self.task.outputs([self.physics.data.ptr], self.physics.model.ptr)
        if not np.all(np.isfinite(obs)):
            raise PhysicsDiverged(f"the {self.spec.name} simulation diverged at step {self.t}")
        self.t += 1
        done = self.t >= self.spec.horizon
        self._needs_reset = done
        return obs[0], float(reward[0]), done

    def mode_feature(self) -> np.ndarray:
        """The mode feature of the current physics state."""
        return np.asarray(self.task.mode_feature(self.physics), dtype=np.float32)

    # -- state, for replaying demonstrations -------------------------------------------------
    def get_state(self) -> np.ndarray:
        """The full MuJoCo simulation state (``mjSTATE_INTEGRATION``), float64."""
        sig = mujoco.mjtState.mjSTATE_INTEGRATION
        m, d = self.physics.model.ptr, self.physics.data.ptr
        state = np.empty(mujoco.mj_stateSize(m, sig))
        mujoco.mj_getState(m, d, state, sig)
        return state

    def set_state(self, state: np.ndarray) -> np.ndarray:
        """Restores a state from :meth:`get_state` at the start of an episode; returns the obs."""
        sig = mujoco.mjtState.mjSTATE_INTEGRATION
        m, d = self.physics.model.ptr, self.physics.data.ptr
        state = np.asarray(state, dtype=np.float64)
        if state.shape != (mujoco.mj_stateSize(m, sig),):
            raise ValueError(f"state of shape {state.shape} does not fit task {self.spec.name!r}")
        mujoco.mj_setState(m, d, state, sig)
        # dm_control keeps position-dependent quantities up to date after every step.
        mujoco.mj_forward(m, d)
        return self._start()

    def render(self, height: int = 240, width: int = 320, camera_id=None) -> np.ndarray:
        cam = self.default_camera if camera_id is None else camera_id
        return self.physics.render(height=height, width=width, camera_id=cam)

    @property
    def default_camera(self):
        return getattr(self.task, "camera", 0)


Factory = Callable[[np.random.RandomState], tuple]
