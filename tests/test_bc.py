"""Behaviour cloning: the loss by hand, one step, the split, early stopping, recovery of a known
linear-Gaussian expert, determinism, and BC beating the random policy on reacher1."""

import math
import time

import numpy as np
import pytest
import torch
from scipy import stats

from dc_lesson.algorithms import bc
from dc_lesson import data
from dc_lesson.data import rollout
from dc_lesson.nn.policies import GaussianPolicy, load_policy, save_policy
from dc_lesson.algorithms.ppo import PPOConfig




# A known expert: a = W s + b + 0.1 noise, on states far from zero mean and unit scale (so the
# normaliser matters), in 20 "episodes" of 200 independent states.
W = np.array([[0.5, -0.3, 0.2, 0.1], [-0.2, 0.4, 0.0, -0.15]])
B = np.array([0.3, -0.2])
LOC, SCALE, NOISE = np.array([1.0, -2.0, 0.0, 5.0]), np.array([0.5, 2.0, 1.0, 3.0]), 0.1


def linear_episodes(n_episodes, length, seed):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n_episodes):
        s = LOC + SCALE * rng.normal(size=(length, 4))
        a = s @ W.T + B + NOISE * rng.normal(size=(length, 2))
        out.append((s.astype(np.float32), a.astype(np.float32)))
    return out


def _assert_same_state(a, b):
    sa, sb = a.state_dict(), b.state_dict()
    assert sa.keys() == sb.keys()
    for k in sa:
        assert torch.equal(sa[k], sb[k]), k


# -- the loss and one step -----------------------------------------------------------------------

def test_bc_loss_matches_the_gaussian_negative_log_likelihood_by_hand():
    policy = GaussianPolicy(3, 2, hidden=())
    with torch.no_grad():   # mean(s) = 0, sigma = 0.5 in both dimensions
        policy.mean_net[0].weight.zero_()
        policy.mean_net[0].bias.zero_()
        policy.log_std.fill_(math.log(0.5))
    obs = torch.randn(5, 3)
    act = torch.tensor([[0.1, -0.2], [0.0, 0.3], [0.5, 0.5], [-1.0, 0.0], [0.2, 0.2]])
    terms = bc.bc_loss(policy, obs, act)
    per_pair = (act ** 2 / (2 * 0.25) + math.log(0.5) + 0.5 * math.log(2 * math.pi)).sum(1)
    assert torch.allclose(terms["nll"], per_pair.mean())
    assert torch.allclose(terms["mse"], (act ** 2).mean())
    assert torch.allclose(terms["log_std"], torch.tensor(math.log(0.5)))
    assert terms["nll"].requires_grad and not terms["mse"].requires_grad


def test_bc_step_takes_one_step_and_lowers_the_batch_loss():
    torch.manual_seed(0)
    policy = GaussianPolicy(4, 2, hidden=(16,))
    optimizer = torch.optim.SGD(policy.parameters(), lr=1e-2)
    obs, act = torch.randn(64, 4), torch.randn(64, 2) * 0.3
    before = {k: v.clone() for k, v in policy.state_dict().items()}
    nll0 = float(bc.bc_loss(policy, obs, act)["nll"].detach())
    out = bc.bc_step(policy, optimizer, obs, act)
    assert set(out) == {"nll", "mse", "log_std", "grad_norm"}
    assert out["nll"] == pytest.approx(nll0)          # the terms are from before the step
    assert out["grad_norm"] > 0
    assert any(not torch.equal(before[k], v) for k, v in policy.state_dict().items())
    assert float(bc.bc_loss(policy, obs, act)["nll"].detach()) < nll0


# -- the split, the normaliser, early stopping ---------------------------------------------------

def test_split_is_by_whole_episodes_seeded_and_thirty_percent():
    train, val = bc.split_episodes(25, 0.3, seed=1)
    assert len(val) == 8 and len(train) == 17     # round(7.5) = 8
    assert set(train) | set(val) == set(range(25)) and not set(train) & set(val)
    again = bc.split_episodes(25, 0.3, seed=1)
    assert np.array_equal(train, again[0]) and np.array_equal(val, again[1])
    assert not np.array_equal(val, bc.split_episodes(25, 0.3, seed=2)[1])
    assert len(bc.split_episodes(4, 0.3, seed=0)[1]) == 1    # the paper's smallest subset
    assert len(bc.split_episodes(5, 0.0, seed=0)[1]) == 0
    with pytest.raises(ValueError, match="keep one for training"):
        bc.split_episodes(1, 0.3, seed=0)


