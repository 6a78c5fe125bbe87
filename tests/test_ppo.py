"""PPO and its policies: GAE and the clipped loss by hand, time-limit bootstrapping, policy
files, determinism, exact resume from a checkpoint, and PPO learning cartpole."""

import dataclasses
import itertools
import math
import time

import numpy as np
import pytest
import torch

from dc_lesson.algorithms import ppo
from dc_lesson.nn.checkpoint import write_checksum
from dc_lesson.nn.policies import (GaussianPolicy, PolicyFileError, StochasticPolicy, ValueNetwork,
                                load_policy, save_policy)
from dc_lesson.data.rollout import RandomPolicy, collect, returns


def _three(r):
    """(policy, value network, log) of a TrainResult."""
    return r.policy, r.models["value"], r.log





# A run small enough for a few seconds: 4 updates of 2 envs x 300 steps, so the fourth update
# crosses the 1000-step horizon (an episode end and a reset) and a checkpoint after the third
# falls mid-episode.
TINY = ppo.PPOConfig(n_envs=2, n_steps=300, n_epochs=2, n_minibatches=4, total_steps=2400,
                     seed=7)
TIMING = {"steps_per_second"}


def _without_timing(log):
    return [{k: v for k, v in row.items() if k not in TIMING} for row in log]


def _assert_same_state(a: torch.nn.Module, b: torch.nn.Module):
    sa, sb = a.state_dict(), b.state_dict()
    assert sa.keys() == sb.keys()
    for k in sa:
        assert torch.equal(sa[k], sb[k]), k


def _assert_same_log(a, b):
    # NaN (no episode ended in a batch) compares equal to NaN here.
    np.testing.assert_equal(_without_timing(a), _without_timing(b))


# -- hand computations ---------------------------------------------------------------------------

def test_gae_matches_a_hand_computation():
    gamma, lam = 0.9, 0.8
    # Column 0: an episode ends (time limit) after step 1, so step 1 bootstraps from the final
    # observation's value (4.0) and step 0's sum stops there.  Column 1: no end.
    rewards = torch.tensor([[1.0, 0.0], [2.0, 0.0], [3.0, 1.0]])
    values = torch.tensor([[0.5, 0.0], [1.0, 0.0], [1.5, 0.0]])
    next_values = torch.tensor([[1.0, 0.0], [4.0, 0.0], [2.0, 0.0]])
    dones = torch.tensor([[False, False], [True, False], [False, False]])
    adv, targets = ppo.compute_gae(rewards, values, next_values, dones, gamma, lam)
    # deltas, column 0: 1 + .9*1 - .5 = 1.4;  2 + .9*4 - 1 = 4.6;  3 + .9*2 - 1.5 = 3.3
    # A2 = 3.3;  A1 = 4.6 (the episode ended);  A0 = 1.4 + .72 * 4.6 = 4.712
    # column 1: deltas 0, 0, 1  ->  A = .72**2, .72, 1
    expected = torch.tensor([[4.712, 0.72 ** 2], [4.6, 0.72], [3.3, 1.0]])
    torch.testing.assert_close(adv, expected)
    torch.testing.assert_close(targets, expected + values)


def test_clipped_surrogate_matches_a_hand_computation():
    ratios = torch.tensor([0.5, 1.0, 1.5, 1.5])
    adv = torch.tensor([1.0, -1.0, 1.0, -1.0])
    old = torch.zeros(4)
    new = ratios.log().clone().requires_grad_(True)
    loss, approx_kl, clip_fraction = ppo.clipped_surrogate(new, old, adv, clip_coef=0.2)
    # per sample min(r A, clip(r) A): 0.5 (r below the clip, but A > 0 keeps the smaller r A),
    # -1, 1.2 (clipped), -1.5 (A < 0: the unclipped r A is smaller)
    assert loss.item() == pytest.approx(-(0.5 - 1.0 + 1.2 - 1.5) / 4)
    assert clip_fraction.item() == pytest.approx(0.75)
    r = ratios.numpy()
    assert approx_kl.item() == pytest.approx(np.mean((r - 1) - np.log(r)), rel=1e-5)
    # Gradient d loss / d log r_i = -A_i r_i / n where unclipped, 0 where the clip is active.
    loss.backward()
    torch.testing.assert_close(new.grad, torch.tensor([-0.125, 0.25, 0.0, 0.375]))


