"""``humanoid``: dm_control's humanoid with the walk task (the paper's Humanoid-v2).

Reward = standing (head height) x upright x small control x moving (horizontal speed of the
centre of mass up to 1 m/s, in any direction), in [0, 1] per step, 1000 steps of 25 ms.
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control.suite import humanoid as suite_humanoid
from dm_control.utils import rewards

from dc_lesson.tasks.base import PortTask, TaskSpec, name_id, sensor_slice

SPEC = TaskSpec(
    name="humanoid", paper_task="Humanoid-v2", base="suite humanoid, walk task",
    obs_dim=67, act_dim=21, horizon=1000, control_timestep=0.025, n_sub_steps=5,
    mode_feature_names=("head height", "horizontal speed"),
    differs="dm_control's 21-actuator humanoid and walk reward (speed 1 m/s in any direction); "
            "Gym's Humanoid-v2 pays forward speed plus an alive bonus and ends on a fall")


class Physics(suite_humanoid.Physics):
    pass


HEAD_INDEX = 21          # head height in the observation (after the 21 joint angles)
FALLEN_HEAD = 0.9        # m: the head of a standing humanoid is at about 1.5 m


def fell(obs: np.ndarray) -> np.ndarray:
    """A fallen humanoid: its head below ``FALLEN_HEAD``. A *training-only* termination
    (SAC's ``terminate="humanoid-fall"``, as Gym's Humanoid ends an episode when the torso
    drops below 1 m): the task never ends early, and a fallen humanoid earns about nothing,
    since the walk reward is multiplied by a standing term of the head's height."""
    return np.asarray(obs)[..., HEAD_INDEX] < FALLEN_HEAD


_ZX, _ZY, _ZZ = 6, 7, 8   # entries of a flattened rotation matrix
_EXTREMITIES = ("left_hand", "left_foot", "right_hand", "right_foot")


class Walk(PortTask, suite_humanoid.Humanoid):
    """The suite's walk task (egocentric features), computed for a batch of environments."""

    camera = "side"
    fields = ("qpos", "qvel", "xpos", "xmat", "sensordata", "ctrl")

    def __init__(self, random=None):
        super().__init__(move_speed=suite_humanoid._WALK_SPEED, pure_state=False, random=random)

    def resolve(self, model):
        vel = sensor_slice(model, "torso_subtreelinvel")
        return {"torso": name_id(model, "body", "torso"), "head": name_id(model, "body", "head"),
                "limbs": [name_id(model, "body", n) for n in _EXTREMITIES],
                "vel": vel}

    def _com_velocity(self, b):
        return b.sensordata[:, b.ids["vel"]]

    def batch_observation(self, b):
        i = b.ids
        torso_frame = b.xmat[:, i["torso"]].reshape(-1, 3, 3)
        to_limbs = b.xpos[:, i["limbs"]] - b.xpos[:, i["torso"]][:, None]     # (B, 4, 3)
        # torso_to_limb.dot(torso_frame) for each limb, as the suite writes it.
        extremities = np.matmul(to_limbs, torso_frame).reshape(len(b.qpos), -1)
        return collections.OrderedDict(
            joint_angles=b.qpos[:, 7:], head_height=b.xpos[:, i["head"], 2],
            extremities=extremities,
            torso_vertical=b.xmat[:, i["torso"]][:, [_ZX, _ZY, _ZZ]],
            com_velocity=self._com_velocity(b), velocity=b.qvel)

    def batch_reward(self, b):
        # Humanoid.get_reward with move_speed > 0, term by term.
        stand_height = suite_humanoid._STAND_HEIGHT
        standing = rewards.tolerance(b.xpos[:, b.ids["head"], 2],
                                     bounds=(stand_height, float("inf")), margin=stand_height / 4)
        upright = rewards.tolerance(b.xmat[:, b.ids["torso"], _ZZ], bounds=(0.9, float("inf")),
                                    sigmoid="linear", margin=1.9, value_at_margin=0)
        stand_reward = standing * upright
        small_control = rewards.tolerance(b.ctrl, margin=1, value_at_margin=0,
                                          sigmoid="quadratic").mean(axis=1)
        small_control = (4 + small_control) / 5
        com_speed = np.linalg.norm(self._com_velocity(b)[:, [0, 1]], axis=1)
        move = rewards.tolerance(com_speed, bounds=(self._move_speed, float("inf")),
                                 margin=self._move_speed, value_at_margin=0, sigmoid="linear")
        move = (5 * move + 1) / 6
        return small_control * stand_reward * move

    def batch_mode_feature(self, b):
        speed = np.linalg.norm(self._com_velocity(b)[:, [0, 1]], axis=1)
        return np.stack([b.xpos[:, b.ids["head"], 2], speed], axis=1)
