"""The hand-written backward passes give autograd's gradients to the bit."""

import contextlib
import dataclasses

import pytest
import torch

from dc_lesson.algorithms import bc, ppo
from dc_lesson.nn import backprop, fast
from dc_lesson.nn.mixture import MixturePolicy
from dc_lesson.nn.policies import GaussianPolicy, ValueNetwork

SHAPES = [  # obs dim, action dim, hidden widths, minibatch
    (17, 6, (64, 64), 64),
    (4, 1, (64, 64), 100),       # one action dimension, a batch that is no power of two
    (11, 3, (32,), 37),          # one hidden layer
    (8, 2, (16, 16, 16), 64),    # three
]


def _moved(net, gen, scale):
    with torch.no_grad():
        for p in net.parameters():
            p.add_(torch.randn(p.shape, generator=gen) * scale)
    return net


def _autograd_ppo(pi, v, zp, act, olp, adv, tg, clip, vf):
    for p in (*pi.parameters(), *v.parameters()):
        p.grad = None
    new_logp, entropy = pi.log_prob_entropy(zp, act)
    pg, kl, cf = ppo.clipped_surrogate(new_logp, olp, adv, clip)
    vl = ppo.value_loss(v.value_of(zp), tg, tg, None)
    (pg + vf * vl).backward()
    return [p.grad.clone() for p in (*pi.parameters(), *v.parameters())], [
        pg, vl, entropy.mean(), kl, cf]


@pytest.mark.parametrize("obs_dim,act_dim,hidden,size", SHAPES)
def test_ppo_gradients_are_autograds_to_the_bit(obs_dim, act_dim, hidden, size):
    gen = torch.Generator().manual_seed(obs_dim)
    pi = _moved(GaussianPolicy(obs_dim, act_dim, hidden), gen, 0.3)
    v = _moved(ValueNetwork(obs_dim, hidden), gen, 0.3)
    clipped = 0
    for step in range(40):
        zp = torch.randn(size, obs_dim, generator=gen)
        act = torch.randn(size, act_dim, generator=gen) * 0.7
        with torch.no_grad():   # old log-probabilities near the new ones: some ratios clip
            olp = pi.log_prob_entropy(zp, act)[0] + torch.randn(size, generator=gen) * 0.3
        adv = torch.randn(size, generator=gen)
        tg = torch.randn(size, generator=gen) * 5
        want, want_terms = _autograd_ppo(pi, v, zp, act, olp, adv, tg, 0.2, 0.5)
        for p in (*pi.parameters(), *v.parameters()):
            p.grad = None
        terms = backprop.ppo_grads(pi, v, zp, zp, act, olp, adv, tg, 0.2, 0.5)
        got = [p.grad for p in (*pi.parameters(), *v.parameters())]
        for (name, _), a, b in zip((*pi.named_parameters(), *v.named_parameters()), want, got):
            assert torch.equal(a, b), f"step {step}: d loss / d {name} differs from autograd's"
        for a, b in zip(want_terms, terms.values()):
            assert torch.equal(a.detach(), b)
        clipped += float(terms["clip_fraction"]) > 0
        _moved(pi, gen, 0.02)
        _moved(v, gen, 0.02)
    assert clipped > 10, "the clipped branch of the surrogate was hardly exercised"


@pytest.mark.parametrize("norm_obs", [False, True])
@pytest.mark.parametrize("obs_dim,act_dim,hidden,size", SHAPES)
def test_bc_gradients_are_autograds_to_the_bit(obs_dim, act_dim, hidden, size, norm_obs):
    gen = torch.Generator().manual_seed(act_dim)
    pi = _moved(GaussianPolicy(obs_dim, act_dim, hidden, norm_obs=norm_obs), gen, 0.3)
    if norm_obs:
        pi.update_obs_norm(torch.randn(300, obs_dim, generator=gen) * 3 + 1)
    for step in range(20):
        obs = torch.randn(size, obs_dim, generator=gen) * 2
        act = torch.randn(size, act_dim, generator=gen) * 0.5
        for p in pi.parameters():
            p.grad = None
        want_terms = bc.bc_loss(pi, obs, act)
        want_terms["nll"].backward()
        want = [p.grad.clone() for p in pi.parameters()]
        for p in pi.parameters():
            p.grad = None
        terms = backprop.bc_grads(pi, obs, act)
        for (name, p), a in zip(pi.named_parameters(), want):
            assert torch.equal(p.grad, a), f"step {step}: d nll / d {name} differs"
        for k, a in want_terms.items():
            assert torch.equal(a.detach(), terms[k]), k
        _moved(pi, gen, 0.05)


