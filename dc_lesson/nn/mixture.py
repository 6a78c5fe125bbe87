"""A policy that can hold several modes: a mixture of K Gaussians whose weights, means and
standard deviations all depend on the state (a mixture density network, Bishop 1994).

    pi(a | s) = sum_k w_k(s) N(a; mu_k(s), diag(sigma_k(s))^2),   w = softmax(logits(s))

A unimodal Gaussian policy facing demonstrations that go left from some states and right from
others (or, worse, from the same state: the "coin" experts of chapter 04) fits the average of
the modes; a mixture can put one component on each.  It is a drop-in for
:class:`~dc_lesson.nn.policies.GaussianPolicy` where the library needs a policy's density:

* :meth:`log_prob` is the mixture's exact log-density (log-sum-exp over the components),
  which is all BC (Eq. 1) and PPO's ratio need;
* :meth:`sample` draws a component, then a Gaussian sample from it (raw, unclipped: the
  environment clips, as for the Gaussian policy; no tanh squashing, so the log-density stays
  exact and the two policies are compared on equal terms);
* :meth:`act` with ``deterministic=True`` (what mean-action evaluation runs) is the mean of the
  most probable component at that state, not the mixture's mean, which would lie *between*
  the modes;
* :class:`ComponentMeans` draws the component and acts with its mean (the ``"components"``
  evaluation of :func:`~dc_lesson.evaluation.evaluate_policy`): the mode question without
  the within-component noise;
* :meth:`entropy` has no closed form: a one-sample Monte Carlo estimate, used only for logs.

Choices left open by the literature and made here: the components share one MLP trunk (64-64
tanh) and read their parameters off one linear head; the log-stds are clamped to
``[log_std_min, log_std_max]`` (:data:`LOG_STD_MIN`, :data:`LOG_STD_MAX`) so that BC cannot
drive a component's density to infinity on the demonstration pairs it alone explains; the
component means are initialised spread out (a random head, not
the near-zero head of the Gaussian policy), so that they start apart and BC can assign them
to different modes.

**Why the floor is e^-2.**  A mixture density network's likelihood grows without bound as a
component's spread shrinks onto the pairs it alone explains (Bishop 1994); the usual remedy is
a floor on the spread.  The first floor, e^-5, let that happen on our deterministic experts'
demonstrations.  Measured once by a probe on the reference path (not a package command, so
these figures are a record, not a result the package regenerates): the mixture BC's mean
action scored 0.21 scaled return on ``reacher4`` (seed 0, 18 demonstrations, the
``studies.modes`` match episodes) against plain BC's 0.85 (whose own learned log-std was
-5.25), and a single component with a state-dependent spread 0.02; with the floor at e^-3, 0.67; at
e^-2, 0.83 (and 1.01 against plain BC's 0.94 on ``halfcheetah2``).  A state-independent
spread per component (the Gaussian policy's form, K times) did not help (0.04: a component
still shrinks onto its own pairs).  So the floor is e^-2, about 0.14 of the [-1, 1] action
range: chapter 04's mixture rows need a mixture BC that matches plain BC before its DC is
judged, and the stored evidence that it now can is the ``modes`` cells' match records.  The first Table I grid ran at e^-5 (``FIRST_GRID_LOG_STD_MIN``) and stays stored
as it ran.  ``tests/test_mixture.py`` checks the floor's effect on a small regression.
"""

from __future__ import annotations

import math
from typing import Sequence

import torch
from torch import nn

from dc_lesson.nn import policies as _policies
from dc_lesson.nn.policies import (ACTION_HIGH, ACTION_LOW, RunningNorm, _Normalised, layer_init,
                                   mlp)

LOG_STD_MIN, LOG_STD_MAX = -2.0, 1.0
FIRST_GRID_LOG_STD_MIN = -5.0   # the floor the first Table I grid's mixture rows ran with


