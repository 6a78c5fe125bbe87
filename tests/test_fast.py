"""The fast path (``dc_lesson.nn.fast``) against the reader's path: the pieces that are
bit-identical compared to the bit, the others within a bound derived from float32 rounding
(never from one machine's run: each CPU's vector unit rounds in its own order); the switch is
off by default, and a readable loss edited there changes training."""

import dataclasses

import numpy as np
import pytest
import torch

from dc_lesson import data
from dc_lesson.algorithms import bc, ppo
from dc_lesson.data import rollout
from dc_lesson.nn import fast
from dc_lesson.nn.policies import (ACTION_HIGH, ACTION_LOW, GaussianPolicy, StochasticPolicy,
                                  ValueNetwork)

U = 2.0 ** -24          # float32's unit roundoff
ACT_ULPS = 4            # an activation (NumPy's or torch's tanh, expm1, exp) within a few ulps


def _trained_like(net):
    """Non-trivial weights and normaliser statistics (a fresh net's last layer is ~0)."""
    g = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(torch.randn(p.shape, generator=g) * 0.5)
    if net.obs_norm is not None:
        net.update_obs_norm(torch.randn(500, net.obs_norm.mean.numel(), generator=g) * 3 + 1)
    return net


def float32_bound(net, obs) -> np.ndarray:
    """A bound on ``|float32 net(obs) - exact net(obs)|`` for *any* order of summation, per
    output: a K-term dot product rounds to within ``gamma_K |x| . |w|`` (gamma_K = K u /
    (1 - K u), Higham's bound, whatever the blocking or FMA use), an activation to within a
    few ulps of its output, the normalised input to within one ulp; errors carried from the
    layer before grow by at most ``|W|`` and the activation's slope near the point.  Computed
    in float64 from the network's own activations."""
    seq = net.mean_net if hasattr(net, "mean_net") else net.net
    with torch.no_grad():
        x = torch.as_tensor(obs, dtype=torch.float32)
        h = (net.normalise(x) if net.obs_norm is not None else x).double()
        err = U * h.abs()
        layers = list(seq)
        for i, m in enumerate(layers):
            if not isinstance(m, torch.nn.Linear):
                continue
            w, b = m.weight.double(), m.bias.double()
            k = w.shape[1] + 1                                   # the bias is one more term
            gamma = k * U / (1 - k * U)
            a = h @ w.T + b
            err = err @ w.abs().T + gamma * (h.abs() @ w.abs().T + b.abs())
            if i + 1 < len(layers):                              # an activation follows
                act = layers[i + 1]
                h = act(a)
                err = _slope(act, a, err) * err + ACT_ULPS * U * h.abs()
            else:
                h = a
        out = err.numpy()
    return out[..., 0] if not hasattr(net, "mean_net") else out


def _slope(act, a, err):
    """The largest ``|act'|`` over ``[a - err, a + err]``, elementwise: the largest of the
    derivative at the ends and the middle, plus ``err`` (every activation here has
    ``|act''| <= 1``; ReLU's kink is caught by the ends)."""
    def slope(x):
        x = x.detach().clone().requires_grad_(True)
        act(x).sum().backward()
        return x.grad.abs()
    with torch.enable_grad():
        ends = torch.maximum(slope(a - err), slope(a + err))
        return torch.maximum(ends, slope(a)) + err


def _paths_agree(got, want, bound):
    """Both paths round within ``bound`` of the exact value, so within twice it of each other."""
    gap = np.abs(np.asarray(got, np.float64) - np.asarray(want, np.float64))
    assert (gap <= 2 * bound).all(), f"worst gap {gap.max():.3g} at bound {bound.max():.3g}"


def test_the_switch_is_off_by_default_and_on_within_its_block():
    assert not fast.enabled()
    with fast.on():
        assert fast.enabled()
        with fast.disabled():
            assert not fast.enabled()
        assert fast.enabled()
    assert not fast.enabled()
    assert not fast.adamw(GaussianPolicy(3, 1).parameters()).param_groups[0]["fused"]
    with fast.on():
        assert fast.adamw(GaussianPolicy(3, 1).parameters()).param_groups[0]["fused"]


