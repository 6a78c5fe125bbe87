"""Gaussian policies and value networks for the on-policy algorithms (PPO, and DC on top of it).

* :class:`GaussianPolicy`: an MLP for the action mean and one learned, state-independent
  log-std per action dimension (``log_std``), as in CleanRL's ``ppo_continuous_action.py``;
* :class:`ValueNetwork`: an MLP for the state value;
* :class:`RunningNorm`: an optional observation normaliser kept *inside* a network as buffers,
  so a saved ``state_dict`` carries it and a loaded policy needs nothing else;
* :class:`StochasticPolicy`: a numpy batch policy that samples from a :class:`GaussianPolicy`
  with its own seeded generator, for stochastic rollouts with :func:`dc_lesson.data.rollout.collect`
  (passing the policy itself gives the deterministic mean);
* :func:`save_policy` / :func:`load_policy`: a small, atomically written file with the weights,
  the constructor arguments and JSON metadata, loaded with ``torch.load(weights_only=True)``.

Actions live in [-1, 1] (the bounds of every task port): :meth:`GaussianPolicy.act` clips to
them, while :meth:`GaussianPolicy.sample` returns the raw, unclipped sample whose log-probability
PPO needs.
"""

from __future__ import annotations

import json
import math
import pathlib
from typing import Sequence

import numpy as np
import torch
from torch import nn

from dc_lesson.nn.checkpoint import (ModelFileError, PolicyFileError, atomic_torch_save,
                                     load_checked)

ACTIVATIONS = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "silu": nn.SiLU}

ACTION_LOW, ACTION_HIGH = -1.0, 1.0   # the action bounds of every task port
_LOG_SQRT_2PI = math.log(math.sqrt(2 * math.pi))   # torch.distributions.Normal's constant


# -- building blocks -----------------------------------------------------------------------------

def layer_init(layer: nn.Linear, gain: float = math.sqrt(2), bias: float = 0.0) -> nn.Linear:
    """Orthogonal weights and constant bias (CleanRL's ``layer_init``)."""
    nn.init.orthogonal_(layer.weight, gain)
    nn.init.constant_(layer.bias, bias)
    return layer


def mlp(in_dim: int, hidden: Sequence[int], out_dim: int, activation: str,
        out_gain: float) -> nn.Sequential:
    """Linear-activation stacks with sqrt(2) gain, then a linear output layer with ``out_gain``."""
    if activation not in ACTIVATIONS:
        raise ValueError(f"unknown activation {activation!r}; choose one of "
                         f"{', '.join(ACTIVATIONS)}")
    layers, d = [], in_dim
    for h in hidden:
        layers += [layer_init(nn.Linear(d, h)), ACTIVATIONS[activation]()]
        d = h
    layers.append(layer_init(nn.Linear(d, out_dim), gain=out_gain))
    return nn.Sequential(*layers)


class RunningNorm(nn.Module):
    """Observation normaliser: running mean and variance kept as buffers.

    ``forward`` only applies the statistics; :meth:`update` changes them.  Keeping the two apart
    lets PPO freeze the statistics while it collects a batch and while it learns from it, so the
    log-probabilities it compares are computed on the same inputs.
    """

    def __init__(self, dim: int, clip: float = 10.0, eps: float = 1e-8):
        super().__init__()
        self.clip, self.eps = clip, eps
        self.register_buffer("mean", torch.zeros(dim, dtype=torch.float64))
        self.register_buffer("var", torch.ones(dim, dtype=torch.float64))
        # A tiny prior count (as in CleanRL's RunningMeanStd) so the first update is well defined.
        self.register_buffer("count", torch.tensor(1e-4, dtype=torch.float64))

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        """Merges a batch of observations (..., dim) into the statistics (Chan et al.)."""
        x = torch.as_tensor(x, dtype=torch.float64).reshape(-1, self.mean.numel())
        b_mean, b_var, b_count = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        delta, total = b_mean - self.mean, self.count + b_count
        m2 = self.var * self.count + b_var * b_count + delta ** 2 * self.count * b_count / total
        self.mean += delta * b_count / total
        self.var.copy_(m2 / total)
        self.count.copy_(total)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = (x.to(torch.float64) - self.mean) / torch.sqrt(self.var + self.eps)
        return z.clamp(-self.clip, self.clip).to(x.dtype)


