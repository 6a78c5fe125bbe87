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
    the task's spec, plus ``none`` (episodes that arrived at no mode) for a multi-mode task;
    ``{"single": 1.0}`` for a single-mode task."""
    spec = _tasks.spec(task)
    trajectories = list(trajectories)
    if not trajectories:
        raise ValueError("mode_shares needs at least one trajectory")
    for i, t in enumerate(trajectories):
        if not isinstance(t, Trajectory):
            raise ValueError(f"item {i} is a {type(t).__name__}, not a Trajectory")
        if t.task != task:
            raise ValueError(f"trajectory {i} is of task {t.task!r}, not {task!r}")
    if not spec.multimodal:
        return {"single": 1.0}
    names = (*spec.modes, "none")
    labels = np.array([t.mode for t in trajectories])
    counts = np.bincount(np.where(labels == _tasks.NO_MODE, len(spec.modes), labels),
                         minlength=len(names))
    return {name: float(c / len(trajectories)) for name, c in zip(names, counts)}


def total_variation(p: dict[str, float], q: dict[str, float]) -> float:
    """Total-variation distance of two mode-share dicts (the "none" class included):
    half the summed absolute differences, 0 for equal shares, 1 for disjoint ones."""
    keys = set(p) | set(q)
    return 0.5 * float(sum(abs(p.get(k, 0.0) - q.get(k, 0.0)) for k in keys))


__all__ = ["mode_shares", "total_variation"]
