"""``hopper``: dm_control's hopper model with Gym's Hopper-v2 objective (the paper's Hopper).

The suite's own hop task starts the hopper lying in a random orientation and pays nothing
until it hops at speed; no expert we could train on a laptop CPU got past zero on it (PPO,
2 M steps: return 0; predictive-sampling MPC, in ../shared/notes/platform.md: about 10).  So
the port keeps dm_control's model and observation (joint positions, velocities, two foot
touch sensors) and takes Gym's task instead, rescaled to [0, 1] per step:

* start standing, as Gym does: the model's standing pose and zero velocity plus uniform
  noise of +-``INIT_NOISE`` on every position and velocity;
* reward = standing x (1 + 3 x forward) / 4, where standing is the suite's test (torso at
  least 0.6 m above the foot) and forward = clip(speed / 2 m/s, 0, 1).  Like Gym's "alive
  bonus plus forward velocity", standing still pays a quarter and hopping forward at 2 m/s or
  more pays in full;
* 1000 steps of 20 ms, no termination on a fall (a fallen hopper simply earns nothing).
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control.suite import hopper as suite_hopper
from dm_control.utils import rewards

from dc_lesson.tasks.base import PortTask, TaskSpec, name_id, sensor_slice

INIT_NOISE = 0.02
RUN_SPEED = 2.0   # m/s for the full forward term

SPEC = TaskSpec(
    name="hopper", paper_task="Hopper-v2", base="suite hopper model, Gym's objective",
    obs_dim=15, act_dim=4, horizon=1000, control_timestep=0.02, n_sub_steps=4,
    mode_feature_names=("torso height", "forward speed"),
    differs="dm_control's hopper model (4 actuators) and observation; Gym's objective rescaled "
            "to [0, 1] (a quarter for standing, the rest for speed up to 2 m/s) and Gym's "
            "standing start; no termination on a fall")


class Physics(suite_hopper.Physics):
    pass


class Hop(PortTask, suite_hopper.Hopper):
    """Hop forward from a standing start, computed for a batch of environments."""

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

    def initialize_episode(self, physics):
        # Gym's start: the standing pose (the model's qpos0) at rest, plus a little noise.
        nq, nv = physics.model.nq, physics.model.nv
        physics.data.qpos[:] = physics.model.qpos0 + self.random.uniform(-INIT_NOISE,
                                                                         INIT_NOISE, nq)
        physics.data.qvel[:] = self.random.uniform(-INIT_NOISE, INIT_NOISE, nv)
        self._timeout_progress = 0
        PortTask.initialize_episode(self, physics)

    def batch_reward(self, b):
        height, speed = self._height_speed(b)
        standing = rewards.tolerance(height, (suite_hopper._STAND_HEIGHT, 2))
        forward = rewards.tolerance(speed, bounds=(RUN_SPEED, float("inf")), margin=RUN_SPEED,
                                    value_at_margin=0, sigmoid="linear")
        return standing * (1 + 3 * forward) / 4

    def batch_mode_feature(self, b):
        return np.stack(self._height_speed(b), axis=1)
