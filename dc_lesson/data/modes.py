"""Which behaviour mode an episode took, and the shares of the modes over a set of episodes.

A multi-mode task's spec names its modes (``tasks.SPECS[name].modes``); each
:class:`~dc_lesson.data.types.Trajectory` records the mode index its episode took.
"""

from __future__ import annotations

import numpy as np

from dc_lesson import tasks as _tasks
from dc_lesson.data.types import Trajectory


def mode_shares(task: str, trajectories) -> dict[str, float]:
    """Fraction of episodes that took each behaviour mode (``Trajectory.mode``), named as in
    the task's spec (``single`` for a single-mode task)."""
    spec = _tasks.spec(task)
    trajectories = list(trajectories)
    if not trajectories:
        raise ValueError("mode_shares needs at least one trajectory")
    for i, t in enumerate(trajectories):
        if not isinstance(t, Trajectory):
            raise ValueError(f"item {i} is a {type(t).__name__}, not a Trajectory")
        if t.task != task:
            raise ValueError(f"trajectory {i} is of task {t.task!r}, not {task!r}")
    names = spec.modes or ("single",)
    counts = np.bincount([t.mode for t in trajectories], minlength=len(names))
    return {name: float(c / len(trajectories)) for name, c in zip(names, counts)}


__all__ = ["mode_shares"]