def test_value_loss_clipping_by_hand():
    new, old, target = torch.tensor([2.0, 0.0]), torch.tensor([1.0, 0.5]), torch.tensor([3.0, 1.0])
    assert ppo.value_loss(new, old, target).item() == pytest.approx(0.5 * (1 + 1) / 2)
    # clipped values 1.2 and 0.3: errors 1.8**2 = 3.24 > 1 and .7**2 = .49 < 1
    assert ppo.value_loss(new, old, target, 0.2).item() == pytest.approx(0.5 * (3.24 + 1) / 2)


# -- collection ----------------------------------------------------------------------------------

def test_collect_batch_bootstraps_the_final_observation_at_the_time_limit():
    envs = ppo.EnvBatch("cartpole", 2, seed=0)
    policy, value_fn = GaussianPolicy(5, 1), ValueNetwork(5)
    batch = ppo.collect_batch(envs, policy, value_fn, 1003, torch.Generator().manual_seed(0))
    assert batch.obs.shape == (1003, 2, 5) and batch.actions.shape == (1003, 2, 1)
    assert batch.dones[999].all() and batch.dones.sum() == 2
    # The final observation is kept for the bootstrap; the env went on from a reset one.
    assert not torch.equal(batch.next_obs[999], batch.obs[1000])
    torch.testing.assert_close(batch.next_values[999], value_fn(batch.next_obs[999]))
    torch.testing.assert_close(batch.next_obs[:999], batch.obs[1:1000])
    # Resets draw the next seeds of the stream: episodes 3 and 4 of seed 0.
    from dc_lesson import tasks
    seeds = ppo.SeedStream(0)
    [next(seeds) for _ in range(2)]
    for i in range(2):
        first = tasks.make("cartpole").reset(seed=next(seeds))
        np.testing.assert_array_equal(batch.obs[1000, i].numpy(), first)
    np.testing.assert_allclose(batch.episode_returns, batch.env_rewards[:1000].sum(0).numpy(),
                               rtol=1e-5)
    # Stored actions are the raw samples (some outside [-1, 1]); log-probs are theirs.
    torch.testing.assert_close(batch.logprobs[:5],
                               policy.log_prob(batch.obs[:5], batch.actions[:5]))


def _trained_pair(seed: int = 0):
    """A policy and value network with fitted normalisers and moved weights."""
    torch.manual_seed(seed)
    pi, v = GaussianPolicy(6, 3, norm_obs=True), ValueNetwork(6, norm_obs=True)
    obs = torch.randn(500, 6) * 3 + 1
    pi.update_obs_norm(obs)
    v.update_obs_norm(obs)
    with torch.no_grad():
        pi.log_std.copy_(torch.tensor([-0.3, -1.2, 0.4]))
    return pi, v


def test_log_prob_entropy_equals_torch_normal_bit_for_bit_values_and_gradients():
    """PPO's minibatch step reads the Gaussian's terms without building a Normal; a
    reordered formula (or a second exp of log_std) would differ in the last bits and change
    every stored PPO-based cell."""
    pi, _ = _trained_pair()
    obs, act = torch.randn(64, 6) * 3, torch.randn(64, 3)

    def grads(loss):
        pi.zero_grad()
        loss.backward()
        return [p.grad.clone() for p in pi.parameters()]

    dist = pi.distribution(obs)
    ref_logp, ref_ent = dist.log_prob(act).sum(-1), dist.entropy().sum(-1)
    ref = grads((ref_logp * torch.linspace(-1, 1, 64)).mean() - 0.1 * ref_ent.mean())
    logp, ent = pi.log_prob_entropy(pi.normalise(obs), act)
    new = grads((logp * torch.linspace(-1, 1, 64)).mean() - 0.1 * ent.mean())
    assert torch.equal(logp, ref_logp) and torch.equal(ent, ref_ent)
    assert all(torch.equal(a, b) for a, b in zip(ref, new))


