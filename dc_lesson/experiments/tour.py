"""The tour of the tasks (chapter 00 and ``dc-lesson tour``): a frame of each task, its spec,
and what a uniformly random policy scores on it."""

from __future__ import annotations

import numpy as np

from dc_lesson.viz import render
from dc_lesson.data import rollout
from dc_lesson import tasks as _tasks


def random_returns(names=None, n_episodes: int = 10, seed: int = 0,
                   progress: bool = True) -> dict[str, dict]:
    """Mean and std of the return of ``RandomPolicy`` over ``n_episodes`` per task."""
    names = list(names or _tasks.NAMES)
    out = {}
    it = names
    if progress:
        from dc_lesson import progress as _progress
        it = _progress.bar(names, desc="random-policy episodes", unit="task")
    for name in it:
        trajs = rollout.collect(name, rollout.RandomPolicy(name, seed), n_episodes, seed=seed,
                                progress=False)
        r = rollout.returns(trajs)
        out[name] = {"mean": float(r.mean()), "std": float(r.std(ddof=1)) if len(r) > 1 else 0.0,
                     "n_episodes": int(n_episodes)}
    return out


def frames(names=None, height: int = 240, width: int = 320, seed: int = 0) -> list[np.ndarray]:
    return [render.frame(n, seed=seed, height=height, width=width)
            for n in (names or _tasks.NAMES)]
