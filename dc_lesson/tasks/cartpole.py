"""``cartpole``: dm_control's cartpole with the balance task (the paper's CartPole-v0).

Gym's CartPole-v0 has a discrete push left/right and ends when the pole passes 12 degrees; the
port keeps dm_control's continuous force, its smooth reward in [0, 1] (upright, centred, small
control, small velocity) and a fixed horizon of 1000 steps of 10 ms, so a random policy scores
well above zero (the pole falls slowly from near-vertical).
"""

from __future__ import annotations

import numpy as np
from dm_control.suite import cartpole as suite_cartpole

from dc_lesson.tasks.base import PortTask, TaskSpec

SPEC = TaskSpec(
    name="cartpole", paper_task="CartPole-v0", base="suite cartpole, balance task",
    obs_dim=5, act_dim=1, horizon=1000, control_timestep=0.01, n_sub_steps=1,
    mode_feature_names=("cart position", "pole angle"),
    differs="continuous force instead of two discrete pushes; no termination when the pole "
            "falls; 1000 steps instead of 200; dm_control's smooth reward")


class Physics(suite_cartpole.Physics):
    def pole_angle(self) -> float:
        """Pole angle from vertical in radians (0 is upright)."""
        return float(np.arctan2(self.data.xmat[2, 2], self.data.xmat[2, 8]))


class Balance(suite_cartpole.Balance, PortTask):
    camera = "fixed"

    def __init__(self, random=None):
        super().__init__(swing_up=False, sparse=False, random=random)

    def mode_feature(self, physics):
        return np.array([physics.cart_position(), physics.pole_angle()])