def _update_before_the_change(policy, value_fn, optimizer, batch, config, generator,
                              extra_loss=None):
    """``ppo_update``'s minibatch loop as it was before it normalised the batch once
    (commit 1a1c022): index every tensor per minibatch, build a Normal per step."""
    from dc_lesson.nn import fast
    obs = batch.obs.reshape(-1, batch.obs.shape[-1])
    actions = batch.actions.reshape(-1, batch.actions.shape[-1])
    old_logp, old_values = batch.logprobs.reshape(-1), batch.values.reshape(-1)
    advantages, targets = batch.advantages.reshape(-1), batch.returns.reshape(-1)
    n = len(obs)
    size = n // config.n_minibatches
    for _ in range(config.n_epochs):
        order = torch.randperm(n, generator=generator)
        for start in range(0, n, size):
            idx = order[start:start + size]
            dist = policy.distribution(obs[idx])
            new_logp = dist.log_prob(actions[idx]).sum(-1)
            entropy = dist.entropy().sum(-1).mean()
            adv = advantages[idx]
            adv = (adv - adv.mean()) / (adv.std() + 1e-8)
            pg_loss, _, _ = ppo.clipped_surrogate(new_logp, old_logp[idx], adv,
                                                  config.clip_coef)
            v_loss = ppo.value_loss(value_fn(obs[idx]), old_values[idx], targets[idx],
                                    config.clip_coef if config.clip_vloss else None)
            loss = pg_loss - config.ent_coef * entropy + config.vf_coef * v_loss
            if extra_loss is not None:
                loss = loss + extra_loss()
            optimizer.zero_grad()
            loss.backward()
            fast.clip_grad_norm_(policy.parameters(), config.max_grad_norm)
            fast.clip_grad_norm_(value_fn.parameters(), config.max_grad_norm)
            optimizer.step()


def test_the_fast_ppo_update_equals_the_reference_path_bit_for_bit():
    """The fast path normalises the batch once and skips Normal; the reference path
    (``fast.disabled()``, as before issue 14) normalises every minibatch and validates a
    Normal. Same parameters and terms to the bit after two epochs, with a different
    result for a different minibatch order (so the comparison can fail)."""
    import copy
    from dc_lesson.nn import fast
    config = ppo.PPOConfig(n_envs=2, n_steps=64, n_epochs=2, n_minibatches=4,
                           total_steps=128, norm_obs=True, ent_coef=0.01)   # entropy's path too
    envs = ppo.EnvBatch("reacher1", 2, seed=0)
    pi, v = GaussianPolicy(envs.spec.obs_dim, envs.spec.act_dim, norm_obs=True), \
        ValueNetwork(envs.spec.obs_dim, norm_obs=True)
    batch = ppo.collect_batch(envs, pi, v, 64, torch.Generator().manual_seed(0))
    pi.update_obs_norm(batch.obs)
    v.update_obs_norm(batch.obs * 2 + 1)   # each network its own statistics
    batch.advantages, batch.returns = ppo.compute_gae(
        batch.env_rewards, batch.values, batch.next_values, batch.dones, config.gamma,
        config.gae_lambda)

    def run(disabled: bool, order_seed: int = 0):
        p, q = copy.deepcopy(pi), copy.deepcopy(v)
        opt = fast.adamw([*p.parameters(), *q.parameters()], lr=3e-3, eps=1e-5)
        with fast.disabled() if disabled else fast.on():
            terms = ppo.ppo_update(p, q, opt, batch, config,
                                   torch.Generator().manual_seed(order_seed))
        return [t.detach().clone() for t in (*p.parameters(), *q.parameters())], terms

    fast_params, fast_terms = run(False)
    ref_params, ref_terms = run(True)
    other_params, _ = run(False, order_seed=1)
    assert fast_terms == ref_terms
    assert all(torch.equal(a, b) for a, b in zip(fast_params, ref_params))
    assert not all(torch.equal(a, b) for a, b in zip(fast_params, other_params))

    # and against the loop as it was, with value clipping and a proximal term on every
    # parameter (DC's consensus ADMM adds one) in play
    config = dataclasses.replace(config, clip_vloss=True)
    out = []
    for update in (ppo.ppo_update, _update_before_the_change):
        p, q = copy.deepcopy(pi), copy.deepcopy(v)
        anchor = [t.detach().clone() + 0.01 for t in p.parameters()]
        opt = fast.adamw([*p.parameters(), *q.parameters()], lr=3e-3, eps=1e-5)
        update(p, q, opt, batch, config, torch.Generator().manual_seed(0),
               extra_loss=lambda: sum(((a - b) ** 2).sum() for a, b in zip(p.parameters(),
                                                                            anchor)))
        out.append([t.detach().clone() for t in (*p.parameters(), *q.parameters())])
    assert all(torch.equal(a, b) for a, b in zip(*out))


