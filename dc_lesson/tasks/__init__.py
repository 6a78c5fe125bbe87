"""The paper's ten tasks as dm_control task ports, with three faces on the same physics.

* :func:`load` gives a genuine dm_env environment, as ``dm_control.suite.load`` does
  (``TimeStep``s, observation dicts, ``LAST`` at the fixed horizon, which is a time limit:
  its discount stays 1)::

      >>> from dc_lesson import tasks
      >>> env = tasks.load("reacher4", seed=0)
      >>> ts = env.reset(); ts = env.step(env.action_spec().minimum * 0)

* Gymnasium: importing this module registers ``dc_lesson/NAME-v0`` for every port, so
  ``gymnasium.make("dc_lesson/reacher4-v0")`` gives ``Box`` spaces, ``reset(seed=) -> (obs,
  info)``, ``terminated=False, truncated=True`` at the horizon and the mode feature in
  ``info`` (``gymnasium.make("dc_lesson.tasks:dc_lesson/reacher4-v0")`` imports it for you);
* :func:`make` (and :func:`load_vec` for a batch) is the fast flat-vector engine the library's
  own training and rollouts use: ``reset(seed) -> obs``, ``step(a) -> (obs, reward, done)``.

A test checks that the three agree step for step over whole episodes.

``tasks.NAMES`` lists the ports in the paper's order; ``tasks.SPECS[name]`` is each one's
:class:`~dc_lesson.tasks.base.TaskSpec` (sizes, horizon, timestep, mode feature, how it differs
from the paper's Gym task); ``tasks.spec_table()`` gives them as rows for a table.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
from typing import Callable

import numpy as np
from dm_control.suite import cartpole as suite_cartpole
from dm_control.suite import cheetah as suite_cheetah
from dm_control.suite import humanoid as suite_humanoid
from dm_control.suite import walker as suite_walker

from dc_lesson.tasks import ant, cartpole, cheetah, hopper, humanoid, reacher, walker
from dc_lesson.tasks.base import (NO_MODE, ActionError, PhysicsDiverged, PortTask, TaskEnv,
                                  TaskSpec)
from dc_lesson.tasks.vec import VecEnv

@dataclasses.dataclass(frozen=True)
class Port:
    """How to build one task port: its spec, Physics class, model and Task class."""
    spec: TaskSpec
    physics: type
    model_and_assets: Callable[[], tuple]
    task: Callable[..., PortTask]   # called with random=RandomState


_PORTS = {
    "cartpole": Port(cartpole.SPEC, cartpole.Physics, suite_cartpole.get_model_and_assets,
                     cartpole.Balance),
    "reacher1": Port(reacher.SPECS[1], reacher.Physics,
                     functools.partial(reacher.get_model_and_assets, 1),
                     functools.partial(reacher.ReachAny, 1)),
    "reacher2": Port(reacher.SPECS[2], reacher.Physics,
                     functools.partial(reacher.get_model_and_assets, 2),
                     functools.partial(reacher.ReachAny, 2)),
    "reacher4": Port(reacher.SPECS[4], reacher.Physics,
                     functools.partial(reacher.get_model_and_assets, 4),
                     functools.partial(reacher.ReachAny, 4)),
    "hopper": Port(hopper.SPEC, hopper.Physics, hopper.get_model_and_assets, hopper.Hop),
    "walker": Port(walker.SPEC, walker.Physics, suite_walker.get_model_and_assets, walker.Walk),
    "halfcheetah": Port(cheetah.SPEC, cheetah.Physics, suite_cheetah.get_model_and_assets,
                        cheetah.Run),
    "halfcheetah2": Port(cheetah.SPEC2, cheetah.Physics, suite_cheetah.get_model_and_assets,
                         cheetah.RunEitherWay),
    "ant": Port(ant.SPEC, ant.Physics, ant.get_model_and_assets, ant.Run),
    "humanoid": Port(humanoid.SPEC, humanoid.Physics, suite_humanoid.get_model_and_assets,
                     humanoid.Walk),
}
_MODELS: dict = {}   # compiled models, one per task and process: compiling costs ~0.1 s

NAMES: tuple[str, ...] = tuple(_PORTS)
# Training-only terminal tests by name, for PPO's and SAC's ``terminate`` (the tasks never
# end early): fn(observations (N, obs_dim)) -> (N,) bool.
TERMINATIONS = {"hopper-fall": hopper.fell, "humanoid-fall": humanoid.fell}
SPECS: dict[str, TaskSpec] = {name: port.spec for name, port in _PORTS.items()}


class UnknownTaskError(KeyError):
    """A task name that is not one of :data:`NAMES`."""

    def __str__(self):  # KeyError would print the message with quotes around it
        return str(self.args[0])


def check_name(name: str) -> str:
    if name not in _PORTS:
        raise UnknownTaskError(
            f"unknown task {name!r}; the tasks are: {', '.join(NAMES)}")
    return name


def spec(name: str) -> TaskSpec:
    return SPECS[check_name(name)]


def _not_settotalmass(record: logging.LogRecord) -> bool:
    """Drops one log line: MuJoCo's deprecation of ``settotalmass``, which dm_control's own
    cheetah.xml uses (not ours to change; the masses are as the suite intends).  Installed
    only while a model compiles, so every other absl message still shows."""
    return "settotalmass" not in record.getMessage()


def make(name: str, seed: int | None = None, *, _model=None) -> TaskEnv:
    """The fast face of task port ``name``; ``seed`` seeds the task's RandomState (initial
    states).

    Raises :class:`UnknownTaskError` (a ``KeyError``) naming the valid tasks for a wrong name.
    """
    port = _PORTS[check_name(name)]
    if name not in _MODELS:
        absl = logging.getLogger("absl")
        absl.addFilter(_not_settotalmass)
        try:
            _MODELS[name] = port.physics.from_xml_string(*port.model_and_assets()).model
        finally:
            absl.removeFilter(_not_settotalmass)
    # Each environment gets its own copy of the model, so a task may change it safely; the
    # copies of a VecEnv share one (no port changes its model after compiling).
    physics = port.physics.from_model(_MODELS[name].copy() if _model is None else _model)
    return TaskEnv(port.spec, physics, port.task(random=np.random.RandomState(seed)))


def load(name: str, seed: int | None = None):
    """Task port ``name`` as a dm_env environment (``dm_control.rl.control.Environment``), as
    ``dm_control.suite.load`` gives its tasks; ``seed`` seeds the task's RandomState.

    Observations are the task's observation dict; an episode ends with ``StepType.LAST``
    after exactly ``spec.horizon`` control steps, a time limit (discount 1).
    """
    return make(name, seed).dm_env


def model_and_assets(name: str) -> tuple:
    """The MJCF text and asset dict of task ``name``'s model (what a planner copies)."""
    return _PORTS[check_name(name)].model_and_assets()