def test_normaliser_is_fitted_on_training_episodes_only():
    eps = linear_episodes(10, 50, seed=3)
    policy, _ = bc.train_bc(eps, bc.BCConfig(epochs=1, hidden=(8,)), progress=False)
    train_idx, val_idx = policy.meta["train_episodes"], policy.meta["val_episodes"]
    assert len(val_idx) == 3 and sorted(train_idx + val_idx) == list(range(10))
    train_obs = np.concatenate([eps[i][0] for i in train_idx]).astype(np.float64)
    np.testing.assert_allclose(policy.obs_norm.mean.numpy(), train_obs.mean(0), rtol=1e-6)
    np.testing.assert_allclose(policy.obs_norm.var.numpy(), train_obs.var(0), rtol=1e-5)


def test_early_stopping_keeps_the_best_validation_parameters():
    # Few pairs and a wide network overfit within a few dozen epochs.
    eps = linear_episodes(6, 30, seed=4)
    config = bc.BCConfig(epochs=400, patience=5, hidden=(64, 64), lr=1e-2, batch_size=32)
    policy, log = bc.train_bc(eps, config, progress=False)
    val_nll = [row["val_nll"] for row in log]
    best = int(np.argmin(val_nll))
    assert len(log) < config.epochs, "training should have stopped early"
    assert policy.meta["best_epoch"] == best + 1 == log[-1]["best_epoch"]
    assert len(log) == best + 1 + config.patience
    val_obs = np.concatenate([eps[i][0] for i in policy.meta["val_episodes"]])
    val_act = np.concatenate([eps[i][1] for i in policy.meta["val_episodes"]])
    assert bc.evaluate(policy, torch.from_numpy(val_obs),
                       torch.from_numpy(val_act))["nll"] == pytest.approx(val_nll[best])
    for key in ("train_nll", "val_nll", "train_mse", "val_mse", "step_nll", "log_std",
                "grad_norm", "best_epoch", "seconds"):
        assert key in log[0]


# -- what BC learns ------------------------------------------------------------------------------

def test_bc_recovers_a_linear_gaussian_expert():
    """With no hidden layer the policy is linear-Gaussian, like the expert: on held-out states
    its mean action must be within RMS 0.015 of W s + b (the statistical error with 2800
    training pairs is about 0.1 * sqrt(5 / 2800) = 0.004), and its std within 10% of 0.1."""
    eps = linear_episodes(20, 200, seed=0)
    config = bc.BCConfig(hidden=(), lr=1e-2, epochs=300, patience=20)
    policy, log = bc.train_bc(eps, config, progress=False)
    s = (LOC + SCALE * np.random.default_rng(99).normal(size=(2000, 4))).astype(np.float32)
    with torch.no_grad():
        mean = policy(torch.from_numpy(s)).numpy()
    err = mean - (s @ W.T + B)
    assert np.sqrt(np.mean(err ** 2)) < 0.015
    assert np.abs(err).max() < 0.05
    np.testing.assert_allclose(policy.log_std.exp().detach().numpy(), NOISE, rtol=0.1)
    # The validation NLL approaches the noise's entropy: 2 * (log(0.1) + 0.5 log(2 pi e)).
    entropy = 2 * (math.log(NOISE) + 0.5 * math.log(2 * math.pi * math.e))
    assert min(row["val_nll"] for row in log) == pytest.approx(entropy, abs=0.05)


def test_same_seed_same_policy_to_the_last_digit(tmp_path):
    demos = data.load_demos("reacher1", n_trajectories=4)
    config = bc.BCConfig(epochs=3, seed=5)
    a, log_a = bc.train_bc(demos, config, progress=False)
    b, log_b = bc.train_bc(demos, config, progress=False)
    _assert_same_state(a, b)
    strip = lambda log: [{k: v for k, v in r.items() if k != "seconds"} for r in log]  # noqa
    assert strip(log_a) == strip(log_b)
    c, _ = bc.train_bc(demos, bc.BCConfig(epochs=3, seed=6), progress=False)
    assert not torch.equal(a.log_std, c.log_std) or not torch.equal(
        a.mean_net[0].weight, c.mean_net[0].weight)
    # The policy file keeps it exactly, with the BC metadata.
    loaded = load_policy(save_policy(a, tmp_path / "bc.pt", meta=a.meta))
    _assert_same_state(a, loaded)
    assert loaded.meta["algorithm"] == "bc" and loaded.meta["config"]["seed"] == 5