def test_seed_stream_continues_episode_seeds():
    from dc_lesson.data.rollout import episode_seeds
    stream = ppo.SeedStream(5)
    np.testing.assert_array_equal([next(stream) for _ in range(100)], episode_seeds(5, 100))


# -- policies and files --------------------------------------------------------------------------

def test_policy_act_sample_and_normaliser():
    torch.manual_seed(0)
    pi = GaussianPolicy(3, 2, norm_obs=True)
    obs = torch.randn(1000, 3) * 5 + 2
    pi.update_obs_norm(obs)
    torch.testing.assert_close(pi.obs_norm.mean.float(), obs.mean(0), atol=1e-4, rtol=0)
    torch.testing.assert_close(pi.obs_norm.var.float(), obs.var(0, unbiased=False), rtol=1e-3,
                               atol=0)
    with torch.no_grad():
        pi.mean_net[-1].bias.fill_(3.0)   # a mean beyond the bounds
    a = pi.act(obs[:4])
    assert a.shape == (4, 2) and torch.all(a == 1.0)
    s1 = pi.sample(obs[:4], torch.Generator().manual_seed(1))
    s2 = pi.sample(obs[:4], torch.Generator().manual_seed(1))
    assert torch.equal(s1, s2) and (s1 > 1).any()   # raw samples are not clipped
    assert pi.log_prob(obs[:4], s1).shape == (4,)
    # A stochastic numpy policy for rollout.collect: seeded, so episodes repeat.
    pi = GaussianPolicy(5, 1)
    x = collect("cartpole", StochasticPolicy(pi, seed=3), 1, max_steps=20)
    y = collect("cartpole", StochasticPolicy(pi, seed=3), 1, max_steps=20)
    z = collect("cartpole", pi, 1, max_steps=20)   # the module itself: the deterministic mean
    assert np.array_equal(x[0].actions, y[0].actions)
    assert not np.array_equal(x[0].actions, z[0].actions)
    with torch.no_grad():
        np.testing.assert_allclose(z[0].actions, pi.act(torch.tensor(
            z[0].observations[:-1])).numpy(), rtol=1e-5)