@pytest.mark.parametrize("activation", ["tanh", "relu", "elu", "silu"])
@pytest.mark.parametrize("norm_obs", [False, True])
def test_numpy_forward_equals_the_modules_to_float32_rounding(activation, norm_obs):
    pi = _trained_like(GaussianPolicy(6, 2, (32, 16), activation, norm_obs=norm_obs))
    v = _trained_like(ValueNetwork(6, (32, 16), activation, norm_obs=norm_obs))
    obs = np.random.default_rng(1).normal(0, 4, (64, 6)).astype(np.float32)
    for net in (pi, v):
        bound = float32_bound(net, obs)
        assert bound.max() < 1e-4 * max(1.0, float(np.abs(fast.NumpyForward(net)(obs)).max()))
        with torch.no_grad():
            _paths_agree(fast.NumpyForward(net)(obs), net(torch.from_numpy(obs)).numpy(), bound)


def _sampler_bounds(pi, obs, noise):
    """Bounds on the gap between the two paths' actions and log-probabilities: the mean's
    (above) plus the rounding of ``mu + sigma * noise``; the log-density's terms each within a
    few ulps of their size, and z = (a - mu) / sigma, whose error is that of a and mu over
    sigma (the mean's own error cancels: both paths subtract their own mean)."""
    mu_bound = float32_bound(pi, obs)
    with torch.no_grad():
        mu = pi(torch.from_numpy(obs)).double().numpy()
        sigma = pi.log_std.exp().double().numpy()
    spread = np.abs(mu) + sigma * np.abs(noise)
    act_bound = mu_bound + 2 * U * spread
    z_err = 4 * U * spread / sigma + 2 * U * np.abs(noise)
    terms = 0.5 * noise ** 2 + np.abs(np.log(sigma)) + 1.0
    logp_bound = (np.abs(noise) * z_err).sum(-1) + 8 * U * pi.act_dim * terms.sum(-1)
    return act_bound, logp_bound


def test_sampler_draws_the_modules_actions_and_log_probs_from_the_same_noise():
    pi = _trained_like(GaussianPolicy(6, 3, norm_obs=True))
    obs = np.random.default_rng(2).normal(size=(16, 6)).astype(np.float32)
    a, lp = fast.GaussianSampler(pi)(obs, torch.Generator().manual_seed(7))
    noise = torch.randn((16, 3), generator=torch.Generator().manual_seed(7)).double().numpy()
    with torch.no_grad():
        a_ref = pi.sample(torch.from_numpy(obs), torch.Generator().manual_seed(7))
        lp_ref = pi.log_prob(torch.from_numpy(obs), a_ref)
    act_bound, logp_bound = _sampler_bounds(pi, obs, noise)
    _paths_agree(a, a_ref.numpy(), act_bound)
    _paths_agree(lp, lp_ref.numpy(), logp_bound)


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
        _paths_agree(after, pi(torch.from_numpy(obs)).numpy(), float32_bound(pi, obs))


@pytest.mark.parametrize("make", [fast.adamw, fast.adam])
def test_a_snapshot_follows_the_learners_own_optimiser_steps(make):
    """The learners' optimisers are PyTorch's fused kernels, which write the parameters
    without bumping their version counters: a snapshot taken before a step must still be
    retaken after it (GAIL's checkpoint evaluations once kept acting with the weights of the
    first one).  The hook that bumps the counters leaves the fused update bit for bit."""
    pi, twin = _trained_like(GaussianPolicy(6, 2)), _trained_like(GaussianPolicy(6, 2))
    obs = np.random.default_rng(3).normal(size=(8, 6)).astype(np.float32)
    with fast.on():
        opt = make(pi.parameters(), lr=1e-2)
        _steps_and_snapshots(opt, pi, twin, obs)