class MixturePolicy(_Normalised):
    """pi(a | s): a mixture of ``n_components`` state-dependent diagonal Gaussians."""

    gaussian = False     # its spreads are network outputs: no log_std parameter

    def __init__(self, obs_dim: int, act_dim: int, n_components: int = 4,
                 hidden: Sequence[int] = (64, 64), activation: str = "tanh",
                 log_std_init: float = -0.5, norm_obs: bool = False,
                 log_std_min: float = LOG_STD_MIN):
        super().__init__()
        if n_components < 1:
            raise ValueError(f"n_components must be at least 1, got {n_components}")
        if not log_std_min < LOG_STD_MAX:
            raise ValueError(f"log_std_min must be below LOG_STD_MAX ({LOG_STD_MAX}), got "
                             f"{log_std_min}")
        self._config = dict(obs_dim=int(obs_dim), act_dim=int(act_dim),
                            n_components=int(n_components), hidden=[int(h) for h in hidden],
                            activation=activation, log_std_init=float(log_std_init),
                            norm_obs=bool(norm_obs), log_std_min=float(log_std_min))
        self.log_std_min = float(log_std_min)
        self.obs_dim, self.act_dim, self.k = int(obs_dim), int(act_dim), int(n_components)
        self.obs_norm = RunningNorm(obs_dim) if norm_obs else None
        # trunk: all but the last layer of an MLP; head: weights, means, log-stds
        width = list(hidden)[-1] if hidden else obs_dim
        self.trunk = mlp(obs_dim, hidden, width, activation, out_gain=math.sqrt(2))[:-1] \
            if hidden else nn.Identity()
        self.head = layer_init(nn.Linear(width, self.k * (1 + 2 * self.act_dim)), gain=1.0)
        with torch.no_grad():   # log-stds start at log_std_init, weights equal
            a = self.act_dim
            self.head.weight[self.k + self.k * a:].mul_(0.01)
            self.head.bias[self.k + self.k * a:].fill_(float(log_std_init))
            self.head.weight[:self.k].mul_(0.01)
        self.log_std = None   # no single log-std: DC averages every parameter of a mixture

    def components(self, obs: torch.Tensor):
        """(log-weights (B, K), means (B, K, A), log-stds (B, K, A))."""
        h = self.trunk(self.normalise(obs))
        out = self.head(h)
        k, a = self.k, self.act_dim
        logits = out[..., :k]
        mu = out[..., k:k + k * a].reshape(*out.shape[:-1], k, a)
        log_std = out[..., k + k * a:].reshape(*out.shape[:-1], k, a)
        log_std = log_std.clamp(self.log_std_min, LOG_STD_MAX)
        return torch.log_softmax(logits, dim=-1), mu, log_std

    def log_prob(self, obs: torch.Tensor, act: torch.Tensor) -> torch.Tensor:
        """log pi(act | obs): shape (B,)."""
        log_w, mu, log_std = self.components(obs)
        act = torch.as_tensor(act, dtype=torch.float32).unsqueeze(-2)        # (B, 1, A)
        z = (act - mu) / log_std.exp()
        comp = (-0.5 * z.pow(2) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)   # (B, K)
        return torch.logsumexp(log_w + comp, dim=-1)

    def sample(self, obs: torch.Tensor, generator: torch.Generator | None = None,
               noise: bool = True) -> torch.Tensor:
        """A raw (unclipped) action: a component by its weight, then its Gaussian (with
        ``noise=False``, the chosen component's mean: :class:`ComponentMeans`)."""
        log_w, mu, log_std = self.components(obs)
        u = torch.rand(log_w.shape[:-1] + (1,), generator=generator)
        k = torch.searchsorted(log_w.exp().cumsum(-1).clamp(max=1.0), u).clamp(max=self.k - 1)
        idx = k[..., None].expand(*k.shape, self.act_dim)                    # (B, 1, A)
        m = mu.gather(-2, idx).squeeze(-2)
        if not noise:
            return m
        s = log_std.gather(-2, idx).squeeze(-2).exp()
        noise = torch.randn(m.shape, generator=generator, dtype=m.dtype)
        return m + s * noise

    def mode_action(self, obs: torch.Tensor) -> torch.Tensor:
        """The mean of the most probable component (unclipped)."""
        log_w, mu, _ = self.components(obs)
        k = log_w.argmax(-1)
        return mu.gather(-2, k[..., None, None].expand(*k.shape, 1, self.act_dim)).squeeze(-2)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.mode_action(obs)

    def act(self, obs: torch.Tensor, deterministic: bool = True,
            generator: torch.Generator | None = None) -> torch.Tensor:
        a = self.mode_action(obs) if deterministic else self.sample(obs, generator)
        return a.clamp(ACTION_LOW, ACTION_HIGH)

    def entropy(self, obs: torch.Tensor, generator: torch.Generator | None = None):
        """A one-sample Monte Carlo estimate of the entropy per state (for logs only)."""
        with torch.no_grad():
            a = self.sample(obs, generator)
        return -self.log_prob(obs, a)


class ComponentMeans:
    """A numpy batch policy that, at every step and in every environment, draws a component of
    a :class:`MixturePolicy` by its weight at that state and acts with that component's mean
    (clipped to the bounds), from its own seeded generator.

    Why: the mixture's sampled actions add its component spread, which the floor keeps at
    e^-2 or more; on a reacher that noise can stop the arm arriving anywhere (the first
    ``modes`` reacher4 ``bc-mix`` cell, seed 0: 96% of its sampled episodes arrived nowhere,
    4% of its mean-action ones), so sampled actions cannot tell whether the mixture holds
    several modes.  The mean action (the most
    probable component) picks one mode per state by construction.  Drawing the component
    and dropping only the within-component noise asks the mode question of the mixture's
    weights: does it put weight on several modes where the expert went to several?  For a
    Gaussian policy (one component) it is the mean action."""

    def __init__(self, policy: MixturePolicy, seed: int = 0):
        self.policy = policy
        self.generator = torch.Generator().manual_seed(int(seed))

    def __call__(self, obs):
        with torch.no_grad():
            a = self.policy.sample(torch.as_tensor(obs, dtype=torch.float32), self.generator,
                                   noise=False)
        return a.clamp(ACTION_LOW, ACTION_HIGH).numpy()


_policies._CLASSES["MixturePolicy"] = MixturePolicy   # save_policy / load_policy know it

__all__ = ["ComponentMeans", "FIRST_GRID_LOG_STD_MIN", "LOG_STD_MAX", "LOG_STD_MIN",
           "MixturePolicy"]
