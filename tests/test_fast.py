"""The NumPy forward pass of rollouts computes what the torch modules compute."""

import numpy as np
import pytest
import torch

from dc_lesson.algorithms import ppo
from dc_lesson.data import rollout
from dc_lesson.nn import fast
from dc_lesson.nn.policies import GaussianPolicy, StochasticPolicy, ValueNetwork


def _trained_like(net):
    """Non-trivial weights and normaliser statistics (a fresh net's last layer is ~0)."""
    g = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(torch.randn(p.shape, generator=g) * 0.5)
    if net.obs_norm is not None:
        net.update_obs_norm(torch.randn(500, net.obs_norm.mean.numel(), generator=g) * 3 + 1)
    return net


@pytest.mark.parametrize("activation", ["tanh", "relu", "elu", "silu"])
@pytest.mark.parametrize("norm_obs", [False, True])
def test_numpy_forward_equals_the_modules(activation, norm_obs):
    pi = _trained_like(GaussianPolicy(6, 2, (32, 16), activation, norm_obs=norm_obs))
    v = _trained_like(ValueNetwork(6, (32, 16), activation, norm_obs=norm_obs))
    obs = np.random.default_rng(1).normal(0, 4, (64, 6)).astype(np.float32)
    with torch.no_grad():
        np.testing.assert_allclose(fast.NumpyForward(pi)(obs), pi(torch.from_numpy(obs)).numpy(),
                                   rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(fast.NumpyForward(v)(obs), v(torch.from_numpy(obs)).numpy(),
                                   rtol=1e-5, atol=1e-5)


def test_sampler_draws_the_modules_actions_and_log_probs_from_the_same_noise():
    pi = _trained_like(GaussianPolicy(6, 3, norm_obs=True))
    obs = np.random.default_rng(2).normal(size=(16, 6)).astype(np.float32)
    a, lp = fast.GaussianSampler(pi)(obs, torch.Generator().manual_seed(7))
    with torch.no_grad():
        a_ref = pi.sample(torch.from_numpy(obs), torch.Generator().manual_seed(7))
        lp_ref = pi.log_prob(torch.from_numpy(obs), a_ref)
    np.testing.assert_allclose(a, a_ref.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(lp, lp_ref.numpy(), rtol=1e-4, atol=1e-4)


def test_a_snapshot_follows_the_weights():
    pi = _trained_like(GaussianPolicy(6, 2))
    obs = np.ones((1, 6), np.float32)
    before = fast.snapshot(pi)(obs)
    assert fast.snapshot(pi) is fast.snapshot(pi)          # reused while nothing changed
    with torch.no_grad():
        pi.mean_net[0].bias.add_(1.0)                      # an optimiser step would do this
    after = fast.snapshot(pi)(obs)
    assert not np.allclose(before, after)
    with torch.no_grad():
        np.testing.assert_allclose(after, pi(torch.from_numpy(obs)).numpy(), rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("make", [fast.adamw, fast.adam])
def test_a_snapshot_follows_the_learners_own_optimiser_steps(make):
    """The learners' optimisers are PyTorch's fused kernels, which write the parameters
    without bumping their version counters: a snapshot taken before a step must still be
    retaken after it (GAIL's checkpoint evaluations once kept acting with the weights of the
    first one).  The hook that bumps the counters leaves the fused update bit for bit."""
    pi, twin = _trained_like(GaussianPolicy(6, 2)), _trained_like(GaussianPolicy(6, 2))
    obs = np.random.default_rng(3).normal(size=(8, 6)).astype(np.float32)
    opt = make(pi.parameters(), lr=1e-2)
    plain = type(opt)(twin.parameters(), lr=1e-2, fused=True)   # no hook
    before = fast.snapshot(pi)(obs)
    for o, net in ((opt, pi), (plain, twin)):
        o.zero_grad()
        net(torch.from_numpy(obs)).pow(2).sum().backward()
        o.step()
    after = fast.snapshot(pi)(obs)
    assert not np.allclose(before, after)
    with torch.no_grad():
        np.testing.assert_allclose(after, pi(torch.from_numpy(obs)).numpy(), rtol=1e-5,
                                   atol=1e-5)
    for p, q in zip(pi.parameters(), twin.parameters()):
        assert torch.equal(p, q)


def test_rollouts_and_batches_agree_on_either_path():
    """Mean-action episodes match to float tolerance; seeded stochastic batches repeat exactly
    on the fast path and agree with the torch path to float tolerance."""
    from dc_lesson import tasks
    spec = tasks.spec("reacher1")
    pi = _trained_like(GaussianPolicy(spec.obs_dim, spec.act_dim, norm_obs=True))
    v = ValueNetwork(spec.obs_dim, norm_obs=True)
    fast_trajs = rollout.collect("reacher1", pi, 2, seed=3, max_steps=50)
    with fast.disabled():
        assert not fast.enabled()
        slow_trajs = rollout.collect("reacher1", pi, 2, seed=3, max_steps=50)
    for a, b in zip(fast_trajs, slow_trajs):
        # float32 rounding differs between the two paths by ~1e-7 per step; a closed loop
        # amplifies it, so the episodes agree closely at first and drift apart slowly
        np.testing.assert_allclose(a.actions[:10], b.actions[:10], atol=1e-5)
        assert abs(a.ret - b.ret) < 0.05 * abs(b.ret) + 0.5

    def batch(seed):
        envs = ppo.EnvBatch("reacher1", 4, seed=seed)
        return ppo.collect_batch(envs, pi, v, 20, torch.Generator().manual_seed(seed))

    one, two = batch(5), batch(5)
    assert torch.equal(one.actions, two.actions) and torch.equal(one.logprobs, two.logprobs)
    with fast.disabled():
        ref = batch(5)
    torch.testing.assert_close(one.actions[:5], ref.actions[:5], atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(one.logprobs[:5], ref.logprobs[:5], atol=1e-4, rtol=1e-4)
    s1 = rollout.collect("reacher1", StochasticPolicy(pi, seed=9), 2, seed=1, max_steps=30)
    s2 = rollout.collect("reacher1", StochasticPolicy(pi, seed=9), 2, seed=1, max_steps=30)
    np.testing.assert_array_equal(s1[0].actions, s2[0].actions)


def _train_a_little(optimiser: str, max_norm: float, lean: bool, n_steps: int = 100):
    """``n_steps`` minibatch steps of two small networks (PPO's step: one optimiser, each
    network clipped on its own), with torch's wrappers or the lean calls; the learning rate
    moves as PPO's annealing moves it."""
    torch.manual_seed(0)
    pi, v = GaussianPolicy(5, 2, (16, 16)), ValueNetwork(5, (16, 16))
    make = fast.adamw if optimiser == "adamw" else fast.adam
    opt = make([*pi.parameters(), *v.parameters()], lr=1e-2, eps=1e-5, weight_decay=1e-3)
    g = torch.Generator().manual_seed(1)
    norms = []
    torch_steps = []
    torch_step = opt.step
    opt.step = lambda: (torch_steps.append(1), torch_step())[1]   # counts torch's own steps
    for step in range(n_steps):
        x, a = torch.randn(32, 5, generator=g), torch.randn(32, 2, generator=g)
        loss = -pi.distribution(x).log_prob(a).sum(-1).mean() + (v(x) - a[:, 0]).pow(2).mean()
        if step == 7:   # one step where one tensor's gradient is infinite, the others finite
            loss = loss + pi.log_std.sum() * float("inf")
        opt.param_groups[0]["lr"] = 1e-2 * (1 - step / n_steps)
        if lean:
            fast.zero_grad(opt)
        else:
            opt.zero_grad()
        loss.backward()
        if lean:
            norms += [fast.clip_grad_norm_(list(m.parameters()), max_norm) for m in (pi, v)]
            fast.optimizer_step(opt)
        else:
            norms += [torch.nn.utils.clip_grad_norm_(list(m.parameters()), max_norm)
                      for m in (pi, v)]
            opt.step()
        if step == 7:   # start again from finite weights, both ways alike
            with torch.no_grad():
                for p in (*pi.parameters(), *v.parameters()):
                    p.copy_(torch.nan_to_num(p, nan=0.1))
            opt.state.clear()
    # the lean path took torch's step only where the state was created (steps 0 and 8)
    assert len(torch_steps) == (2 if lean else n_steps)
    return pi, v, opt, torch.stack(norms)


@pytest.mark.parametrize("optimiser", ["adamw", "adam"])
@pytest.mark.parametrize("max_norm", [0.5, float("inf")])
def test_the_lean_optimiser_step_is_torchs_to_the_bit(optimiser, max_norm):
    """fast.optimizer_step / zero_grad / clip_grad_norm_ against Optimizer.step, zero_grad and
    clip_grad_norm_: the same weights, optimiser state and norms after a hundred steps, one
    of them with an infinite gradient (whose norm turns every gradient it clips to NaN, even
    under an infinite bound)."""
    ref = _train_a_little(optimiser, max_norm, lean=False)
    got = _train_a_little(optimiser, max_norm, lean=True)
    for a, b in zip((*ref[0].parameters(), *ref[1].parameters()),
                    (*got[0].parameters(), *got[1].parameters())):
        torch.testing.assert_close(b, a, rtol=0, atol=0, equal_nan=True)
    for (ka, sa), (kb, sb) in zip(ref[2].state_dict()["state"].items(),
                                  got[2].state_dict()["state"].items()):
        assert ka == kb
        for name in sa:
            torch.testing.assert_close(sb[name], sa[name], rtol=0, atol=0)
    torch.testing.assert_close(got[3], ref[3], rtol=0, atol=0, equal_nan=True)
    assert not torch.isfinite(ref[3]).all() and (ref[3][-10:] > 0).all()


def test_the_lean_step_bumps_the_versions_a_snapshot_reads():
    pi = GaussianPolicy(5, 2, (16, 16))
    opt = fast.adamw(pi.parameters(), lr=1e-2)
    for _ in range(2):
        fast.zero_grad(opt)
        pi(torch.randn(4, 5)).sum().backward()
        before = [p._version for p in pi.parameters()]
        fast.optimizer_step(opt)
        assert all(p._version > b for p, b in zip(pi.parameters(), before) if p.grad is not None)


def test_a_registered_hook_sends_the_step_through_torch():
    """Hooks are Optimizer.step's to call: with one registered for all optimisers, the lean
    path steps through torch, and the hook runs."""
    from torch.optim.optimizer import register_optimizer_step_post_hook
    pi = GaussianPolicy(5, 2, (16, 16))
    opt = fast.adamw(pi.parameters(), lr=1e-2)
    calls = []
    for _ in range(2):
        fast.zero_grad(opt)
        pi(torch.randn(4, 5)).sum().backward()
        handle = register_optimizer_step_post_hook(lambda *args: calls.append(1))
        try:
            fast.optimizer_step(opt)
        finally:
            handle.remove()
    assert len(calls) == 2