def test_bc_policy_has_ppos_architecture():
    """So that ``ppo.train(task, policy=bc_policy)`` and DC can start from it."""
    demos = data.load_demos("cartpole", n_trajectories=2)
    policy, _ = bc.train_bc(demos, bc.BCConfig(epochs=1), progress=False)
    p = PPOConfig()
    assert policy.config() == GaussianPolicy(5, 1, p.hidden, log_std_init=p.log_std_init,
                                             norm_obs=p.norm_obs).config()


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="at least one episode"):
        bc.train_bc([], progress=False)
    with pytest.raises(ValueError, match="same T"):
        bc.train_bc([(np.zeros((5, 3)), np.zeros((4, 2)))], progress=False)
    with pytest.raises(ValueError, match="NaN"):
        bc.train_bc([(np.full((5, 3), np.nan), np.zeros((5, 2)))] * 3, progress=False)
    with pytest.raises(ValueError, match="disagree"):
        bc.train_bc([(np.zeros((5, 3)), np.zeros((5, 2))), (np.zeros((5, 4)), np.zeros((5, 2)))],
                    progress=False)
    with pytest.raises(ValueError, match="keep one for training"):
        bc.train_bc(linear_episodes(1, 10, 0), progress=False)
    with pytest.raises(ValueError, match="val_fraction"):
        bc.BCConfig(val_fraction=1.0)
    with pytest.raises(ValueError, match="patience"):
        bc.BCConfig(patience=0)


# -- BC against the random policy on a real task -------------------------------------------------

MIN_GAIN = 300.0   # BC's mean return must beat the random policy's by this much (of 1000)


def test_bc_beats_the_random_policy_on_reacher1():
    """Ten demonstrations, a short BC run, then 10 evaluation episodes from initial states the
    demonstrations did not start from.  BC's returns must be larger than the random policy's
    in a one-sided permutation test (difference of means, p < 0.05) and by MIN_GAIN."""
    start = time.perf_counter()
    demos = data.load_demos("reacher1", n_trajectories=10)
    policy, log = bc.train_bc(demos, bc.BCConfig(epochs=40, patience=10), progress=False)
    trained = time.perf_counter()
    bc_returns = rollout.returns(rollout.collect("reacher1", policy, 10, seed=100))
    random_returns = rollout.returns(rollout.collect(
        "reacher1", rollout.RandomPolicy("reacher1", seed=100), 10, seed=100))
    wall = time.perf_counter() - start
    test = stats.permutation_test((bc_returns, random_returns),
                                  lambda x, y, axis: x.mean(axis) - y.mean(axis),
                                  permutation_type="independent", alternative="greater",
                                  n_resamples=9999, vectorized=True, rng=0)
    gain = bc_returns.mean() - random_returns.mean()
    print(f"\nreacher1 BC: returns {bc_returns.tolist()} (mean {bc_returns.mean():.1f}); random "
          f"{random_returns.tolist()} (mean {random_returns.mean():.1f}); gain {gain:.1f}; "
          f"p = {test.pvalue:.5f}; best epoch {policy.meta['best_epoch']} of {len(log)}; "
          f"training {trained - start:.1f} s, all {wall:.1f} s")
    assert test.pvalue < 0.05
    assert gain >= MIN_GAIN


def test_warm_start_keeps_bcs_mean_and_resets_only_the_log_std():
    from dc_lesson.algorithms import bc
    policy, demos, log = bc.warm_start("reacher1", 3, seed=0, max_epochs=2)
    plain, _ = bc.train_bc(demos, bc.BCConfig(epochs=2, seed=0), progress=False)
    obs = torch.from_numpy(demos.trajectories[0].observations[:50].copy())
    assert torch.equal(policy.distribution(obs).mean, plain.distribution(obs).mean)
    assert torch.all(policy.log_std == bc.WARM_START_LOG_STD)
    assert not torch.all(plain.log_std == bc.WARM_START_LOG_STD)


def test_bc_on_every_demo_stops_on_the_other_demonstrations():
    """stop_on_others: all 18 given episodes are trained on; the 7 others of the task (never
    trained on) decide the early stop."""
    import dataclasses as dc

    from dc_lesson import algorithms
    demos = data.load_demos("reacher1", n_trajectories=18)
    cfg = dc.replace(bc.BCConfig(epochs=3, seed=0), val_fraction=0.0, stop_on_others=True)
    res = algorithms.get("bc").train("reacher1", demos, cfg, progress=False)
    meta = res.policy.meta
    assert meta["train_episodes"] == list(range(18))      # every given episode trained on
    assert len(meta["val_episodes"]) == 25 - 18            # the others validated on
    assert all(np.isfinite(r["val_nll"]) for r in res.log)
    with pytest.raises(ValueError, match="val_fraction=0"):
        algorithms.get("bc").train("reacher1", demos, dc.replace(cfg, val_fraction=0.3),
                                   progress=False)