def load_vec(name: str, n_envs: int, batched: bool | None = None) -> VecEnv:
    """``n_envs`` copies of task ``name`` stepped in lockstep (see :class:`VecEnv`;
    ``batched=False`` steps each copy on its own Physics, the reference path)."""
    if n_envs < 1:
        raise ValueError(f"n_envs must be at least 1, got {n_envs}")
    model = make(name).physics.model
    return VecEnv([make(name, _model=model) for _ in range(n_envs)], batched=batched)


def spec_table() -> list[dict]:
    """One row per task: the facts of its spec, for the tour chapter and the README."""
    return [{"task": s.name, "paper task": s.paper_task, "dm_control base": s.base,
             "obs": s.obs_dim, "act": s.act_dim, "horizon": s.horizon,
             "control dt (s)": s.control_timestep, "physics steps": s.n_sub_steps,
             "mode feature": ", ".join(s.mode_feature_names),
             "modes": ", ".join(s.modes) or "-", "differs from the paper": s.differs}
            for s in SPECS.values()]


def gym_id(name: str) -> str:
    """The Gymnasium id of task port ``name``: ``dc_lesson/NAME-v0``."""
    return f"dc_lesson/{check_name(name)}-v0"


def _register_gymnasium() -> None:
    try:
        import gymnasium
    except ImportError:   # pragma: no cover - gymnasium is a dependency; stay importable
        return
    for name in NAMES:
        if gym_id(name) not in gymnasium.registry:
            gymnasium.register(id=gym_id(name), entry_point="dc_lesson.tasks.gym:GymEnv",
                               kwargs={"task": name}, disable_env_checker=False)


_register_gymnasium()

__all__ = ["NAMES", "NO_MODE", "SPECS", "TERMINATIONS", "ActionError", "PhysicsDiverged", "PortTask", "TaskEnv", "TaskSpec",
           "UnknownTaskError", "VecEnv", "check_name", "gym_id", "load", "load_vec", "make", "spec",
           "spec_table"]