def test_save_and_load_policy(tmp_path):
    pi = GaussianPolicy(5, 1, hidden=(8,), norm_obs=True)
    pi.update_obs_norm(torch.randn(50, 5))
    path = save_policy(pi, tmp_path / "pi.pt", {"task": "cartpole", "return": 999.0})
    back = load_policy(path)
    _assert_same_state(pi, back)
    assert back.meta == {"task": "cartpole", "return": 999.0}
    obs = torch.randn(3, 5)
    assert torch.equal(pi.act(obs), back.act(obs))
    # no temporary file left behind: the policy and its checksum
    assert sorted(tmp_path.iterdir()) == [path, path.with_name("pi.pt.sha256")]

    (tmp_path / "junk.pt").write_bytes(b"not a torch file")
    with pytest.raises(PolicyFileError, match="junk.pt has no checksum file"):
        load_policy(tmp_path / "junk.pt")
    write_checksum(tmp_path / "junk.pt")   # past the checksum, torch refuses it
    with pytest.raises(PolicyFileError, match="junk.pt.*could not be read"):
        load_policy(tmp_path / "junk.pt")
    torch.save({"weights": torch.zeros(2)}, tmp_path / "foreign.pt")
    write_checksum(tmp_path / "foreign.pt")
    with pytest.raises(PolicyFileError, match="foreign.pt is not a policy file"):
        load_policy(tmp_path / "foreign.pt")
    with pytest.raises(FileNotFoundError, match="missing.pt"):
        load_policy(tmp_path / "missing.pt")
    with pytest.raises(TypeError, match="JSON"):
        save_policy(pi, tmp_path / "x.pt", {"bad": object()})


# -- determinism and resume ----------------------------------------------------------------------

def test_same_config_gives_identical_runs():
    pi_a, v_a, log_a = _three(ppo.train("cartpole", None, TINY, progress=False))
    pi_b, v_b, log_b = _three(ppo.train("cartpole", None, TINY, progress=False))
    _assert_same_state(pi_a, pi_b)
    _assert_same_state(v_a, v_b)
    _assert_same_log(log_a, log_b)
    assert log_a[-1]["n_episodes"] == 2   # the run did cross an episode end
    # A different seed: other numbers from the first update on.
    _, _, log_c = _three(ppo.train("cartpole", None, dataclasses.replace(TINY, seed=8, total_steps=600),
                            progress=False))
    assert log_c[0]["policy_loss"] != log_a[0]["policy_loss"]


class Crash(Exception):
    pass


def test_resumed_run_equals_uninterrupted_run(tmp_path):
    pi_full, v_full, log_full = _three(ppo.train("cartpole", None, TINY, progress=False))

    ckpt = tmp_path / "run.pt"

    def crash_after_third(row, policy):
        if row["update"] == 3:
            raise Crash   # after the checkpoint of update 3 was written

    with pytest.raises(Crash):
        ppo.train("cartpole", None, TINY, progress=False, checkpoint=ckpt, checkpoint_every=3,
                  callback=crash_after_third)
    resumed = []
    pi, v, log = _three(ppo.train("cartpole", None, TINY, progress=False, checkpoint=ckpt,
                           checkpoint_every=3, callback=lambda row, *_: resumed.append(row)))
    assert [row["update"] for row in resumed] == [4]   # it did start from the checkpoint
    _assert_same_state(pi_full, pi)
    _assert_same_state(v_full, v)
    _assert_same_log(log_full, log)

    # Another configuration must not silently continue this run.
    with pytest.raises(PolicyFileError, match="another configuration.*lr"):
        ppo.train("cartpole", None, dataclasses.replace(TINY, lr=1e-3), progress=False,
                  checkpoint=ckpt)