class _Normalised(nn.Module):
    """Shared by both networks: the optional normaliser and the constructor record."""

    obs_norm: RunningNorm | None

    def normalise(self, obs: torch.Tensor) -> torch.Tensor:
        """The network's input: ``obs`` as float32, through the normaliser if it has one."""
        obs = torch.as_tensor(obs, dtype=torch.float32)
        return obs if self.obs_norm is None else self.obs_norm(obs)

    def update_obs_norm(self, obs) -> None:
        """Adds observations to the normaliser's statistics (nothing without a normaliser)."""
        if self.obs_norm is not None:
            self.obs_norm.update(obs)

    def config(self) -> dict:
        """The constructor arguments, JSON-able: ``type(self)(**self.config())`` rebuilds it."""
        return dict(self._config)


# -- the networks --------------------------------------------------------------------------------

class GaussianPolicy(_Normalised):
    """pi(a | s) = N(mean(s), diag(exp(log_std))^2), independent per action dimension."""

    # One Gaussian whose spread is the parameter ``log_std``, not a network output: what the
    # learners ask before they touch ``log_std`` (a MixturePolicy answers False).
    gaussian = True

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (64, 64),
                 activation: str = "tanh", log_std_init: float = -0.5, norm_obs: bool = False):
        super().__init__()
        self._config = dict(obs_dim=int(obs_dim), act_dim=int(act_dim),
                            hidden=[int(h) for h in hidden], activation=activation,
                            log_std_init=float(log_std_init), norm_obs=bool(norm_obs))
        self.obs_dim, self.act_dim = int(obs_dim), int(act_dim)
        self.obs_norm = RunningNorm(obs_dim) if norm_obs else None
        # A small last layer starts every action mean near 0, so early behaviour is the noise.
        self.mean_net = mlp(obs_dim, hidden, act_dim, activation, out_gain=0.01)
        self.log_std = nn.Parameter(torch.full((act_dim,), float(log_std_init)))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """The action mean (unclipped)."""
        return self.mean_net(self.normalise(obs))

    def distribution(self, obs: torch.Tensor) -> torch.distributions.Normal:
        mean = self(obs)
        # Argument validation (finite mean, positive scale: true by construction here) costs
        # more than the rest of a minibatch step on small nets; skipped on the fast path.
        from dc_lesson.nn import fast
        return torch.distributions.Normal(mean, self.log_std.exp().expand_as(mean),
                                          validate_args=not fast.enabled())

    def log_prob_entropy(self, z: torch.Tensor, act: torch.Tensor):
        """``(log pi(act | s), entropy of pi(. | s))``, each summed over the action dimensions
        (shape (B,)), for inputs ``z = normalise(obs)``.

        What ``distribution(obs).log_prob(act).sum(-1)`` and ``.entropy().sum(-1)`` give:
        torch's Normal formulas in its order of operations, one ``scale`` tensor for both (so
        the same bits and the same gradients, ``tests/test_ppo.py``), without building a
        ``Normal`` per call, which on these small networks costs more than its arithmetic.
        PPO's update calls this once per minibatch step; taking ``z`` lets it normalise a
        batch once (the normaliser is frozen during an update), not once per minibatch.
        """
        mean = self.mean_net(z)
        scale = self.log_std.exp().expand_as(mean)
        var = scale ** 2
        log_scale = scale.log()
        logp = -((act - mean) ** 2) / (2 * var) - log_scale - _LOG_SQRT_2PI
        entropy = 0.5 + 0.5 * math.log(2 * math.pi) + torch.log(scale)
        return logp.sum(-1), entropy.sum(-1)

    def log_prob(self, obs: torch.Tensor, act: torch.Tensor) -> torch.Tensor:
        """log pi(act | obs), summed over the action dimensions: shape (B,)."""
        return self.distribution(obs).log_prob(torch.as_tensor(act, dtype=torch.float32)).sum(-1)

    def sample(self, obs: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """A raw (unclipped) action sample, drawn from ``generator`` for reproducibility."""
        dist = self.distribution(obs)
        noise = torch.randn(dist.mean.shape, generator=generator, dtype=dist.mean.dtype)
        return dist.mean + dist.stddev * noise

    def act(self, obs: torch.Tensor, deterministic: bool = True,
            generator: torch.Generator | None = None) -> torch.Tensor:
        """The action to apply, clipped to the bounds: the mean, or a sample.

        ``rollout.collect`` calls ``act(obs)``, so passing a policy to it runs the mean.
        """
        a = self(obs) if deterministic else self.sample(obs, generator)
        return a.clamp(ACTION_LOW, ACTION_HIGH)

    def act_numpy(self, obs: np.ndarray) -> np.ndarray:
        """``act(obs)`` (the clipped mean) for a NumPy batch, as rollouts call it: through
        :mod:`dc_lesson.nn.fast` unless that is switched off."""
        from dc_lesson.nn import fast
        if fast.enabled():
            return np.clip(fast.snapshot(self)(obs), ACTION_LOW, ACTION_HIGH)
        with torch.no_grad():
            return self.act(torch.as_tensor(obs, dtype=torch.float32)).numpy()


class ValueNetwork(_Normalised):
    """V(s): an MLP with one output, for PPO's advantages."""

    def __init__(self, obs_dim: int, hidden: Sequence[int] = (64, 64), activation: str = "tanh",
                 norm_obs: bool = False):
        super().__init__()
        self._config = dict(obs_dim=int(obs_dim), hidden=[int(h) for h in hidden],
                            activation=activation, norm_obs=bool(norm_obs))
        self.obs_norm = RunningNorm(obs_dim) if norm_obs else None
        self.net = mlp(obs_dim, hidden, 1, activation, out_gain=1.0)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """Values, shape (...,) for observations (..., obs_dim)."""
        return self.net(self.normalise(obs)).squeeze(-1)

    def value_of(self, z: torch.Tensor) -> torch.Tensor:
        """Values for inputs ``z = normalise(obs)`` (see ``GaussianPolicy.log_prob_entropy``)."""
        return self.net(z).squeeze(-1)


class StochasticPolicy:
    """A numpy batch policy that samples from a :class:`GaussianPolicy` (clipped to the bounds),
    with its own seeded generator, so ``collect(task, StochasticPolicy(pi, seed=1), ...)``
    gives the same stochastic episodes every time."""

    def __init__(self, policy: GaussianPolicy, seed: int = 0):
        self.policy = policy
        self.generator = torch.Generator().manual_seed(int(seed))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        from dc_lesson.nn import fast
        if fast.enabled() and isinstance(self.policy, GaussianPolicy):   # the same noise, the mean in NumPy (dc_lesson.nn.fast)
            a, _ = fast.snapshot(self.policy, fast.GaussianSampler)(obs, self.generator)
            return np.clip(a, ACTION_LOW, ACTION_HIGH)
        with torch.no_grad():
            a = self.policy.act(torch.as_tensor(obs, dtype=torch.float32), deterministic=False,
                                generator=self.generator)
        return a.numpy()


# -- files ---------------------------------------------------------------------------------------

POLICY_FORMAT = "dc_lesson.policy"
POLICY_VERSION = 1
_CLASSES = {"GaussianPolicy": GaussianPolicy, "ValueNetwork": ValueNetwork}


def save_policy(policy: GaussianPolicy | ValueNetwork, path, meta: dict | None = None
                ) -> pathlib.Path:
    """Saves weights, constructor arguments and JSON-able ``meta`` (task, algorithm, ...)."""
    cls = type(policy).__name__
    if cls not in _CLASSES:
        raise TypeError(f"save_policy saves {' or '.join(_CLASSES)}, not {cls}")
    try:
        meta_json = json.dumps(meta or {})
    except TypeError as e:
        raise TypeError(f"policy metadata must be JSON-able: {e}") from None
    return atomic_torch_save({"format": POLICY_FORMAT, "version": POLICY_VERSION, "class": cls,
                              "args": json.dumps(policy.config()), "meta": meta_json,
                              "state_dict": policy.state_dict()}, path)


def load_policy(path, fix: str | None = None) -> GaussianPolicy | ValueNetwork:
    """Rebuilds a saved network (in eval mode); its metadata is in the ``meta`` attribute.

    The file's sha256 is checked first (:func:`~dc_lesson.nn.checkpoint.load_checked`);
    ``fix``, the command that makes the file again, goes into every error."""
    obj = load_checked(path, POLICY_FORMAT, POLICY_VERSION, "policy", fix)
    try:
        cls = _CLASSES[obj["class"]]
        net = cls(**json.loads(obj["args"]))
        net.load_state_dict(obj["state_dict"])
        meta = json.loads(obj["meta"])
    except (KeyError, TypeError, ValueError, RuntimeError) as e:
        raise PolicyFileError(f"policy file {path} is inconsistent "
                              f"({type(e).__name__}: {e}); "
                              f"{fix or 'delete it and rerun the command that wrote it'}"
                              ) from None
    net.meta = meta
    return net.eval()


__all__ = ["ACTIVATIONS", "GaussianPolicy", "ModelFileError", "PolicyFileError", "RunningNorm",
           "StochasticPolicy", "ValueNetwork", "atomic_torch_save", "layer_init",
           "load_checked", "load_policy", "mlp", "save_policy"]
