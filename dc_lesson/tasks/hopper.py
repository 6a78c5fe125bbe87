"""``hopper``: dm_control's hopper with the hop task (the paper's Hopper-v2).

Kept as the suite's task: reward = standing (torso at least 0.6 above the foot) times hopping
speed (linear in forward speed up to 2 m/s), in [0, 1] per step, 1000 steps of 20 ms. Gym's
Hopper-v2 instead pays 1 per healthy step plus forward velocity and ends the episode on a fall.
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control.suite import hopper as suite_hopper
from dm_control.utils import rewards

from dc_lesson.tasks.base import PortTask, TaskSpec, name_id, sensor_slice

SPEC = TaskSpec(
    name="hopper", paper_task="Hopper-v2", base="suite hopper, hop task",
    obs_dim=15, act_dim=4, horizon=1000, control_timestep=0.02, n_sub_steps=4,
    mode_feature_names=("torso height", "forward speed"),
    differs="dm_control's hopper model (4 actuators) and hop reward; no alive bonus and no "
            "termination on a fall; random initial orientation as in the suite")


class Physics(suite_hopper.Physics):
    pass


class Hop(PortTask, suite_hopper.Hopper):
    """The suite's hop task, computed for a batch of environments."""

    camera = "cam0"
    fields = ("qpos", "qvel", "xipos", "sensordata")

    def __init__(self, random=None):
        super().__init__(hopping=True, random=random)

    def resolve(self, model):
        return {"torso": name_id(model, "body", "torso"), "foot": name_id(model, "body", "foot"),
                "touch": [sensor_slice(model, "touch_toe").start,
                          sensor_slice(model, "touch_heel").start],
                "vel": sensor_slice(model, "torso_subtreelinvel").start}

    def _height_speed(self, b):
        i = b.ids
        return b.xipos[:, i["torso"], 2] - b.xipos[:, i["foot"], 2], b.sensordata[:, i["vel"]]

    def batch_observation(self, b):
        return collections.OrderedDict(position=b.qpos[:, 1:], velocity=b.qvel,
                                       touch=np.log1p(b.sensordata[:, b.ids["touch"]]))

    def batch_reward(self, b):
        height, speed = self._height_speed(b)
        standing = rewards.tolerance(height, (suite_hopper._STAND_HEIGHT, 2))
        hopping = rewards.tolerance(speed, bounds=(suite_hopper._HOP_SPEED, float("inf")),
                                    margin=suite_hopper._HOP_SPEED / 2, value_at_margin=0.5,
                                    sigmoid="linear")
        return standing * hopping

    def batch_mode_feature(self, b):
        return np.stack(self._height_speed(b), axis=1)
