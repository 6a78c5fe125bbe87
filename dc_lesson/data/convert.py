"""Our trajectories in other libraries' types.

:func:`to_imitation` gives HumanCompatibleAI ``imitation``'s ``TrajectoryWithRew`` (``obs``:
T+1 observations, ``acts``: T actions, ``rews``: T rewards, ``infos``: one dict per step with the
mode feature, ``terminal=False``).  ``terminal`` is False because every episode of a port ends
at its fixed horizon, a time limit and not a terminal state; an algorithm that bootstraps from
the last state (imitation's AIRL and GAIL do) then treats it correctly.  ``imitation`` is not a
dependency of this library: install it to use this (``pip install imitation``).
"""

from __future__ import annotations

import numpy as np

from dc_lesson.data.types import Trajectory


def to_imitation(trajectories):
    """A :class:`Trajectory` (or a sequence of them) as imitation's ``TrajectoryWithRew``."""
    try:
        from imitation.data.types import TrajectoryWithRew
    except ImportError:
        raise ImportError("to_imitation needs the imitation library: pip install imitation") \
            from None
    single = isinstance(trajectories, Trajectory)
    items = [trajectories] if single else list(trajectories)
    out = []
    for i, t in enumerate(items):
        if not isinstance(t, Trajectory):
            raise TypeError(f"item {i} is a {type(t).__name__}, not a dc_lesson Trajectory")
        infos = np.array([{"mode_feature": f, "mode": t.mode} for f in t.mode_features[1:]])
        out.append(TrajectoryWithRew(obs=np.array(t.observations), acts=np.array(t.actions),
                                     infos=infos, terminal=False,
                                     rews=t.rewards.astype(np.float32)))
    return out[0] if single else out


__all__ = ["to_imitation"]
