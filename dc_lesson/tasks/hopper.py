"""``hopper``: Gym's Hopper model and objective as a custom dm_control domain (the paper's Hopper).

The model is Gymnasium's ``hopper.xml`` (Hopper-v5; ``assets/hopper.xml``, MIT-licensed): a
torso, thigh, leg and foot of capsules in the x-z plane, three motors of gear 200, RK4 at 2 ms
and 4 physics steps per 8 ms control step (Gym's frame skip), 1000 control steps per episode
(8 s, Gym's time limit).  The observation is Gym's: the joint positions without the forward
position (``qpos[1:]``: torso height, torso angle, three joint angles) and all six velocities
clipped to +-10 (11 numbers).  Episodes start as Gym's: the model's standing pose at rest plus
uniform noise of +-``INIT_NOISE`` on every position and velocity.

The objective is Gym's, divided by a constant so that a step pays at most 1::

    reward = healthy * clip((1 + v - 1e-3 |a|^2) / (1 + RUN_SPEED), 0, 1),   RUN_SPEED = 3 m/s

with ``v`` the forward velocity of the centre of mass and ``a`` the applied action.  It is
Gym's ``healthy_reward + forward_reward - ctrl_cost`` over 4, so every trade between staying
up, speed and effort is Gym's: standing still pays 0.25 per step (250 per episode), hopping at
1 m/s pays 0.5 and at 3 m/s (about a good Gym hopper's speed) or faster the full 1.  ``healthy``
is Gym's test: torso height above 0.7 m, torso angle within +-0.2 rad and every other position
and velocity within +-100.

A fall does not end the episode (every episode has the same 1000 steps): an unhealthy step
simply pays nothing, and once fallen a hopper earns nothing until it is healthy again.  Getting
up is allowed, but with the torso to be within 0.2 rad of vertical at 0.7 m it is all but
impossible from lying down, so a fall costs, as in Gym, about the rest of the episode.

Differences from Gym: the speed is the centre of mass's at the end of the control step (from a
``subtreelinvel`` sensor; Gym differences the torso's x position over the step), the reward is
Gym's over 4 and clipped to [0, 1], and there is no termination.
"""

from __future__ import annotations

import collections
import pathlib

import numpy as np
from dm_control import mujoco

from dc_lesson.tasks.base import PortTask, TaskSpec, name_id, sensor_slice

INIT_NOISE = 5e-3            # Gym's reset_noise_scale
RUN_SPEED = 3.0              # m/s: forward speed at which a healthy step pays in full
HEALTHY_REWARD = 1.0         # Gym's healthy_reward (the reward's scale: 1 + RUN_SPEED)
CTRL_COST = 1e-3             # Gym's ctrl_cost_weight
HEALTHY_Z = 0.7              # m: Gym's healthy_z_range lower end (no upper end)
HEALTHY_ANGLE = 0.2          # rad: Gym's healthy_angle_range
HEALTHY_STATE = 100.0        # Gym's healthy_state_range for qpos[2:] and qvel
VEL_CLIP = 10.0              # Gym clips the observed velocities to +-10

SPEC = TaskSpec(
    name="hopper", paper_task="Hopper-v2", base="Gym's hopper model as a custom dm_control domain",
    obs_dim=11, act_dim=3, horizon=1000, control_timestep=0.008, n_sub_steps=4,
    mode_feature_names=("torso height", "forward speed"),
    differs="Gym's model, observation and objective (alive bonus + forward speed - control "
            "cost) divided by 4 and clipped to [0, 1] per step; an unhealthy step pays 0 "
            "and there is no termination; centre-of-mass speed")


def get_model_and_assets():
    return (pathlib.Path(__file__).parent / "assets" / "hopper.xml").read_text(), {}


class Physics(mujoco.Physics):
    def height(self) -> float:
        """Torso height (Gym's z, ``qpos[1]``)."""
        return float(self.data.qpos[1])

    def speed(self) -> float:
        """Forward (x) velocity of the hopper's centre of mass."""
        return float(self.named.data.sensordata["torso_subtreelinvel"][0])


def healthy(qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """Gym's ``is_healthy`` for a batch: (B,) bool."""
    z, angle = qpos[:, 1], qpos[:, 2]
    state = np.concatenate([qpos[:, 2:], qvel], axis=1)
    return ((z > HEALTHY_Z) & (np.abs(angle) < HEALTHY_ANGLE)
            & np.all(np.abs(state) < HEALTHY_STATE, axis=1))


class Hop(PortTask):
    """Hop forward from a standing start, computed for a batch of environments."""

    camera = "track"
    fields = ("qpos", "qvel", "ctrl", "sensordata")

    def resolve(self, model):
        name_id(model, "body", "torso")
        return {"vel": sensor_slice(model, "torso_subtreelinvel").start}

    def initialize_episode(self, physics):
        nq, nv = physics.model.nq, physics.model.nv
        physics.data.qpos[:] = physics.model.qpos0 + self.random.uniform(-INIT_NOISE,
                                                                         INIT_NOISE, nq)
        physics.data.qvel[:] = self.random.uniform(-INIT_NOISE, INIT_NOISE, nv)
        super().initialize_episode(physics)

    def batch_observation(self, b):
        return collections.OrderedDict(position=b.qpos[:, 1:],
                                       velocity=np.clip(b.qvel, -VEL_CLIP, VEL_CLIP))

    def batch_reward(self, b):
        speed = b.sensordata[:, b.ids["vel"]]
        gym = HEALTHY_REWARD + speed - CTRL_COST * np.sum(b.ctrl ** 2, axis=1)
        return healthy(b.qpos, b.qvel) * np.clip(gym / (HEALTHY_REWARD + RUN_SPEED), 0.0, 1.0)

    def batch_mode_feature(self, b):
        return np.stack([b.qpos[:, 1], b.sensordata[:, b.ids["vel"]]], axis=1)


def fell(obs: np.ndarray) -> np.ndarray:
    """Gym's unhealthy hopper, read from the observation (torso height ``obs[0]``, angle
    ``obs[1]``): below 0.7 m or tilted more than 0.2 rad.  A *training-only* termination
    (PPO's ``terminate="hopper-fall"``): the task itself never ends an episode early, it pays
    an unhealthy step nothing.  (Gym's third test, every position and velocity within +-100,
    needs the unclipped velocities; a hopper does not get there before it falls.)"""
    obs = np.asarray(obs)
    return (obs[..., 0] <= HEALTHY_Z) | (np.abs(obs[..., 1]) >= HEALTHY_ANGLE)