def test_training_only_termination_restarts_a_copy_and_stops_its_bootstrap(tmp_path):
    # The hopper falls within a few hundred steps of random actions: a fallen copy restarts at
    # once with the next episode seed, its last step is terminal (no bootstrap in GAE), and a
    # run resumed from a checkpoint taken after restarts ends exactly where one run does.
    from dc_lesson.experts import trained
    config = ppo.PPOConfig(n_envs=3, n_steps=150, n_epochs=1, n_minibatches=3,
                           total_steps=1800, terminate="hopper-fall", seed=3)
    envs = ppo.EnvBatch("hopper", 3, seed=0, terminate="hopper-fall")
    policy, value_fn = GaussianPolicy(11, 3, (8,)), ValueNetwork(11, (8,))
    batch = ppo.collect_batch(envs, policy, value_fn, 300, torch.Generator().manual_seed(0))
    assert batch.terminals.any() and envs.restarts
    assert torch.equal(batch.terminals & ~batch.dones, torch.zeros_like(batch.dones))
    fell = torch.from_numpy(trained.hopper_fell(batch.next_obs.numpy()))
    assert torch.equal(batch.terminals, fell)
    step, i, seed = envs.restarts[0]   # the copy restarted from the next seed's start state
    assert np.array_equal(batch.obs[step, i].numpy(), ppo.EnvBatch("hopper", 1, 0).venv.envs[0]
                          .reset(seed=seed))
    adv, _ = ppo.compute_gae(batch.env_rewards, batch.values, batch.next_values, batch.dones,
                             0.99, 0.95, batch.terminals)
    t, j = map(int, torch.nonzero(batch.terminals)[0])
    assert adv[t, j] == pytest.approx(float(batch.env_rewards[t, j] - batch.values[t, j]),
                                      abs=1e-6)

    log_full = ppo.train("hopper", None, config, progress=False).log
    ckpt = tmp_path / "run.pt"

    def crash(row, *_):
        if row["update"] == 3:
            raise Crash

    with pytest.raises(Crash):
        ppo.train("hopper", None, config, progress=False, checkpoint=ckpt, checkpoint_every=3,
                  callback=crash)
    log = ppo.train("hopper", None, config, progress=False, checkpoint=ckpt,
                    checkpoint_every=3).log
    _assert_same_log(log_full, log)
    with pytest.raises(ValueError, match="unknown termination"):
        ppo.EnvBatch("hopper", 1, 0, terminate="nope")


def test_reward_fn_replaces_the_environment_reward():
    seen = {}

    def reward_fn(batch):
        seen["shapes"] = (batch.obs.shape, batch.actions.shape, batch.next_obs.shape)
        return -batch.next_obs[..., 0] ** 2   # keep the cart centred

    config = ppo.PPOConfig(n_envs=2, n_steps=32, n_epochs=1, n_minibatches=2, total_steps=64)
    _, _, log = _three(ppo.train("cartpole", None, config, reward_fn=reward_fn, progress=False))
    assert seen["shapes"] == ((32, 2, 5), (32, 2, 1), (32, 2, 5))
    assert log[0]["reward_mean"] <= 0

    with pytest.raises(ValueError, match="reward_fn returned shape"):
        ppo.train("cartpole", None, config, reward_fn=lambda b: torch.zeros(3), progress=False)


# -- PPO learns ----------------------------------------------------------------------------------

def permutation_p_value(treated: np.ndarray, control: np.ndarray) -> float:
    """Exact one-sided permutation test of mean(treated) > mean(control)."""
    pooled = np.concatenate([treated, control])
    n, total = len(treated), pooled.sum()
    observed = treated.mean() - control.mean()
    groups = np.array(list(itertools.combinations(range(len(pooled)), n)))
    sums = pooled[groups].sum(1)
    diffs = sums / n - (total - sums) / (len(pooled) - n)
    return float(np.mean(diffs >= observed - 1e-9))


# Settings that balance the pole within this budget (80k steps, ~30-40 s on a 2-core machine;
# 6 of 6 seeds reached 988-1000 deterministic return): CleanRL's defaults with a larger
# learning rate (3e-3, annealed), 8 minibatches per epoch, a shorter discount (0.98) and no
# observation normaliser (with it, only 3 of 6 seeds balanced in 80k steps; the others scored
# 480-570).
LEARN = ppo.PPOConfig(n_envs=8, n_steps=250, n_epochs=10, n_minibatches=8, lr=3e-3,
                      gamma=0.98, norm_obs=False, total_steps=80_000, seed=0)
MIN_GAIN = 300.0   # return over the random policy's (~340), on the 0..1000 scale


