"""PPO's and BC's gradients by hand: the kernels autograd would call, without autograd.

A minibatch step of PPO on the library's networks (two 64-64 MLPs, 64 samples) does a few
microseconds of arithmetic per operation and pays torch's autograd as much again: recording
each operation's node on the way forward, then the engine's walk back through about forty
nodes, each a C++ call with its bookkeeping (1.7 ms per step, 40% of it in ``backward``,
issue 14's profile).  For a fixed, known computation the backward pass is short to write out:
the derivative of every operation below is the formula in torch's ``derivatives.yaml``,
evaluated with the same kernel on the same operands in the same layout, so every gradient is
the one autograd computes, to the bit (``tests/test_backprop.py`` compares them over many
steps, and whole trained runs hash equal).

The computations covered (anything else takes autograd):

* an MLP of ``nn.Linear`` layers with ``nn.Tanh`` between them (:func:`mlp_forward`,
  :func:`mlp_backward`); a linear layer ``a = h W^T + b`` is ``addmm(b, h, W^T)``, and its
  backward is ``dh = da W``, ``dW = da^T h``, ``db = sum_rows(da)``; ``tanh``'s is
  ``da = dh * (1 - tanh^2)`` (``tanh_backward``);
* the Gaussian log-density torch's ``Normal.log_prob`` computes,
  ``-(a - mu)^2 / (2 sigma^2) - log sigma - log sqrt(2 pi)`` with ``sigma = exp(log_std)``;
* PPO's clipped surrogate and squared value error (:func:`ppo_grads`), BC's mean negative
  log-likelihood (:func:`bc_grads`).

The order of operations matters only where it changes a rounding: a sum of two gradients is
the same either way round, and every tensor here receives at most two.
"""

from __future__ import annotations

import math

import torch
from torch import nn

_LOG_SQRT_2PI = math.log(math.sqrt(2 * math.pi))


def supported(net: nn.Sequential) -> bool:
    """Whether ``net`` is Linear (Tanh Linear)*: the networks this module differentiates."""
    layers = list(net)
    return (len(layers) % 2 == 1
            and all(type(m) is nn.Linear and m.bias is not None for m in layers[0::2])
            and all(type(m) is nn.Tanh for m in layers[1::2]))


def mlp_forward(net: nn.Sequential, z: torch.Tensor):
    """``net(z)`` and what its backward pass needs: the input and every tanh output."""
    linears = list(net)[0::2]
    hs = [z]
    h = z
    for k, layer in enumerate(linears):
        a = torch.addmm(layer.bias, h, layer.weight.t())   # what F.linear calls for 2-D input
        if k == len(linears) - 1:
            return a, hs
        h = torch.tanh(a)
        hs.append(h)


def mlp_backward(net: nn.Sequential, hs: list, grad: torch.Tensor) -> list:
    """Gradients ``[dW_1, db_1, ..., dW_L, db_L]`` for the output gradient ``grad``.

    Autograd's ``AddmmBackward0`` with ``mat2 = W^T`` (a column-major view) computes the weight
    gradient as ``(grad^T mm h)^T`` and the transpose's backward transposes it back: one
    ``mm(grad^T, h)``; the bias gradient is ``sum_to``'s ``sum(0, keepdim=True)``, viewed
    back; the input's is ``grad mm W`` (not needed for the first layer's input)."""
    linears = list(net)[0::2]
    out = [None] * (2 * len(linears))
    for k in range(len(linears) - 1, -1, -1):
        layer, h = linears[k], hs[k]
        out[2 * k] = torch.mm(grad.t(), h)
        out[2 * k + 1] = grad.sum(0, keepdim=True).view(layer.bias.shape)
        if k:
            grad = torch.ops.aten.tanh_backward(torch.mm(grad, layer.weight), h)
    return out


def _assign(params, grads) -> None:
    for p, g in zip(params, grads):
        p.grad = g


def gaussian_logp(mean: torch.Tensor, log_std: torch.Tensor, act: torch.Tensor):
    """``Normal(mean, exp(log_std)).log_prob(act)`` per dimension, in torch's order of
    operations, and what its backward pass needs."""
    std = log_std.exp()
    scale = std.expand_as(mean)
    var = scale ** 2
    log_scale = scale.log()
    diff = act - mean
    neg_sq = -(diff ** 2)
    den = 2 * var
    logp = neg_sq / den - log_scale - _LOG_SQRT_2PI
    return logp, (std, scale, diff, neg_sq, den)


def gaussian_logp_backward(grad: torch.Tensor, saved):
    """Gradients of the per-dimension log-density (``grad`` of the same shape) with respect
    to the mean and to ``log_std``.  Each line is the derivative autograd takes of the
    corresponding forward line: DivBackward0's ``-g * ((x / y) / y)``, PowBackward0's
    ``g * (2 * x)``, LogBackward0's ``g / x``, ExpBackward0's ``g * exp(x)``, and the
    expand's ``sum(0)``."""
    std, scale, diff, neg_sq, den = saved
    g_neg_sq = grad / den
    g_den = -grad * ((neg_sq / den) / den)
    g_diff = -g_neg_sq * (2 * diff)
    g_mean = -g_diff
    g_scale = (g_den * 2) * (2 * scale) + (-grad) / scale
    g_std = g_scale.sum(0, keepdim=True).view(std.shape)
    return g_mean, g_std * std