def _batch(obs_dim, act_dim, gen, t=64, n=4):
    return ppo.Batch(obs=torch.randn(t, n, obs_dim, generator=gen),
                     actions=torch.randn(t, n, act_dim, generator=gen) * 0.5,
                     logprobs=torch.randn(t, n, generator=gen) - 3,
                     env_rewards=torch.zeros(t, n), next_obs=torch.zeros(t, n, obs_dim),
                     dones=torch.zeros(t, n, dtype=torch.bool),
                     values=torch.randn(t, n, generator=gen),
                     next_values=torch.zeros(t, n), episode_returns=[],
                     advantages=torch.randn(t, n, generator=gen),
                     returns=torch.randn(t, n, generator=gen) * 3)


@fast.on()      # the by-hand path is the fast path's
def _update(monkeypatch, by_hand: bool):
    gen = torch.Generator().manual_seed(5)
    torch.manual_seed(0)     # the initial weights
    pi = GaussianPolicy(9, 3, norm_obs=True)
    v = ValueNetwork(9, norm_obs=True)
    for net in (pi, v):
        _moved(net, gen, 0.2)
        net.update_obs_norm(torch.randn(100, 9, generator=gen))
    opt = fast.adam([*pi.parameters(), *v.parameters()], lr=1e-3)
    cfg = dataclasses.replace(ppo.PPOConfig(), n_epochs=3, n_minibatches=4)
    calls = []
    if by_hand:
        real = backprop.ppo_grads
        monkeypatch.setattr(backprop, "ppo_grads", lambda *a: calls.append(1) or real(*a))
    else:
        monkeypatch.setattr(backprop, "supported", lambda net: False)
    logs = [ppo.ppo_update(pi, v, opt, _batch(9, 3, gen), cfg, torch.Generator().manual_seed(1))
            for _ in range(3)]
    monkeypatch.undo()
    return [p.detach().clone() for p in (*pi.parameters(), *v.parameters())], logs, calls


def test_ppo_update_by_hand_ends_where_autograd_ends(monkeypatch):
    """Three updates of twelve minibatch steps each (with the optimiser and the clip between
    them): the same weights and the same logged terms either way."""
    w_auto, log_auto, _ = _update(monkeypatch, by_hand=False)
    w_hand, log_hand, calls = _update(monkeypatch, by_hand=True)
    assert len(calls) == 36, "the by-hand path was not taken"
    assert all(torch.equal(a, b) for a, b in zip(w_auto, w_hand))
    assert log_auto == log_hand


def test_the_readers_ppo_update_is_the_fast_paths_with_the_same_optimiser():
    """The reader's path (autograd through ``minibatch_loss``, ``optimizer.step()``, torch's
    clip) against the fast path (by hand, lean step), on one fused optimiser each: the same
    bits.  What differs between the paths in a real run is only which optimiser ``train``
    builds (fused or not) and the rollout's forward pass."""
    def run(on: bool):
        gen = torch.Generator().manual_seed(5)
        torch.manual_seed(0)
        pi, v = GaussianPolicy(9, 3, norm_obs=True), ValueNetwork(9, norm_obs=True)
        for net in (pi, v):
            _moved(net, gen, 0.2)
            net.update_obs_norm(torch.randn(100, 9, generator=gen))
        with fast.on():
            opt = fast.adamw([*pi.parameters(), *v.parameters()], lr=1e-3)
        cfg = dataclasses.replace(ppo.PPOConfig(), n_epochs=3, n_minibatches=4)
        with (fast.on() if on else contextlib.nullcontext()):
            logs = [ppo.ppo_update(pi, v, opt, _batch(9, 3, gen), cfg,
                                   torch.Generator().manual_seed(1)) for _ in range(3)]
        return [p.detach().clone() for p in (*pi.parameters(), *v.parameters())], logs
    w_read, log_read = run(False)
    w_fast, log_fast = run(True)
    assert all(torch.equal(a, b) for a, b in zip(w_read, w_fast))
    assert log_read == log_fast