def _steps_and_snapshots(opt, pi, twin, obs):
    plain = type(opt)(twin.parameters(), lr=1e-2, fused=True)   # no hook
    before = fast.snapshot(pi)(obs)
    for o, net in ((opt, pi), (plain, twin)):
        o.zero_grad()
        net(torch.from_numpy(obs)).pow(2).sum().backward()
        o.step()
    after = fast.snapshot(pi)(obs)
    assert not np.allclose(before, after)
    with torch.no_grad():
        _paths_agree(after, pi(torch.from_numpy(obs)).numpy(), float32_bound(pi, obs))
    for p, q in zip(pi.parameters(), twin.parameters()):
        assert torch.equal(p, q)


def test_one_step_from_the_same_state_agrees_on_either_path():
    """Where the two paths are defined to agree: each step's action, from the same state.

    A closed loop carries a last-bit difference into the next state and grows it, by an
    amount that depends on the CPU, so whole episodes are not compared across paths.  Here
    every state of an episode on the reader's path (the torch modules) is given to the NumPy
    forward; every seeded stochastic step of a PPO batch is redrawn from the same generator
    on the same state.  On the fast path episodes and batches repeat exactly."""
    from dc_lesson import tasks
    spec = tasks.spec("reacher1")
    pi = _trained_like(GaussianPolicy(spec.obs_dim, spec.act_dim, norm_obs=True))
    v = ValueNetwork(spec.obs_dim, norm_obs=True)
    torch_trajs = rollout.collect("reacher1", pi, 2, seed=3, max_steps=50)
    for t in torch_trajs:
        states = t.observations[:-1].astype(np.float32)
        got = np.clip(fast.NumpyForward(pi)(states), ACTION_LOW, ACTION_HIGH)
        _paths_agree(got, t.actions, float32_bound(pi, states))
    with fast.on():
        once = rollout.collect("reacher1", pi, 2, seed=3, max_steps=50)
        again = rollout.collect("reacher1", pi, 2, seed=3, max_steps=50)
    for a, b in zip(once, again):
        np.testing.assert_array_equal(a.actions, b.actions)

    def batch(seed):
        envs = ppo.EnvBatch("reacher1", 4, seed=seed)
        return ppo.collect_batch(envs, pi, v, 20, torch.Generator().manual_seed(seed))

    ref = batch(5)                                    # the reader's path
    gen = torch.Generator().manual_seed(5)
    sampler = fast.GaussianSampler(pi)
    for t in range(20):
        states = ref.obs[t].numpy()
        noise_gen = torch.Generator()
        noise_gen.set_state(gen.get_state())
        noise = torch.randn(ref.actions[t].shape, generator=noise_gen).double().numpy()
        a, lp = sampler(states, gen)                  # the same draw from the same generator
        act_bound, logp_bound = _sampler_bounds(pi, states, noise)
        _paths_agree(a, ref.actions[t].numpy(), act_bound)
        _paths_agree(lp, ref.logprobs[t].numpy(), logp_bound)
    with fast.on():
        one, two = batch(5), batch(5)
    assert torch.equal(one.actions, two.actions) and torch.equal(one.logprobs, two.logprobs)
    with fast.on():
        s1 = rollout.collect("reacher1", StochasticPolicy(pi, seed=9), 2, seed=1, max_steps=30)
        s2 = rollout.collect("reacher1", StochasticPolicy(pi, seed=9), 2, seed=1, max_steps=30)
    np.testing.assert_array_equal(s1[0].actions, s2[0].actions)


@fast.on()      # the learners' fused optimiser, stepped by torch's wrappers or the lean calls
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


@fast.on()
def test_the_lean_step_bumps_the_versions_a_snapshot_reads():
    pi = GaussianPolicy(5, 2, (16, 16))
    opt = fast.adamw(pi.parameters(), lr=1e-2)
    for _ in range(2):
        fast.zero_grad(opt)
        pi(torch.randn(4, 5)).sum().backward()
        before = [p._version for p in pi.parameters()]
        fast.optimizer_step(opt)
        assert all(p._version > b for p, b in zip(pi.parameters(), before) if p.grad is not None)


