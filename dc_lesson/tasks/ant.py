"""``ant``: Gym's Ant-v2 model as a dm_control domain (the suite has no ant).

The model is Gym's (rllab's) ant: a 0.25 m torso sphere, four legs of hip and ankle hinges,
8 motors of gear 150, RK4 integration at 10 ms and 5 physics steps per 50 ms control step, as
Gym's frame skip.  The objective is Gym's (healthy and moving forward), rescaled to [0, 1] per
step the dm_control way::

    reward = healthy * clip(forward speed / 3 m/s, 0, 1)
    healthy = tolerance(torso height, bounds=(0.2, 1.0), margin=0.1)   (Gym: 0.2 <= z <= 1)

with a fixed horizon of 1000 control steps and no termination.  Observation as Gym's without
contact forces: the torso height and orientation quaternion, the 8 joint angles (13 numbers),
and all 14 velocities (27 in total).  Episodes start from Gym's initial pose with uniform noise
of +-0.1 on positions and Gaussian noise of std 0.1 on velocities.
"""

from __future__ import annotations

import collections
import pathlib

import numpy as np
from dm_control import mujoco
from dm_control.suite import common
from dm_control.utils import rewards

from dc_lesson.tasks.base import PortTask, TaskSpec, sensor_slice

RUN_SPEED = 3.0          # m/s for full reward
HEALTHY_Z = (0.2, 1.0)   # Gym's healthy torso height range

SPEC = TaskSpec(
    name="ant", paper_task="Ant-v2", base="Gym's ant model as a custom dm_control domain",
    obs_dim=27, act_dim=8, horizon=1000, control_timestep=0.05, n_sub_steps=5,
    mode_feature_names=("forward speed",),
    differs="Gym's model and objective rescaled to [0, 1] per step (speed / 3 m/s, times a "
            "smooth healthy-height term); no control or contact cost; no termination")


def get_model_and_assets():
    xml = (pathlib.Path(__file__).parent / "assets" / "ant.xml").read_text()
    return xml, common.ASSETS


class Physics(mujoco.Physics):
    def torso_height(self) -> float:
        return float(self.data.qpos[2])

    def speed(self) -> float:
        """Forward (x) velocity of the ant's centre of mass."""
        return float(self.named.data.sensordata["torso_subtreelinvel"][0])


class Run(PortTask):
    camera = "track"

    def initialize_episode(self, physics):
        nq, nv = physics.model.nq, physics.model.nv
        physics.data.qpos[:] = physics.model.qpos0 + self.random.uniform(-0.1, 0.1, nq)
        physics.data.qvel[:] = 0.1 * self.random.randn(nv)
        super().initialize_episode(physics)

    fields = ("qpos", "qvel", "sensordata")

    def resolve(self, model):
        return {"vel": sensor_slice(model, "torso_subtreelinvel").start}

    def batch_observation(self, b):
        return collections.OrderedDict(position=b.qpos[:, 2:], velocity=b.qvel)

    def batch_reward(self, b):
        healthy = rewards.tolerance(b.qpos[:, 2], bounds=HEALTHY_Z, margin=0.1)
        run = rewards.tolerance(b.sensordata[:, b.ids["vel"]], bounds=(RUN_SPEED, float("inf")),
                                margin=RUN_SPEED, value_at_margin=0, sigmoid="linear")
        return healthy * run

    def batch_mode_feature(self, b):
        return b.sensordata[:, b.ids["vel"]][:, None]