def test_ppo_learns_cartpole():
    start = time.perf_counter()
    policy, _, log = _three(ppo.train("cartpole", None, LEARN, progress=False))
    train_seconds = time.perf_counter() - start
    trained = returns(collect("cartpole", policy, 10, seed=2024))
    random = returns(collect("cartpole", RandomPolicy("cartpole", seed=0), 10, seed=2024))
    p = permutation_p_value(trained, random)
    print(f"\nPPO cartpole: {LEARN.total_steps} steps in {train_seconds:.0f} s; trained "
          f"{trained.mean():.0f} +- {trained.std():.0f}, random {random.mean():.0f} +- "
          f"{random.std():.0f}, one-sided permutation p = {p:.2g}")
    assert all(math.isfinite(row["policy_loss"]) for row in log)
    assert p < 0.05
    assert trained.mean() >= random.mean() + MIN_GAIN


def test_a_zero_entropy_weight_left_out_of_the_loss_changes_no_gradient_bit():
    """ppo_update leaves ``- ent_coef * entropy`` out of the loss when ent_coef is 0: the term
    would add -0.0 to the log-std's gradient.  The gradients with and without it, to the bit
    (log-std 0 too, where the logp path's own gradient can be a signed zero)."""
    torch.manual_seed(0)
    pi, v = GaussianPolicy(5, 2, (16, 16)), ValueNetwork(5, (16, 16))
    z, act = torch.randn(64, 5), torch.randn(64, 2)
    olp, adv, tg = torch.randn(64) - 3, torch.randn(64), torch.randn(64)
    params = [*pi.parameters(), *v.parameters()]
    for log_std in (-0.5, 0.0):
        with torch.no_grad():
            pi.log_std.fill_(log_std)
        grads = []
        for with_term in (True, False):
            logp, entropy = pi.log_prob_entropy(z, act)
            pg, _, _ = ppo.clipped_surrogate(logp, olp, adv, 0.2)
            loss = pg + 0.5 * ppo.value_loss(v.value_of(z), tg, tg)
            if with_term:
                loss = pg - 0.0 * entropy.mean() + 0.5 * ppo.value_loss(v.value_of(z), tg, tg)
            grads.append(torch.autograd.grad(loss, params, allow_unused=True))
        for a, b in zip(*grads):
            assert (a is None) == (b is None)
            if a is not None:
                assert torch.equal(a, b) and torch.equal(torch.signbit(a), torch.signbit(b))


def test_a_critic_warm_up_holds_the_policy_and_trains_the_critic():
    import copy
    import dataclasses
    from dc_lesson.algorithms import base, dc, dril
    from dc_lesson.nn.policies import GaussianPolicy
    cfg = ppo.PPOConfig(n_envs=2, n_steps=64, n_epochs=2, n_minibatches=4, total_steps=512,
                        value_warmup=2, seed=1)
    start = GaussianPolicy(5, 1, (16,), norm_obs=True)
    seen = []
    r = ppo.train("cartpole", config=cfg, policy=copy.deepcopy(start), progress=False,
                  callback=lambda row, pi: seen.append(copy.deepcopy(pi.state_dict())))
    for k, v in start.state_dict().items():          # held still for two updates ...
        assert torch.equal(seen[1][k], v), k
    assert any(not torch.equal(seen[2][k], v) for k, v in start.state_dict().items())  # ... then
    assert [row["policy_frozen"] for row in r.log] == [True, True, False, False]
    assert r.log[0]["value_loss"] > 0                # the critic trained meanwhile
    # unset, it is not in the JSON, so stored runs and cells keep their identity
    assert "value_warmup" not in dataclasses.replace(cfg, value_warmup=None).to_json()
    with pytest.raises(ValueError, match="value_warmup"):
        dataclasses.replace(cfg, value_warmup=4)     # leaves no update to the policy
    with pytest.raises(ValueError, match="ppo.value_warmup"):   # other loops refuse it
        dril.DRILConfig(ppo=dataclasses.replace(dril.DRILConfig().ppo, value_warmup=1))
    with pytest.raises(ValueError, match="ppo.value_warmup"):
        dc.DCConfig(ppo=dataclasses.replace(dc.DCConfig().ppo, value_warmup=1))
    assert base.unset_dropped({"value_warmup": None, "x": 1}) == {"x": 1}
