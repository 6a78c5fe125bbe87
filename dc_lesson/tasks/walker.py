"""``walker``: dm_control's planar walker with the walk task (the paper's Walker2d-v2).

Reward = stand term (torso height and uprightness) times a move term (forward speed up to
1 m/s), in [0, 1] per step, 1000 steps of 25 ms (10 physics steps each).
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control.suite import walker as suite_walker

from dc_lesson.tasks.base import (PortTask, TaskSpec, gaussian_tolerance_above,
                                  linear_tolerance_above, name_id, sensor_slice)

SPEC = TaskSpec(
    name="walker", paper_task="Walker2d-v2", base="suite walker, walk task",
    obs_dim=24, act_dim=6, horizon=1000, control_timestep=0.025, n_sub_steps=10,
    mode_feature_names=("torso height", "forward speed"),
    differs="dm_control's walker model and walk reward (target speed 1 m/s); no alive bonus "
            "and no termination on a fall")


class Physics(suite_walker.Physics):
    pass


_XX, _XZ, _ZZ = 0, 2, 8   # entries of a flattened rotation matrix


class Walk(PortTask, suite_walker.PlanarWalker):
    """The suite's walk task, computed for a batch of environments."""

    camera = "side"
    fields = ("qvel", "xpos", "xmat", "sensordata")

    def __init__(self, random=None):
        super().__init__(move_speed=suite_walker._WALK_SPEED, random=random)

    def resolve(self, model):
        return {"torso": name_id(model, "body", "torso"),
                "vel": sensor_slice(model, "torso_subtreelinvel").start}

    def batch_observation(self, b):
        orientations = b.xmat[:, 1:][:, :, [_XX, _XZ]].reshape(len(b.qvel), -1)
        return collections.OrderedDict(orientations=orientations,
                                       height=b.xpos[:, b.ids["torso"], 2], velocity=b.qvel)

    def batch_reward(self, b):
        # PlanarWalker.get_reward term by term, its tolerances as base's equivalents of
        # dm_control's (the same floats, cheaper; tests/test_tasks.py)
        height = b.xpos[:, b.ids["torso"], 2]
        standing = gaussian_tolerance_above(height, suite_walker._STAND_HEIGHT,
                                            suite_walker._STAND_HEIGHT / 2)
        upright = (1 + b.xmat[:, b.ids["torso"], _ZZ]) / 2
        stand_reward = (3 * standing + upright) / 4
        speed = self._move_speed
        move_reward = linear_tolerance_above(b.sensordata[:, b.ids["vel"]], speed, speed / 2,
                                             value_at_margin=0.5)
        return stand_reward * (5 * move_reward + 1) / 6

    def batch_mode_feature(self, b):
        return np.stack([b.xpos[:, b.ids["torso"], 2], b.sensordata[:, b.ids["vel"]]], axis=1)
