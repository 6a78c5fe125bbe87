"""``VecEnv``: many copies of one task stepped in lockstep, the engine of every rollout.

A step is one control step of every running copy.  Two paths give the same numbers, to the
bit (``tests/test_tasks.py`` compares them with :class:`~dc_lesson.tasks.base.TaskEnv`, itself
compared with dm_control's own ``Environment``):

* **batched** (every task without step hooks): the copies' simulations live in one
  ``mujoco.batch.Batch`` (MuJoCo 3.17, one thread, one ``MjData`` per copy), and a control step
  is one call into C for the whole batch: set the controls, take ``n_sub_steps`` physics steps,
  then compute the position and velocity stages (``mjSTAGE_VEL``, what dm_control's legacy
  ``mj_step1`` after the step computes, and what the next step continues from, as dm_control's
  ``mj_step2`` does).  Observations, rewards and mode features read the batch's arrays, each
  ``(n_envs, ...)``, with NumPy.  A Python loop over the copies, three calls into MuJoCo each,
  is what this replaces; ``dc-lesson perf rollout`` measures the two.
* **per copy** (a task whose ``before_step`` / ``after_step`` do more than set the controls):
  each copy is stepped by its own ``Physics`` as :class:`TaskEnv` steps it.

Episodes start on the copies' own dm_control ``Physics`` (the task's ``initialize_episode`` in
``reset_context``, as dm_control's ``Environment.reset``); the batched path then takes each
copy's full integration state (``mjSTATE_INTEGRATION``: positions, velocities, controls, the
solver's warm start, ...) into its simulation and runs ``mj_forward`` there, which computes
what dm_control's reset computed from the same inputs.  While episodes run, the copies'
``Physics`` are left behind: read states through :meth:`VecEnv.get_states`.
"""

from __future__ import annotations

import contextlib

import mujoco
import mujoco.batch
import numpy as np
from dm_control.suite import base as suite_base

from dc_lesson.tasks.base import ActionError, Batch, PhysicsDiverged, TaskEnv, step_physics

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION
_BATCHED = True      # the default of VecEnv(batched=None); per_copy() switches it off


@contextlib.contextmanager
def per_copy():
    """Within the block, new VecEnvs step copy by copy (the reference path; what a benchmark
    of the path before issue 14 runs)."""
    global _BATCHED
    old, _BATCHED = _BATCHED, False
    try:
        yield
    finally:
        _BATCHED = old


