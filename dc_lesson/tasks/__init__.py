"""The paper's ten tasks as dm_control task ports, and the one entry point :func:`load`.

>>> from dc_lesson import tasks
>>> env = tasks.load("reacher4", seed=0)
>>> obs = env.reset()
>>> obs, reward, done = env.step(env.action_low * 0)

``tasks.NAMES`` lists the ports in the paper's order; ``tasks.SPECS[name]`` is each one's
:class:`~dc_lesson.tasks.base.TaskSpec` (sizes, horizon, timestep, mode feature, how it differs
from the paper's Gym task); ``tasks.spec_table()`` gives them as rows for a table.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Callable

import numpy as np
from dm_control.suite import cartpole as suite_cartpole
from dm_control.suite import cheetah as suite_cheetah
from dm_control.suite import humanoid as suite_humanoid
from dm_control.suite import walker as suite_walker

from dc_lesson.tasks import ant, cartpole, cheetah, hopper, humanoid, reacher, walker
from dc_lesson.tasks.base import (ActionError, PhysicsDiverged, PortTask, TaskEnv, TaskSpec,
                                  VecEnv)

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


def load(name: str, seed: int | None = None, *, _model=None) -> TaskEnv:
    """Builds the task port ``name``; ``seed`` seeds the task's RandomState (initial states).

    Raises :class:`UnknownTaskError` (a ``KeyError``) naming the valid tasks for a wrong name.
    """
    port = _PORTS[check_name(name)]
    if name not in _MODELS:
        _MODELS[name] = port.physics.from_xml_string(*port.model_and_assets()).model
    # Each environment gets its own copy of the model, so a task may change it safely; the
    # copies of a VecEnv share one (no port changes its model after compiling).
    physics = port.physics.from_model(_MODELS[name].copy() if _model is None else _model)
    return TaskEnv(port.spec, physics, port.task(random=np.random.RandomState(seed)))


def model_and_assets(name: str) -> tuple:
    """The MJCF text and asset dict of task ``name``'s model (what a planner copies)."""
    return _PORTS[check_name(name)].model_and_assets()


def load_vec(name: str, n_envs: int) -> VecEnv:
    """``n_envs`` copies of task ``name`` stepped in lockstep (see :class:`VecEnv`)."""
    if n_envs < 1:
        raise ValueError(f"n_envs must be at least 1, got {n_envs}")
    model = load(name).physics.model
    return VecEnv([load(name, _model=model) for _ in range(n_envs)])


def spec_table() -> list[dict]:
    """One row per task: the facts of its spec, for the tour chapter and the README."""
    return [{"task": s.name, "paper task": s.paper_task, "dm_control base": s.base,
             "obs": s.obs_dim, "act": s.act_dim, "horizon": s.horizon,
             "control dt (s)": s.control_timestep, "physics steps": s.n_sub_steps,
             "mode feature": ", ".join(s.mode_feature_names),
             "modes": ", ".join(s.modes) or "-", "differs from the paper": s.differs}
            for s in SPECS.values()]


__all__ = ["NAMES", "SPECS", "ActionError", "PhysicsDiverged", "PortTask", "TaskEnv", "TaskSpec",
           "UnknownTaskError", "VecEnv", "check_name", "load", "load_vec", "spec", "spec_table"]