def ppo_grads(policy, value_fn, zp, zv, act, old_logp, adv, targets, clip_coef: float,
              vf_coef: float) -> dict:
    """PPO's minibatch loss ``clipped surrogate + vf_coef * value loss`` (no entropy term,
    no value clipping, advantages as given) differentiated by hand: sets ``.grad`` of every
    parameter of ``policy`` (its mean network and ``log_std``) and ``value_fn``, as
    ``loss.backward()`` after ``zero_grad`` would, and returns the terms ``ppo_update`` logs,
    computed as :func:`dc_lesson.algorithms.ppo.clipped_surrogate` and ``value_loss`` do."""
    with torch.no_grad():
        mean, hs_pi = mlp_forward(policy.mean_net, zp)
        logp, saved = gaussian_logp(mean, policy.log_std, act)
        entropy = (0.5 + 0.5 * math.log(2 * math.pi) + torch.log(saved[1])).sum(-1).mean()
        new_logp = logp.sum(-1)
        out_v, hs_v = mlp_forward(value_fn.net, zv)
        values = out_v.squeeze(-1)

        log_ratio = new_logp - old_logp
        ratio = log_ratio.exp()
        neg_adv = -adv
        unclipped = neg_adv * ratio
        clipped_ratio = ratio.clamp(1 - clip_coef, 1 + clip_coef)
        clipped = neg_adv * clipped_ratio
        pg_loss = torch.max(unclipped, clipped).mean()
        approx_kl = ((ratio - 1) - log_ratio).mean()
        clip_fraction = ((ratio - 1).abs() > clip_coef).float().mean()
        err = values - targets
        v_loss = 0.5 * (err ** 2).mean()

        # backward, from d loss = 1 (AddBackward passes it to both terms)
        one = torch.ones_like(pg_loss)
        g_max = one.expand(unclipped.shape) / unclipped.numel()          # MeanBackward0
        tie = unclipped == clipped
        g_unclipped = torch.where(tie, g_max / 2, g_max).masked_fill_(unclipped < clipped, 0)
        g_clipped = torch.where(tie, g_max / 2, g_max).masked_fill_(unclipped > clipped, 0)
        g_ratio = g_unclipped * neg_adv + torch.where(
            (ratio >= 1 - clip_coef).logical_and_(ratio <= 1 + clip_coef),
            g_clipped * neg_adv, torch.scalar_tensor(0.0))
        g_new_logp = g_ratio * ratio
        g_logp = g_new_logp.unsqueeze(-1).expand(logp.shape)             # SumBackward1
        g_mean, g_log_std = gaussian_logp_backward(g_logp, saved)
        grads_pi = mlp_backward(policy.mean_net, hs_pi, g_mean)

        g_sq = ((one * vf_coef) * 0.5).expand(err.shape) / err.numel()
        g_values = g_sq * (2 * err)
        grads_v = mlp_backward(value_fn.net, hs_v, g_values.unsqueeze(-1))
    _assign(list(policy.mean_net.parameters()), grads_pi)
    policy.log_std.grad = g_log_std
    _assign(list(value_fn.net.parameters()), grads_v)
    return {"policy_loss": pg_loss, "value_loss": v_loss, "entropy": entropy,
            "approx_kl": approx_kl, "clip_fraction": clip_fraction}


def bc_grads(policy, obs, act) -> dict:
    """BC's loss, the mean negative log-likelihood ``-mean(sum log pi(act | obs))``, differentiated
    by hand: sets ``.grad`` of the policy's parameters as ``loss.backward()`` after
    ``zero_grad`` would, and returns :func:`dc_lesson.algorithms.bc.bc_loss`'s terms."""
    with torch.no_grad():
        mean, hs = mlp_forward(policy.mean_net, policy.normalise(obs))
        logp, saved = gaussian_logp(mean, policy.log_std, act)
        nll = -logp.sum(-1).mean()
        terms = {"nll": nll, "mse": ((mean - act) ** 2).mean(),
                 "log_std": policy.log_std.mean()}
        g = -torch.ones_like(nll)                                         # NegBackward0
        g_logp = (g.expand(logp.shape[:1]) / logp.shape[0]).unsqueeze(-1).expand(logp.shape)
        g_mean, g_log_std = gaussian_logp_backward(g_logp, saved)
        grads = mlp_backward(policy.mean_net, hs, g_mean)
    _assign(list(policy.mean_net.parameters()), grads)
    policy.log_std.grad = g_log_std
    return terms