class VecEnv:
    """``n_envs`` copies of a task stepped in lockstep, for rollouts and RL.

    All copies share the fixed horizon, so they start and end their episodes together;
    ``reset(seeds)`` may start fewer episodes than there are copies (the rest sit idle), and
    ``reset_one(i, seed)`` restarts one copy in the middle of the others' episodes.
    """

    def __init__(self, envs: list[TaskEnv], batched: bool | None = None):
        """``batched``: step the copies as one ``mujoco.batch.Batch`` (None: whenever the task
        has no step hooks, outside :func:`per_copy`; False: each copy on its own Physics, the
        reference path)."""
        if not envs:
            raise ValueError("a VecEnv needs at least one environment")
        self.envs = envs
        self.spec = envs[0].spec
        self.task = envs[0].task
        self.action_low, self.action_high = envs[0].action_low, envs[0].action_high
        self._model = envs[0].physics.model.ptr
        cls = type(self.task)
        hooks = (cls.before_step is not suite_base.Task.before_step
                 or cls.after_step is not suite_base.Task.after_step)
        if batched and hooks:
            raise ValueError(f"task {self.spec.name!r} has step hooks: it steps copy by copy")
        self._batch = None
        if not hooks and (_BATCHED if batched is None else batched):
            self._batch = mujoco.batch.Batch(self._model, len(envs), nthread=1, persistent=True)
            self._ctrl = self._batch.bind("ctrl")
            # live (n_envs, ...) arrays: state fields view the rows, the others are refreshed
            # after every call
            self._fields = {f: self._batch.bind(f) for f in self.task.fields}
        self.n_active = 0
        self.t = 0

    @property
    def n_envs(self) -> int:
        return len(self.envs)

    @property
    def batched(self) -> bool:
        """Whether the copies step as one ``mujoco.batch.Batch`` (see the module docstring)."""
        return self._batch is not None

    def _take(self, ids) -> None:
        """Copies ``ids`` just reset on their own Physics into the batch, and forwards them."""
        for i in ids:
            e = self.envs[i]
            mujoco.mj_getState(self._model, e.physics.data.ptr, self._batch.state[i], _INTEGRATION)
        self._batch.forward(np.asarray(ids, np.int32))

    def _outputs(self, n: int):
        """(observations, rewards, mode features) of the first ``n`` copies."""
        if self._batch is None:
            return self.task.outputs([e.physics.data.ptr for e in self.envs[:n]], self._model)
        return self.task.outputs_of(Batch.of_arrays(self._fields, n, self.task.ids(self._model)),
                                    n)

    def reset(self, seeds) -> tuple[np.ndarray, np.ndarray]:
        """Starts ``len(seeds)`` episodes: returns (observations, mode features)."""
        seeds = np.asarray(seeds).reshape(-1)
        if not 1 <= len(seeds) <= self.n_envs:
            raise ValueError(f"reset takes 1 to {self.n_envs} seeds, got {len(seeds)}")
        for env, seed in zip(self.envs, seeds):
            env.reset(seed=int(seed))
        self.n_active = len(seeds)
        self.t = 0
        if self._batch is not None:
            self._take(range(self.n_active))
        obs, _, feat = self._outputs(self.n_active)
        return obs, feat

    def reset_one(self, i: int, seed: int) -> np.ndarray:
        """Restarts copy ``i`` alone (a training-only termination): returns its observation."""
        if not 0 <= i < self.n_active:
            raise ValueError(f"copy {i} is not running: {self.n_active} episodes are")
        obs = self.envs[i].reset(seed=int(seed))
        if self._batch is None:
            return obs
        self._take([i])
        return self._outputs(self.n_active)[0][i]

    def _running(self) -> None:
        if self.n_active == 0:
            raise RuntimeError("no episode is running: call reset(seeds) first")

    def get_states(self, sig=_INTEGRATION) -> np.ndarray:
        """The running copies' MuJoCo states (``mj_getState`` with ``sig``), float64."""
        self._running()
        if self._batch is None:
            out = np.empty((self.n_active, mujoco.mj_stateSize(self._model, sig)))
            for row, e in zip(out, self.envs):
                mujoco.mj_getState(self._model, e.physics.data.ptr, row, sig)
            return out
        rows = self._batch.state[:self.n_active]
        if sig == _INTEGRATION:
            return rows.copy()
        # another signature: through a scratch MjData (states only, nothing computed)
        scratch = mujoco.MjData(self._model)
        out = np.empty((self.n_active, mujoco.mj_stateSize(self._model, sig)))
        for row, o in zip(rows, out):
            mujoco.mj_setState(self._model, scratch, row, _INTEGRATION)
            mujoco.mj_getState(self._model, scratch, o, sig)
        return out

    def data(self, i: int) -> mujoco.MjData:
        """Copy ``i``'s MjData as the last step left it (state and derived fields): batched,
        a copy taken from the batch; per copy, its Physics' own data."""
        self._running()
        if not 0 <= i < self.n_active:
            raise ValueError(f"copy {i} is not running: {self.n_active} episodes are")
        if self._batch is None:
            return self.envs[i].physics.data.ptr
        return self._batch.get_data(i)

    def check_actions(self, actions) -> np.ndarray:
        a = np.asarray(actions, dtype=np.float64)
        shape = (self.n_active, self.spec.act_dim)
        if a.shape != shape:
            raise ActionError(f"task {self.spec.name!r} with {self.n_active} running episodes "
                              f"takes actions of shape {shape}, got shape {a.shape}")
        if not np.isfinite(a).all():
            raise ActionError(f"task {self.spec.name!r} got non-finite actions")
        # np.clip's value, without its Python wrapper (called on every step of a rollout)
        return np.minimum(np.maximum(a, self.action_low), self.action_high)

    def step(self, actions, *, checked: bool = False
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """One control step of every running episode: (observations, rewards, mode features,
        done); ``done`` is True at the horizon, after which ``reset`` is needed.

        ``checked=True``: the actions are what :meth:`check_actions` returned this step
        (the rollout loops check them once, keep them, then step), so they are not checked
        and clipped a second time."""
        if self.n_active == 0 or self.t >= self.spec.horizon:
            raise RuntimeError("call reset() before step(): the episodes are over or not started")
        # float64 as check_actions returns it (a task's step hook may compute with it)
        a = np.asarray(actions, np.float64) if checked else self.check_actions(actions)
        n = self.n_active
        if self._batch is None:
            for env, ai in zip(self.envs[:n], a):
                env.task.before_step(ai, env.physics)
                step_physics(env.physics.model.ptr, env.physics.data.ptr, self.spec.n_sub_steps)
                env.task.after_step(env.physics)
        else:
            self._ctrl[:n] = a          # what Task.before_step does (set_control)
            self._batch.step(None if n == self.n_envs else np.arange(n, dtype=np.int32),
                             nstep=self.spec.n_sub_steps, stage=mujoco.mjtStage.mjSTAGE_VEL)
        obs, rew, feat = self._outputs(n)
        if not np.isfinite(obs).all():
            raise PhysicsDiverged(f"the {self.spec.name} simulation diverged at step {self.t}")
        self.t += 1
        return obs, rew, feat, self.t >= self.spec.horizon
