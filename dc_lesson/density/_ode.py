"""SoftFlow's dynamics network and its ODE solves (:mod:`dc_lesson.density.softflow` is the
flow that uses them; its docstring gives the equations).

f(t, z, noise input) is a stack of concat-squash layers with tanh between (:class:`ODENet`);
:class:`_Dynamics` augments it with the trace of its Jacobian for torchdiffeq; :func:`solve`
and :func:`solve_path` integrate it, fixed-step solvers stepping exactly onto every output time.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import torch
from torch import nn
from torchdiffeq import odeint

from dc_lesson.density import _trace

FIXED_STEP_SOLVERS = ("euler", "midpoint", "heun3", "rk4")
ADAPTIVE_SOLVERS = ("dopri5", "dopri8", "bosh3", "fehlberg2", "adaptive_heun")
LOG_2PI = math.log(2 * math.pi)


class FlowTrainingError(RuntimeError):
    """Training that cannot go on: a non-finite loss or gradient, or a solver that gave up."""


# -- the dynamics network ------------------------------------------------------------------------

class ConcatSquashLinear(nn.Module):
    """h -> (W h + b) * sigmoid(gate(ctx)) + hyper_bias(ctx), ctx = (t, noise input)."""

    def __init__(self, d_in: int, d_out: int, d_ctx: int = 2):
        super().__init__()
        self.layer = nn.Linear(d_in, d_out)
        self.hyper_gate = nn.Linear(d_ctx, d_out)
        self.hyper_bias = nn.Linear(d_ctx, d_out, bias=False)

    def forward(self, ctx: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        return self.layer(h) * torch.sigmoid(self.hyper_gate(ctx)) + self.hyper_bias(ctx)


class ODENet(nn.Module):
    """f(t, z, noise input): concat-squash layers ``dim -> hidden... -> dim`` with tanh between.

    :meth:`forward` is the plain definition (used by the naive reference and by ``torch.func``);
    :meth:`evaluate` computes the same f together with the exact trace or a Hutchinson estimate
    of its Jacobian, by carrying derivatives forward through the layers (see the module's
    docstring).
    """

    def __init__(self, dim: int, hidden: Sequence[int], tanh: str = "torch"):
        super().__init__()
        self.tanh_kernel = tanh   # evaluate()'s tanh; forward() keeps torch's (the reference)
        dims = [int(dim), *(int(h) for h in hidden), int(dim)]
        self.layers = nn.ModuleList(ConcatSquashLinear(a, b) for a, b in zip(dims[:-1], dims[1:]))

    def forward(self, t: torch.Tensor, z: torch.Tensor, noise_in: torch.Tensor) -> torch.Tensor:
        """f for states z (B, D) and noise inputs (B,) or (1,), at the scalar time t."""
        noise_in = noise_in.reshape(-1, 1).to(z.dtype)
        ctx = torch.cat([torch.as_tensor(t, dtype=z.dtype).reshape(1, 1).expand_as(noise_in),
                         noise_in], dim=1)
        h = z
        for k, layer in enumerate(self.layers):
            h = layer(ctx, h)
            if k < len(self.layers) - 1:
                h = torch.tanh(h)
        return h

    def context(self, noise_in: torch.Tensor) -> list:
        """The noise level's part of every gate and hyper-bias, computed once per ODE solve
        (see :func:`dc_lesson.density._trace.context`)."""
        return _trace.context(self, noise_in)

    def evaluate(self, t: torch.Tensor, z: torch.Tensor, context: list, trace: str | None = None,
                 probe: torch.Tensor | None = None, workspace: dict | None = None):
        """Returns ``(f, tr)``: f (B, D) and, per state, the exact trace of df/dz
        (``trace="exact"``), the estimate ``e^T (df/dz) e`` for the probe e
        (``trace="hutchinson"``), or None (``trace=None``).  The derivatives are carried
        forward through the layers by the kernels of :mod:`dc_lesson.density._trace`;
        ``workspace`` keeps their buffers from one call to the next (without autograd)."""
        return _trace.evaluate(self, t, z, context, trace, probe, workspace)


def jacobian_trace_autodiff(net: ODENet, t: torch.Tensor, z: torch.Tensor,
                            noise_in: torch.Tensor) -> torch.Tensor:
    """tr(df/dz) per state with ``torch.func``: ``vmap`` over the batch of ``jacfwd``.

    An independent check of :meth:`ODENet.evaluate` (and the ``"exact_autodiff"`` trace).
    """
    from torch.func import jacfwd, vmap
    noise_in = noise_in.reshape(-1).expand(len(z))

    def f_one(z1, s1):
        return net(t, z1.unsqueeze(0), s1.reshape(1))[0]

    jac = vmap(jacfwd(f_one, argnums=0))(z, noise_in)     # (B, D, D)
    return jac.diagonal(dim1=-2, dim2=-1).sum(-1)


class _Dynamics(nn.Module):
    """The augmented ODE (z, delta): dz/dt = f, d delta/dt = tr(df/dz), for torchdiffeq."""

    def __init__(self, net: ODENet, noise_in: torch.Tensor, trace: str | None,
                 probe: torch.Tensor | None = None):
        super().__init__()
        self.net, self.noise_in, self.trace, self.probe = net, noise_in, trace, probe
        self.context = net.context(noise_in)
        self.workspace: dict = {}     # the exact trace's buffers, reused along the solve
        self.nfe = 0

    def forward(self, t, state):
        self.nfe += 1
        z = state[0]
        if self.trace == "exact_autodiff":
            with torch.enable_grad():
                f = self.net(t, z, self.noise_in)
                tr = jacobian_trace_autodiff(self.net, t, z, self.noise_in)
            return f, tr
        f, tr = self.net.evaluate(t, z, self.context, self.trace, self.probe, self.workspace)
        return (f,) if tr is None else (f, tr)


def solve(func, y0: tuple, t0: float, t1: float, solver: str, step_size: float, rtol: float,
           atol: float, max_num_steps: int | None = None):
    """torchdiffeq's odeint from t0 to t1; returns the state at t1 (a tuple)."""
    out = solve_path(func, y0, [t0, t1], solver, step_size, rtol, atol, max_num_steps)
    return tuple(x[-1] for x in out)


