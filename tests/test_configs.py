"""Every configuration refuses, at construction, a value of the wrong type or out of range,
naming the class and the field (issue 19: PPOConfig(lr=-1) and lr=nan were accepted,
n_envs=0 gave a ZeroDivisionError)."""

import math

import numpy as np
import pytest

from dc_lesson.algorithms.bc import BCConfig
from dc_lesson.algorithms.dc import DCConfig
from dc_lesson.algorithms.gail import GAILConfig
from dc_lesson.algorithms.ppo import PPOConfig
from dc_lesson.checks import ConfigError
from dc_lesson.density.softflow import SoftFlowConfig
from dc_lesson.experts.planner import PlannerConfig

NAN, INF = float("nan"), float("inf")

CASES = [
    (PPOConfig, "lr", -1.0, "must be positive"),
    (PPOConfig, "lr", 0.0, "must be positive"),
    (PPOConfig, "lr", NAN, "must be finite"),
    (PPOConfig, "lr", INF, "must be finite"),
    (PPOConfig, "lr", "3e-4", "must be a number"),
    (PPOConfig, "n_envs", 0, "must be positive"),
    (PPOConfig, "n_envs", -2, "must be positive"),
    (PPOConfig, "n_envs", True, "must be a whole number"),
    (PPOConfig, "n_envs", 2.5, "must be a whole number"),
    (PPOConfig, "n_steps", 0, "must be positive"),
    (PPOConfig, "total_steps", -1, "must be positive"),
    (PPOConfig, "gamma", 1.5, "between 0 and 1"),
    (PPOConfig, "ent_coef", -0.1, "zero or more"),
    (PPOConfig, "anneal_lr", 1, "True or False"),
    (PPOConfig, "hidden", (64, 0), "positive whole numbers"),
    (PPOConfig, "target_kl", NAN, "must be finite"),
    (PPOConfig, "seed", -1, "zero or more"),
    (BCConfig, "lr", -1e-3, "must be positive"),
    (BCConfig, "lr", NAN, "must be finite"),
    (BCConfig, "epochs", 0, "must be positive"),
    (BCConfig, "batch_size", True, "must be a whole number"),
    (BCConfig, "weight_decay", -1.0, "zero or more"),
    (BCConfig, "max_grad_norm", 0.0, "must be positive"),
    (GAILConfig, "disc_lr", NAN, "must be finite"),
    (GAILConfig, "disc_lr", -1.0, "must be positive"),
    (GAILConfig, "disc_batch", 0, "must be positive"),
    (GAILConfig, "reward_scale", INF, "must be finite"),
    (GAILConfig, "value_warmup", -1, "zero or more"),
    (DCConfig, "lr", -1.0, "must be positive"),
    (SoftFlowConfig, "step_size", 0.0, "must be positive"),   # DC's and NDI's flows
    (DCConfig, "bc_batch_size", 0, "must be positive"),
    (DCConfig, "loops", True, "must be a whole number"),
    (DCConfig, "iterations", 0, "must be positive"),
    (DCConfig, "rho", 0.0, "must be positive"),
    (SoftFlowConfig, "hidden", (16, -1), "positive whole numbers"),
    (DCConfig, "bc_step", "yes", "True or False"),
    (SoftFlowConfig, "lr", 0.0, "must be positive"),
    (SoftFlowConfig, "lr", NAN, "must be finite"),
    (SoftFlowConfig, "batch_size", 0, "must be positive"),
    (SoftFlowConfig, "iterations", -1, "zero or more"),
    (SoftFlowConfig, "sigma_max", INF, "must be finite"),
    (SoftFlowConfig, "eval_quadrature", 0, "must be positive"),
    (PlannerConfig, "n_samples", 0, "must be positive"),
    (PlannerConfig, "horizon", NAN, "must be finite"),
    (PlannerConfig, "threads", 0, "must be positive"),
    (PlannerConfig, "noise", -0.1, "zero or more"),
]


@pytest.mark.parametrize("cls, field, value, message", CASES,
                         ids=[f"{c.__name__}.{f}={v!r}" for c, f, v, _ in CASES])
def test_bad_field_is_refused_naming_it(cls, field, value, message):
    with pytest.raises(ConfigError) as e:
        cls(**{field: value})
    assert f"{cls.__name__}.{field}" in str(e.value) and message in str(e.value)
    assert isinstance(e.value, ValueError) and isinstance(e.value, TypeError)


def test_numpy_numbers_are_accepted_and_stored_as_python_numbers():
    c = PPOConfig(lr=np.float32(1e-3), n_envs=np.int64(4), n_steps=64, n_minibatches=4,
                  total_steps=256, hidden=[32, np.int64(32)])
    assert type(c.lr) is float and math.isclose(c.lr, 1e-3, rel_tol=1e-6)
    assert type(c.n_envs) is int and c.hidden == (32, 32)
    assert '"n_envs": 4' in c.to_json()


def test_every_default_and_preset_is_valid():
    from dc_lesson import budget
    from dc_lesson.algorithms import ALGORITHMS
    for cls in (PPOConfig, BCConfig, GAILConfig, DCConfig, SoftFlowConfig, PlannerConfig):
        cls()
    for name in ("smoke", "lesson", "paper"):
        for algo in ALGORITHMS.values():
            algo.preset(budget.get(name), 3)


# Issue 42: the four later learners' configs checked no types (a 0-wide layer trained a
# constant policy, an infinite rate gave NaN costs, knn_k=True failed deep in torch).
from dc_lesson.algorithms.dril import DRILConfig   # noqa: E402
from dc_lesson.algorithms.gpril import GPRILConfig   # noqa: E402
from dc_lesson.algorithms.ndi import NDIConfig   # noqa: E402
from dc_lesson.algorithms.pwil import PWILConfig   # noqa: E402

LATER = [
    (DRILConfig, "ensemble_lr", INF, "must be finite"),
    (DRILConfig, "ensemble_lr", NAN, "must be finite"),
    (DRILConfig, "ensemble_epochs", True, "must be a whole number"),
    (DRILConfig, "bc_steps", 2.5, "must be a whole number"),
    (DRILConfig, "quantile", "0.98", "must be a number"),
    (DRILConfig, "seed", -1, "zero or more"),
    (PWILConfig, "alpha", INF, "must be finite"),
    (PWILConfig, "subsampling", True, "must be a whole number"),
    (PWILConfig, "use_actions", 1, "True or False"),
    (PWILConfig, "beta", 0.0, "must be positive"),
    (NDIConfig, "flow_pairs", 0, "must be positive"),
    (NDIConfig, "knn_k", True, "must be a whole number"),
    (NDIConfig, "entropy_coef", NAN, "must be finite"),
    (GPRILConfig, "hidden", (0,), "positive whole numbers"),
    (GPRILConfig, "flow_hidden", (64, -1), "positive whole numbers"),
    (GPRILConfig, "lr", INF, "must be finite"),
    (GPRILConfig, "flow_layers", True, "must be a whole number"),
    (GPRILConfig, "episode_steps", 0, "must be positive"),
    (GPRILConfig, "log_std_init", NAN, "must be finite"),
]


@pytest.mark.parametrize("cls, field, value, message", LATER,
                         ids=[f"{c.__name__}.{f}={v!r}" for c, f, v, _ in LATER])
def test_the_later_learners_configs_refuse_bad_fields_naming_them(cls, field, value, message):
    test_bad_field_is_refused_naming_it(cls, field, value, message)


def test_the_later_learners_defaults_are_valid():
    for cls in (DRILConfig, PWILConfig, NDIConfig, GPRILConfig):
        cls()
