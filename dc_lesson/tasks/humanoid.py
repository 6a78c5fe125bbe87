"""``humanoid``: dm_control's humanoid with the walk task (the paper's Humanoid-v2).

Reward = standing (head height) x upright x small control x moving (horizontal speed of the
centre of mass up to 1 m/s, in any direction), in [0, 1] per step, 1000 steps of 25 ms.
"""

from __future__ import annotations

import numpy as np
from dm_control.suite import humanoid as suite_humanoid

from dc_lesson.tasks.base import PortTask, TaskSpec

SPEC = TaskSpec(
    name="humanoid", paper_task="Humanoid-v2", base="suite humanoid, walk task",
    obs_dim=67, act_dim=21, horizon=1000, control_timestep=0.025, n_sub_steps=5,
    mode_feature_names=("head height", "horizontal speed"),
    differs="dm_control's 21-actuator humanoid and walk reward (speed 1 m/s in any direction); "
            "Gym's Humanoid-v2 pays forward speed plus an alive bonus and ends on a fall")


class Physics(suite_humanoid.Physics):
    pass


class Walk(suite_humanoid.Humanoid, PortTask):
    camera = "side"

    def __init__(self, random=None):
        super().__init__(move_speed=suite_humanoid._WALK_SPEED, pure_state=False, random=random)

    def mode_feature(self, physics):
        speed = np.linalg.norm(physics.center_of_mass_velocity()[:2])
        return np.array([physics.head_height(), speed])
