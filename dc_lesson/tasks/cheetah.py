"""``halfcheetah`` and ``halfcheetah2``: dm_control's cheetah (the paper's HalfCheetah tasks).

``halfcheetah`` is the suite's run task: reward = forward speed / 10 m/s, clipped to [0, 1].

``halfcheetah2`` is the paper's two-direction variant: the reward is the *absolute* speed
/ 10 m/s, so running forward and running backward are equally good; the direction is not in the
observation, so which way an episode runs is a property of the policy (two behaviour modes).
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control.suite import cheetah as suite_cheetah

from dc_lesson.tasks.base import (NO_MODE, PortTask, TaskSpec, linear_tolerance_above,
                                  sensor_slice)

_RUN_SPEED = suite_cheetah._RUN_SPEED  # 10 m/s
ARRIVE_SPEED = 1.0   # m/s: an episode "runs" in a direction at a mean speed of at least this

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


class Run(PortTask, suite_cheetah.Cheetah):
    """The suite's run task, computed for a batch of environments."""

    camera = "side"
    fields = ("qpos", "qvel", "sensordata")

    def resolve(self, model):
        return {"vel": sensor_slice(model, "torso_subtreelinvel").start}

    def batch_observation(self, b):
        return collections.OrderedDict(position=b.qpos[:, 1:], velocity=b.qvel)

    def _speed(self, b):
        return b.sensordata[:, b.ids["vel"]]

    def batch_reward(self, b):
        # the suite's tolerance(speed, bounds=(10, inf), margin=10, value_at_margin=0,
        # sigmoid="linear"), as base's equivalent (the same floats, cheaper)
        return linear_tolerance_above(self._speed(b), _RUN_SPEED, _RUN_SPEED)

    def batch_mode_feature(self, b):
        return self._speed(b)[:, None]


class RunEitherWay(Run):
    """Rewards running speed in either direction."""

    def batch_reward(self, b):
        return linear_tolerance_above(np.abs(self._speed(b)), _RUN_SPEED, _RUN_SPEED)

    def classify_mode(self, features):
        # 0 = forward, 1 = backward, by the sign of the forward speed.
        return (np.asarray(features)[..., 0] < 0).astype(np.int64)

    def episode_mode(self, mode_features):
        """The direction the cheetah actually ran: forward (0) if its mean forward speed over
        the second half is at least ``ARRIVE_SPEED``, backward (1) if at most minus that, else
        ``NO_MODE`` (standing, rocking, or turning back and forth)."""
        v = float(np.mean(np.asarray(mode_features)[len(mode_features) // 2:, 0]))
        return 0 if v >= ARRIVE_SPEED else 1 if v <= -ARRIVE_SPEED else NO_MODE
