"""``hopper``: dm_control's hopper with the hop task (the paper's Hopper-v2).

Kept as the suite's task: reward = standing (torso at least 0.6 above the foot) times hopping
speed (linear in forward speed up to 2 m/s), in [0, 1] per step, 1000 steps of 20 ms. Gym's
Hopper-v2 instead pays 1 per healthy step plus forward velocity and ends the episode on a fall.
"""

from __future__ import annotations

import numpy as np
from dm_control.suite import hopper as suite_hopper

from dc_lesson.tasks.base import PortTask, TaskSpec

SPEC = TaskSpec(
    name="hopper", paper_task="Hopper-v2", base="suite hopper, hop task",
    obs_dim=15, act_dim=4, horizon=1000, control_timestep=0.02, n_sub_steps=4,
    mode_feature_names=("torso height", "forward speed"),
    differs="dm_control's hopper model (4 actuators) and hop reward; no alive bonus and no "
            "termination on a fall; random initial orientation as in the suite")


class Physics(suite_hopper.Physics):
    pass


class Hop(suite_hopper.Hopper, PortTask):
    camera = "cam0"

    def __init__(self, random=None):
        super().__init__(hopping=True, random=random)

    def mode_feature(self, physics):
        return np.array([physics.height(), physics.speed()])
