"""``walker``: dm_control's planar walker with the walk task (the paper's Walker2d-v2).

Reward = stand term (torso height and uprightness) times a move term (forward speed up to
1 m/s), in [0, 1] per step, 1000 steps of 25 ms (10 physics steps each).
"""

from __future__ import annotations

import numpy as np
from dm_control.suite import walker as suite_walker

from dc_lesson.tasks.base import PortTask, TaskSpec

SPEC = TaskSpec(
    name="walker", paper_task="Walker2d-v2", base="suite walker, walk task",
    obs_dim=24, act_dim=6, horizon=1000, control_timestep=0.025, n_sub_steps=10,
    mode_feature_names=("torso height", "forward speed"),
    differs="dm_control's walker model and walk reward (target speed 1 m/s); no alive bonus "
            "and no termination on a fall")


class Physics(suite_walker.Physics):
    pass


class Walk(suite_walker.PlanarWalker, PortTask):
    camera = "side"

    def __init__(self, random=None):
        super().__init__(move_speed=suite_walker._WALK_SPEED, random=random)

    def mode_feature(self, physics):
        return np.array([physics.torso_height(), physics.horizontal_velocity()])