@fast.on()
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


@pytest.mark.parametrize("optimiser", ["adamw", "adam"])
def test_the_fused_optimiser_is_the_plain_one_to_float32_rounding(optimiser):
    """One step from the same weights and gradients: the fused kernel (fast path) and the
    plain loop (reader's path) compute the same update in another order, so each weight
    agrees to a few ulps of the terms of its update, ``|p|`` and ``lr * (|m / sqrt(v)| +
    weight_decay |p|)`` (at the first step ``|m / sqrt(v)|`` is at most 1)."""
    torch.manual_seed(0)
    pi = _trained_like(GaussianPolicy(5, 2, (16, 16)))
    twin = _trained_like(GaussianPolicy(5, 2, (16, 16)))
    make = fast.adamw if optimiser == "adamw" else fast.adam
    lr, wd = 1e-2, 1e-3
    with fast.on():
        fused = make(pi.parameters(), lr=lr, eps=1e-5, weight_decay=wd)
    plain = make(twin.parameters(), lr=lr, eps=1e-5, weight_decay=wd)
    assert fused.param_groups[0]["fused"] and not plain.param_groups[0]["fused"]
    x, a = torch.randn(32, 5), torch.randn(32, 2)
    for net, opt in ((pi, fused), (twin, plain)):
        (-net.distribution(x).log_prob(a).sum(-1).mean()).backward()
        opt.step()
    for p, q in zip(pi.parameters(), twin.parameters()):
        size = p.detach().abs().double() + lr * (1 + wd * p.detach().abs().double())
        gap = (p.detach().double() - q.detach().double()).abs()
        assert (gap <= 8 * U * size).all(), float((gap / size).max() / U)


def _tiny_ppo():
    return dataclasses.replace(ppo.PPOConfig(), n_envs=2, n_steps=32, total_steps=128,
                               n_epochs=2, n_minibatches=2, seed=0)


def _ppo_weights(config):
    out = ppo.train("reacher1", None, config, progress=False)
    return torch.cat([p.detach().flatten() for p in out.policy.parameters()])


def _bc_weights(config):
    demos = data.load_demos("reacher1", n_trajectories=4)
    out = bc.train("reacher1", demos, config, progress=False)
    return torch.cat([p.detach().flatten() for p in out.policy.parameters()])


def _scaled_by_zero(module, name):
    real = getattr(module, name)
    if name == "clipped_surrogate":
        return lambda *a, **k: (lambda out: (out[0] * 0, *out[1:]))(real(*a, **k))
    return lambda *a, **k: {**real(*a, **k), "nll": real(*a, **k)["nll"] * 0}


@pytest.mark.parametrize("module, loss", [(ppo, "clipped_surrogate"), (bc, "bc_loss")])
def test_editing_a_readable_loss_changes_training(module, loss, monkeypatch):
    """A reader who scales the loss they read by zero sees training change on the default
    path.  On the fast path PPO's gradients are taken by hand (``nn.backprop``), so there the
    edit does not reach them: that is what the switch is for.  (BC's early stopping reads
    ``bc_loss`` on either path, so there the edit shows on both.)"""
    weights = _ppo_weights if module is ppo else _bc_weights
    config = (_tiny_ppo() if module is ppo
              else dataclasses.replace(bc.BCConfig(), epochs=3, seed=0))
    plain = weights(config)
    with fast.on():
        fast_plain = weights(config)
    monkeypatch.setattr(module, loss, _scaled_by_zero(module, loss))
    edited = weights(config)
    assert not torch.equal(edited, plain), f"editing {loss} did not change training"
    assert torch.equal(weights(config), edited)           # the edited run repeats
    if module is ppo:
        with fast.on():
            assert torch.equal(weights(config), fast_plain)   # the fast path does not read it
