"""What each objective does to the modes, on a toy you can run in seconds (chapter 04).

The target p is a 1-D mixture of two Gaussians, N(-2, 0.5^2) and N(+2, 0.5^2) with equal
weights: the expert with two modes.  A learner q (a Gaussian, or a mixture of two) is fitted by
gradient descent on one of three objectives:

=====================  ==============================  =========================================
objective              minimised                       where it appears
=====================  ==============================  =========================================
``forward_kl``         KL(p || q) = -E_p[log q] + c     BC (Eq. 1): maximum likelihood on p's
                                                        samples: mass-covering
``reverse_kl``         KL(q || p) = E_q[log q - log p]  the entropy-regularised RL view of GAIL:
                                                        mode-seeking
``cross_entropy``      -E_q[log p]                      DC's RL term, E over the learner's
                                                        states of log P(s), without an entropy
                                                        term: collapses onto a point
=====================  ==============================  =========================================

For a fixed p, E_q[log p] is maximised by a point mass at p's highest point: nothing in the
objective rewards covering the second mode.  The forward KL punishes q for missing mass where p
has it, so a Gaussian q spreads over both modes (and puts its peak between them, where p has
none), and a mixture q puts one component on each.  The reverse KL pays for q's own entropy,
so q keeps a width, but it stays on one mode.

Expectations under q are taken by the reparameterisation trick with fixed standard-normal
draws (for a mixture, per component, weighted by the component weights, which keeps the
weights differentiable), so a run is deterministic.
"""

from __future__ import annotations

import dataclasses
import math

import torch

MODES = (-2.0, 2.0)
MODE_STD = 0.5
OBJECTIVES = ("forward_kl", "reverse_kl", "cross_entropy")
FAMILIES = ("gaussian", "mixture")


def log_p(x: torch.Tensor) -> torch.Tensor:
    """The target's log-density."""
    comps = torch.stack([-0.5 * ((x - m) / MODE_STD) ** 2 for m in MODES], -1)
    return torch.logsumexp(comps, -1) - math.log(len(MODES) * MODE_STD * math.sqrt(2 * math.pi))


def sample_p(n: int, generator: torch.Generator) -> torch.Tensor:
    k = torch.randint(len(MODES), (n,), generator=generator)
    return torch.tensor(MODES)[k] + MODE_STD * torch.randn(n, generator=generator)


@dataclasses.dataclass
class ToyResult:
    family: str
    objective: str
    weights: list[float]      # component weights (one for a Gaussian)
    means: list[float]
    stds: list[float]
    mass_near: list[float]    # q's probability within 1 of each of p's modes
    curve: list[float]        # the objective every 20 steps


def _q_params(family: str, generator: torch.Generator):
    k = 1 if family == "gaussian" else 2
    # starts off-centre (so symmetry does not decide) and narrow
    means = torch.tensor([0.3, -0.1][:k]) + 0.1 * torch.randn(k, generator=generator)
    return [torch.zeros(k, requires_grad=True), means.requires_grad_(True),
            torch.full((k,), math.log(0.5), requires_grad=True)]


def _log_q(x, logits, means, log_stds):
    z = (x[..., None] - means) / log_stds.exp()
    comps = -0.5 * z ** 2 - log_stds - 0.5 * math.log(2 * math.pi)
    return torch.logsumexp(torch.log_softmax(logits, -1) + comps, -1)


def fit(family: str, objective: str, steps: int = 1500, n: int = 2048, lr: float = 0.03,
        seed: int = 0) -> ToyResult:
    """Fits q of ``family`` to p by ``objective`` (see the module docstring)."""
    if family not in FAMILIES or objective not in OBJECTIVES:
        raise ValueError(f"family must be one of {FAMILIES} and objective one of "
                         f"{OBJECTIVES}; got {family!r}, {objective!r}")
    g = torch.Generator().manual_seed(seed)
    params = _q_params(family, g)
    logits, means, log_stds = params
    opt = torch.optim.Adam(params, lr=lr)
    x_p = sample_p(n, g)
    eps = torch.randn(n, generator=g)
    curve = []
    for step in range(steps):
        if objective == "forward_kl":
            loss = -_log_q(x_p, logits, means, log_stds).mean()
        else:
            w = torch.softmax(logits, -1)
            x_q = means[None] + log_stds.exp()[None] * eps[:, None]          # (n, K)
            f = -log_p(x_q)
            if objective == "reverse_kl":
                f = f + _log_q(x_q, logits, means, log_stds)
            loss = (f.mean(0) * w).sum()
        opt.zero_grad()
        loss.backward()
        opt.step()
        with torch.no_grad():
            log_stds.clamp_(min=math.log(1e-3))
        if step % 20 == 0:
            curve.append(float(loss.detach()))
    with torch.no_grad():
        w = torch.softmax(logits, -1)
        s = log_stds.exp()
        near = []
        for m in MODES:   # q's mass within 1 of the mode: sum_k w_k P(|x - m| < 1)
            cdf = lambda v: 0.5 * (1 + torch.erf((v - means) / (s * math.sqrt(2))))  # noqa: E731
            near.append(float((w * (cdf(m + 1.0) - cdf(m - 1.0))).sum()))
    return ToyResult(family, objective, w.tolist(), means.tolist(), s.tolist(), near, curve)


def table(steps: int = 1500, seed: int = 0) -> list[ToyResult]:
    """Every family under every objective."""
    return [fit(f, o, steps=steps, seed=seed) for f in FAMILIES for o in OBJECTIVES]


def covers_both(result: ToyResult, threshold: float = 0.25) -> bool:
    """q puts at least ``threshold`` of its mass near each of p's modes."""
    return min(result.mass_near) >= threshold


__all__ = ["FAMILIES", "MODES", "OBJECTIVES", "ToyResult", "covers_both", "fit", "log_p",
           "sample_p", "table"]
