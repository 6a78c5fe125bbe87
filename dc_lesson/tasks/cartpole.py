"""``cartpole``: dm_control's cartpole with the balance task (the paper's CartPole-v0).

Gym's CartPole-v0 has a discrete push left/right and ends when the pole passes 12 degrees; the
port keeps dm_control's continuous force, its smooth reward in [0, 1] (upright, centred, small
control, small velocity) and a fixed horizon of 1000 steps of 10 ms, so a random policy scores
well above zero (the pole falls slowly from near-vertical).
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control.suite import cartpole as suite_cartpole

from dc_lesson.tasks.base import PortTask, TaskSpec, gaussian_tolerance, quadratic_tolerance

SPEC = TaskSpec(
    name="cartpole", paper_task="CartPole-v0", base="suite cartpole, balance task",
    obs_dim=5, act_dim=1, horizon=1000, control_timestep=0.01, n_sub_steps=1,
    mode_feature_names=("cart position", "pole angle"),
    differs="continuous force instead of two discrete pushes; no termination when the pole "
            "falls; 1000 steps instead of 200; dm_control's smooth reward")


_XZ, _ZZ = 2, 8   # entries of a flattened rotation matrix (dm_control's 'xz' and 'zz')
_POLE = 2         # body index of the pole (world, cart, pole)


class Physics(suite_cartpole.Physics):
    def pole_angle(self) -> float:
        """Pole angle from vertical in radians (0 is upright)."""
        return float(np.arctan2(self.data.xmat[_POLE, _XZ], self.data.xmat[_POLE, _ZZ]))


class Balance(PortTask, suite_cartpole.Balance):
    """The suite's smooth balance task, computed for a batch of environments."""

    camera = "fixed"
    fields = ("qpos", "qvel", "xmat", "ctrl")

    def __init__(self, random=None):
        super().__init__(swing_up=False, sparse=False, random=random)

    def batch_observation(self, b):
        position = np.concatenate([b.qpos[:, :1], b.xmat[:, _POLE, [_ZZ, _XZ]]], axis=1)
        return collections.OrderedDict(position=position, velocity=b.qvel)

    def batch_reward(self, b):
        # Balance._get_reward(sparse=False), term by term and in the same order; the
        # tolerances as base's equivalents of dm_control's (the same floats, cheaper).
        upright = (b.xmat[:, _POLE:, _ZZ] + 1) / 2
        centered = (1 + gaussian_tolerance(b.qpos[:, 0], margin=2)) / 2
        small_control = quadratic_tolerance(b.ctrl)[:, 0]
        small_control = (4 + small_control) / 5
        small_velocity = gaussian_tolerance(b.qvel[:, 1:], margin=5).min(axis=1)
        small_velocity = (1 + small_velocity) / 2
        return upright.mean(axis=1) * small_control * small_velocity * centered

    def batch_mode_feature(self, b):
        angle = np.arctan2(b.xmat[:, _POLE, _XZ], b.xmat[:, _POLE, _ZZ])
        return np.stack([b.qpos[:, 0], angle], axis=1)
