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

import numpy as np

from dc_lesson.tasks import ant, cartpole, cheetah, hopper, humanoid, reacher, walker
from dc_lesson.tasks.base import ActionError, PortTask, TaskEnv, TaskSpec

_FACTORIES = {
    "cartpole": (cartpole.SPEC, cartpole.make),
    "reacher1": (reacher.SPECS[1], reacher.make_factory(1)),
    "reacher2": (reacher.SPECS[2], reacher.make_factory(2)),
    "reacher4": (reacher.SPECS[4], reacher.make_factory(4)),
    "hopper": (hopper.SPEC, hopper.make),
    "walker": (walker.SPEC, walker.make),
    "halfcheetah": (cheetah.SPEC, cheetah.make),
    "halfcheetah2": (cheetah.SPEC2, cheetah.make2),
    "ant": (ant.SPEC, ant.make),
    "humanoid": (humanoid.SPEC, humanoid.make),
}

NAMES: tuple[str, ...] = tuple(_FACTORIES)
SPECS: dict[str, TaskSpec] = {name: spec for name, (spec, _) in _FACTORIES.items()}


class UnknownTaskError(KeyError):
    """A task name that is not one of :data:`NAMES`."""

    def __str__(self):  # KeyError would print the message with quotes around it
        return str(self.args[0])


def check_name(name: str) -> str:
    if name not in _FACTORIES:
        raise UnknownTaskError(
            f"unknown task {name!r}; the tasks are: {', '.join(NAMES)}")
    return name


def spec(name: str) -> TaskSpec:
    return SPECS[check_name(name)]


def load(name: str, seed: int | None = None) -> TaskEnv:
    """Builds the task port ``name``; ``seed`` seeds the task's RandomState (initial states).

    Raises :class:`UnknownTaskError` (a ``KeyError``) naming the valid tasks for a wrong name.
    """
    task_spec, factory = _FACTORIES[check_name(name)]
    physics, task = factory(np.random.RandomState(seed))
    return TaskEnv(task_spec, physics, task)


def spec_table() -> list[dict]:
    """One row per task: the facts of its spec, for the tour chapter and the README."""
    return [{"task": s.name, "paper task": s.paper_task, "dm_control base": s.base,
             "obs": s.obs_dim, "act": s.act_dim, "horizon": s.horizon,
             "control dt (s)": s.control_timestep, "physics steps": s.n_sub_steps,
             "mode feature": ", ".join(s.mode_feature_names),
             "modes": ", ".join(s.modes) or "-", "differs from the paper": s.differs}
            for s in SPECS.values()]


__all__ = ["NAMES", "SPECS", "ActionError", "PortTask", "TaskEnv", "TaskSpec",
           "UnknownTaskError", "check_name", "load", "spec", "spec_table"]
