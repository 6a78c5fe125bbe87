"""``halfcheetah`` and ``halfcheetah2``: dm_control's cheetah (the paper's HalfCheetah tasks).

``halfcheetah`` is the suite's run task: reward = forward speed / 10 m/s, clipped to [0, 1].

``halfcheetah2`` is the paper's two-direction variant: the reward is the *absolute* speed
/ 10 m/s, so running forward and running backward are equally good; the direction is not in the
observation, so which way an episode runs is a property of the policy (two behaviour modes).
"""

from __future__ import annotations

import numpy as np
from dm_control.suite import cheetah as suite_cheetah
from dm_control.utils import rewards

from dc_lesson.tasks.base import PortTask, TaskSpec

_RUN_SPEED = suite_cheetah._RUN_SPEED  # 10 m/s

SPEC = TaskSpec(
    name="halfcheetah", paper_task="HalfCheetah-v2", base="suite cheetah, run task",
    obs_dim=17, act_dim=6, horizon=1000, control_timestep=0.01, n_sub_steps=1,
    mode_feature_names=("forward speed",),
    differs="dm_control's cheetah model; reward is forward speed / 10 m/s clipped to [0, 1] "
            "(Gym pays speed minus a control cost, unclipped)")

SPEC2 = TaskSpec(
    name="halfcheetah2", paper_task="HalfCheetah2 (two running directions)",
    base="suite cheetah, reward on absolute speed",
    obs_dim=17, act_dim=6, horizon=1000, control_timestep=0.01, n_sub_steps=1,
    mode_feature_names=("forward speed",), modes=("forward", "backward"),
    differs="reward is |speed| / 10 m/s clipped to [0, 1], so both directions are rewarded "
            "alike; the direction is not observed")


class Physics(suite_cheetah.Physics):
    pass


class Run(suite_cheetah.Cheetah, PortTask):
    camera = "side"

    def mode_feature(self, physics):
        return np.array([physics.speed()])


class RunEitherWay(Run):
    """Rewards running speed in either direction."""

    def get_reward(self, physics):
        return rewards.tolerance(abs(physics.speed()), bounds=(_RUN_SPEED, float("inf")),
                                 margin=_RUN_SPEED, value_at_margin=0, sigmoid="linear")

    def classify_mode(self, features):
        # 0 = forward, 1 = backward, by the sign of the forward speed.
        return (np.asarray(features)[..., 0] < 0).astype(np.int64)