def solve_path(func, y0: tuple, times: Sequence[float], solver: str, step_size: float,
                rtol: float, atol: float, max_num_steps: int | None = None):
    """torchdiffeq's odeint with outputs at ``times`` (a tuple of (len(times), ...) tensors).

    A fixed-step solver steps exactly onto every output time (each interval between two of
    them is cut into equal steps of at most ``step_size``), so no output is interpolated.
    """
    dtype = y0[0].dtype
    ts = torch.tensor(list(times), dtype=dtype)
    if solver in FIXED_STEP_SOLVERS:
        if len(ts) == 2:
            return odeint(func, y0, ts, method=solver, options={"step_size": step_size})
        pieces = [ts[:1]]
        for a, b in zip(ts[:-1], ts[1:]):
            n = max(1, math.ceil(abs(float(b - a)) / step_size - 1e-9))
            seg = torch.linspace(float(a), float(b), n + 1, dtype=dtype)
            seg[-1] = b
            pieces.append(seg[1:])
        grid = torch.cat(pieces)
        return odeint(func, y0, ts, method=solver,
                      options={"grid_constructor": lambda f, y, t: grid})
    options = {} if max_num_steps is None else {"max_num_steps": int(max_num_steps)}
    try:
        return odeint(func, y0, ts, method=solver, rtol=rtol, atol=atol, options=options)
    except AssertionError as e:  # torchdiffeq signals max_num_steps and dt underflow so
        raise FlowTrainingError(
            f"the {solver} solver gave up ({e}): the dynamics are too stiff for rtol={rtol}, "
            f"atol={atol}. Lower the learning rate, use SoftFlow's noise, or a fixed-step "
            f"solver") from None


def gauss_legendre(k: int) -> tuple[list[float], list[float]]:
    """Nodes and weights of the k-point Gauss-Legendre rule on [0, 1] (exact for polynomials
    of degree 2k - 1)."""
    x, w = np.polynomial.legendre.leggauss(int(k))
    return [float(v) for v in (x + 1) / 2], [float(v) for v in w / 2]


def standard_normal_logpdf(z: torch.Tensor) -> torch.Tensor:
    return -0.5 * (z * z).sum(-1) - 0.5 * z.shape[-1] * LOG_2PI