def test_bc_step_by_hand_ends_where_autograd_ends():
    @fast.on()
    def run(disabled: bool):
        gen = torch.Generator().manual_seed(2)
        torch.manual_seed(0)
        pi = _moved(GaussianPolicy(7, 2, norm_obs=True), gen, 0.2)
        pi.update_obs_norm(torch.randn(100, 7, generator=gen))
        opt = fast.adamw(pi.parameters(), lr=1e-3)
        logs = []
        for _ in range(30):
            obs, act = torch.randn(50, 7, generator=gen), torch.randn(50, 2, generator=gen)
            if disabled:   # bc_step's autograd branch, with the same lean optimiser step
                real = backprop.supported
                backprop.supported = lambda net: False
                try:
                    logs.append(bc.bc_step(pi, opt, obs, act, 0.5))
                finally:
                    backprop.supported = real
            else:
                logs.append(bc.bc_step(pi, opt, obs, act, 0.5))
        return [p.detach().clone() for p in pi.parameters()], logs
    w_auto, log_auto = run(True)
    w_hand, log_hand = run(False)
    assert all(torch.equal(a, b) for a, b in zip(w_auto, w_hand))
    assert log_auto == log_hand


def test_the_readers_bc_step_is_the_fast_paths_with_the_same_optimiser():
    """``bc_step`` as read (autograd through ``bc_loss``, torch's clip, ``optimizer.step()``)
    against the fast path (by hand, the lean step), on one fused optimiser each: the same
    bits, with and without a gradient bound."""
    def run(on: bool, max_norm):
        gen = torch.Generator().manual_seed(3)
        torch.manual_seed(0)
        pi = _moved(GaussianPolicy(7, 2, norm_obs=True), gen, 0.2)
        pi.update_obs_norm(torch.randn(100, 7, generator=gen))
        with fast.on():
            opt = fast.adamw(pi.parameters(), lr=1e-3)
        with (fast.on() if on else contextlib.nullcontext()):
            logs = [bc.bc_step(pi, opt, torch.randn(50, 7, generator=gen),
                               torch.randn(50, 2, generator=gen), max_norm) for _ in range(30)]
        return [p.detach().clone() for p in pi.parameters()], logs
    for max_norm in (0.5, None):
        (w_read, log_read), (w_fast, log_fast) = run(False, max_norm), run(True, max_norm)
        assert all(torch.equal(a, b) for a, b in zip(w_read, w_fast))
        assert log_read == log_fast


def test_only_tanh_mlps_are_taken_by_hand():
    assert backprop.supported(GaussianPolicy(4, 2).mean_net)
    assert backprop.supported(ValueNetwork(4, (8, 8, 8)).net)
    assert not backprop.supported(GaussianPolicy(4, 2, activation="relu").mean_net)
    assert not backprop.supported(torch.nn.Sequential(torch.nn.Linear(4, 2, bias=False)))
    # a mixture has no log_std: bc_step and ppo_update keep autograd for it
    pi = MixturePolicy(4, 2, n_components=2)
    opt = torch.optim.Adam(pi.parameters())
    out = bc.bc_step(pi, opt, torch.randn(16, 4), torch.randn(16, 2))
    assert all(p.grad is not None for p in pi.parameters())
    assert out["nll"] == out["nll"]
