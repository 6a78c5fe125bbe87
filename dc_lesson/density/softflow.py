r"""SoftFlow: a noise-conditioned continuous normalizing flow for the state density P(s).

DC's stage 1 fits the density of the states the expert (and later the learner) visited, and
stage 2 uses ``log P(s)`` as a reward.  This module fits that density with SoftFlow (Kim et al.,
NeurIPS 2020), a continuous normalizing flow (FFJORD, Grathwohl et al., ICLR 2019) trained on
data perturbed with noise of a random, known level.

**Change of variables.**  If ``z = phi(x)`` is a smooth bijection of R^D and ``z ~ p_z``, then

    log p_x(x) = log p_z(phi(x)) + log |det d phi / d x|.

A normalizing flow builds ``phi`` so that the determinant is cheap and takes ``p_z = N(0, I)``.

**The instantaneous form.**  A continuous flow defines ``phi`` as the solution at t = 1 of an ODE
``dz/dt = f(t, z)`` started at ``z(0) = x``.  Along a trajectory the log-determinant obeys

    d/dt log |det dz(t)/dx| = tr(df/dz (t, z(t))),

so, integrating z and the log-density change jointly from t = 0 to t = 1,

    log p_x(x) = log N(z(1); 0, I) + integral_0^1 tr(df/dz) dt.           (*)

Any network f gives a valid density: no triangular Jacobians, no restrictions on the layers.
Sampling runs the same ODE backwards from ``z(1) ~ N(0, I)``.  The price is the trace: exactly, D
Jacobian-vector products per evaluation of f; Hutchinson's estimator ``tr(J) = E[e^T J e]``
(``e`` Rademacher or Gaussian) needs one, is unbiased, and is what FFJORD trains with.

**Why a flow struggles with data on a lower-dimensional manifold.**  Expert states are far from
filling R^D: a cartpole balancing at the top has ``cos(angle)`` pinned near 1, a reacher's
fingertip is a function of its joint angles, whole trajectories trace out curves.  The density of
such data is degenerate: zero off the manifold, infinite on it.  A flow is a diffeomorphism of
R^D and cannot map N(0, I) onto a set of measure zero, so maximum likelihood drives it towards a
singular map: it squeezes the volume across the manifold without end, the dynamics get stiff
(an adaptive solver takes ever more steps), the training likelihood keeps rising while the density
just off the manifold collapses, and a state a hair away from the training states - exactly what
a learner visits - is given a terrible log-density.  As a reward that is a cliff, not a slope.

**SoftFlow's fix.**  Perturb each training state with Gaussian noise of a random standard
deviation ``sigma ~ U[0, sigma_max]`` and tell the network the level: it learns the conditional
density ``p(x + sigma * eps | sigma)``.  For sigma > 0 the perturbed data fill R^D, so the problem
is well posed; because one network sees every level, what it learns at small sigma is smoothed
by what it learns at larger ones.  The density is then evaluated at sigma = 0 (SoftFlow samples at
sigma = 0, too), which stays close to the manifold without the singular squeeze.  With
``noise_conditioned=False`` the same network is trained as a plain CNF on the clean data (its
noise input is held at 0), for comparison.

**Computing the exact trace fast.**  The dynamics (:class:`ODENet`, with its ODE solves in
:mod:`dc_lesson.density._ode`) are a stack of concat-squash layers,

    h_k = tanh(a_k),  a_k = (W_k h_{k-1} + b_k) * g_k(t, sigma) + c_k(t, sigma),
    f   = (W_L h_{L-1} + b_L) * g_L(t, sigma) + c_L(t, sigma),

with the gate ``g_k = sigmoid(linear(t, sigma))`` and the hyper-bias ``c_k = linear(t, sigma)``
(FFJORD's ``ConcatSquashLinear``; SoftFlow adds sigma to the context).  Their Jacobian is a
product of known matrices, ``df/dz = diag(g_L) W_L diag(s_{L-1}) W_{L-1} ... diag(s_1) W_1`` with
``s_k = (1 - h_k^2) * g_k``.  The naive exact trace is a Python loop of D reverse-mode passes,
one per ``d f_i / d z_i``.  Here, instead:

1. *Forward mode by hand, batched.*  The forward pass carries the Jacobian along as one
   (batch, D, width) tensor, ``M <- (M @ W_k^T) * s_k`` (a single 2-D matrix product per layer
   for the whole batch), and ``tr = sum_i g_L,i <W_L[i], M[:, i]>``.  No autograd graph under
   ``torch.no_grad`` (the reward path), yet differentiable for training with the exact trace.
   When every state has the same noise level (always so in ``log_prob``) the gates are folded
   into the weights, and the first and last layers are grouped into products against small
   constant tensors (:func:`dc_lesson.density._trace.exact_trace_folded`), with buffers reused across evaluations.
   Same arithmetic as the naive loop; about 1.8x faster than it at D = 17, batch 2048.
2. *The trace only where it is needed.*  Equation (*) needs the trace integrated along the
   path, not at every stage of the solver.  ``log_prob`` integrates z alone (f without the
   trace is about 6x cheaper) and evaluates the trace at the k nodes of a Gauss-Legendre rule
   on [0, 1] (exact for polynomials of degree 2k - 1 in t): 4 trace evaluations instead of 16
   to 32.  With rk4 (step 0.25) this is about 6x faster than the naive reference, within
   about 5e-4 nats of it (``dc-lesson perf softflow``).  ``quadrature=None``
   integrates the trace jointly with z, the textbook way.

Hutchinson's ``e^T J e`` uses the same forward mode with one vector instead of D (one
Jacobian-vector product, ``v <- (v @ W_k^T) * s_k``), which avoids FFJORD's double backward
(about 1.1-1.2x faster per training step).  :func:`jacobian_trace_autodiff` computes the trace
with ``torch.func`` (``vmap(jacfwd)``) as an independent check; the tests hold them together to
float precision.

``trace`` arguments: ``"exact"`` (the hand-carried Jacobian), ``"hutchinson"`` (one probe per
state, drawn once per ODE solve and held fixed along it, as the estimator requires), or ``"auto"``
(:meth:`SoftFlow.log_prob`'s default: exact when ``dim <= EXACT_TRACE_MAX_DIM``, else
Hutchinson).  ``"exact_autodiff"`` is the ``torch.func`` version, slower, for checks.

**Choices made where the paper (and its missing code) is silent** - each a knob of
:class:`SoftFlowConfig` or of :class:`SoftFlow`:

* States are standardised per dimension with the mean and standard deviation of the first fit's
  data (standard deviations floored at ``std_floor`` = 1e-3, so a constant dimension - cartpole's
  ``cos(angle)`` varies by 4e-5 - does not divide by zero).  The statistics are buffers of the
  model, saved with it; :meth:`SoftFlow.log_prob` returns the density of the *original* states,
  ``log p_u(u) - sum(log std)``.  :func:`fit_more` keeps them fixed (DC refits P_w every loop on
  new learner states, and the reward must stay comparable from loop to loop).
* ``sigma_max = 0.1`` (the paper's appendix: "a noise level ranges from 0 to 0.1") is read as a
  standard deviation on the standardised states.  The level enters the network as
  ``sigma / sigma_max * 2``, in [0, 2] (SoftFlow's reference code), beside t in [0, 1].
* Learning rate 1e-3 and weight decay 1e-5 with Adam (SoftFlow's reference; weight decay as
  Adam's L2 term, not AdamW).  The paper's appendix gives 1e-4 for P_w: set ``lr`` for that.
* The hidden layers' tanh is torch's by default; ``tanh="numpy"`` (DC's setting) takes NumPy's
  SIMD kernel, about 8x cheaper here and equal to one unit in the last place (see
  :mod:`dc_lesson.density._trace`).  Stored in the flow: a saved flow evaluates as it was fitted.
* The integration time is fixed at 1 (FFJORD and SoftFlow can learn it; that adds nothing here).
* Gradients by backpropagation through the solver's steps, not the adjoint method: exact
  gradients of the computed loss, and faster at these sizes (memory is no issue on CPU).
* Training: Hutchinson's trace with Rademacher probes and dopri5 at rtol = atol = 1e-5 by default
  (the reference solver; a fixed-step rk4 is several times cheaper per step).  Minibatches of
  512 drawn as successive slices of random permutations (epochs).  Train and evaluate with
  solvers of similar accuracy: a flow trained with very coarse fixed steps learns dynamics that
  only make sense under those steps.
* Evaluation (the reward): exact trace, no autograd; z by rk4 with steps of at most 0.25, the
  trace at 4 Gauss-Legendre nodes (``eval_*`` settings, stored in the flow).  The reference is
  dopri5 at 1e-5 with the trace integrated jointly (:meth:`SoftFlow.reference_log_prob`); compare
  the two on a trained flow's own states before trusting the fast path on stiffer dynamics.
* With an adaptive solver the step sizes are chosen for the whole batch, so a state's log-density
  depends (within the tolerance) on the other states in its batch; a fixed-step solver gives
  every state the same number whatever the batch.  ``log_prob`` splits large inputs into fixed
  chunks, so the same input always gives the same output.
* A non-finite loss or gradient stops training with :class:`FlowTrainingError` before the
  optimiser step, so the flow keeps its last finite parameters; so does a solver that exceeds
  ``max_num_steps``.  NaN or inf in the states raise ``ValueError``.

Determinism: ``config.seed`` fixes the initialisation and one ``torch.Generator`` for minibatch
order, noise levels, noise and probes; the same configuration and data give the same numbers
(on the same machine and thread count).  :func:`fit_more` seeds its generator from
``(config.seed, iterations trained so far)``, so a continued fit does not replay the first one's
noise.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
import time
from typing import Callable, Sequence

import numpy as np
import torch
from torch import nn

from dc_lesson import timing as _timing
from dc_lesson.density import _trace
from dc_lesson.density._ode import (ADAPTIVE_SOLVERS, FIXED_STEP_SOLVERS, LOG_2PI,  # noqa: F401
                                    ConcatSquashLinear, FlowTrainingError, ODENet, _Dynamics,
                                    gauss_legendre, jacobian_trace_autodiff, solve, solve_path,
                                    standard_normal_logpdf)
from dc_lesson.checks import check_fields
from dc_lesson.nn.checkpoint import PolicyFileError, atomic_torch_save, load_checked

EXACT_TRACE_MAX_DIM = 100   # "auto" uses the exact trace up to this state dimension
TRACES = ("exact", "hutchinson", "exact_autodiff")
PROBES = ("rademacher", "gaussian")


# -- configuration -------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class SoftFlowConfig:
    """Every knob of fitting a SoftFlow.  Defaults: SoftFlow's reference settings, except where
    noted."""

    hidden: tuple[int, ...] = (64, 64, 64)   # widths of the concat-squash hidden layers (tanh)
    noise_conditioned: bool = True   # SoftFlow (True) or a plain CNF on clean data (False)
    sigma_max: float = 0.1       # noise std per sample ~ U[0, sigma_max], on standardised states
    std_floor: float = 1e-3      # smallest per-dimension std used to standardise (state units)
    lr: float = 1e-3             # Adam's learning rate (the paper's appendix says 1e-4 for P_w)
    weight_decay: float = 1e-5   # Adam's L2 weight decay
    batch_size: int = 512        # states per gradient step (all of them if there are fewer)
    iterations: int = 2000       # gradient steps of fit(); fit_more() takes its own count
    max_grad_norm: float | None = None   # clip the gradient norm (None: no clipping, as SoftFlow)
    solver: str = "dopri5"       # training ODE solver: adaptive (dopri5, ...) or fixed (rk4, ...)
    step_size: float = 0.25      # step of a fixed-step training solver (1 / step_size steps)
    rtol: float = 1e-5           # relative tolerance of an adaptive training solver
    atol: float = 1e-5           # absolute tolerance of an adaptive training solver
    max_num_steps: int = 2000    # an adaptive solve taking more steps stops training (stiffness)
    trace: str = "hutchinson"    # training trace: "hutchinson" (one probe) or "exact"
    probe: str = "rademacher"    # Hutchinson probe distribution: "rademacher" or "gaussian"
    eval_solver: str = "rk4"     # log_prob / sample solver, stored in the flow
    eval_step_size: float = 0.25     # its largest step if fixed-step
    eval_rtol: float = 1e-5      # its tolerances if adaptive (dopri5 at 1e-5: the reference)
    eval_atol: float = 1e-5
    eval_quadrature: int | None = 4  # log_prob's trace at 4 Gauss-Legendre nodes (None: the
    #                                  trace integrated jointly with z, at every solver stage)
    tanh: str = "torch"          # the hidden layers' tanh kernel: "torch" or "numpy" (about
    #                              8x cheaper, equal to one ulp; DC's choice), stored in the flow
    seed: int = 0                # the one seed of the fit

    def __post_init__(self):
        check_fields(self, positive=("sigma_max", "std_floor", "lr", "batch_size",
                                     "max_grad_norm", "step_size", "rtol", "atol",
                                     "max_num_steps", "eval_step_size", "eval_rtol",
                                     "eval_atol", "eval_quadrature"),
                     non_negative=("weight_decay", "iterations", "seed"))
        _check_solver(self.solver, self.step_size)
        _check_solver(self.eval_solver, self.eval_step_size)
        if self.trace not in ("hutchinson", "exact"):
            raise ValueError(f"config.trace must be 'hutchinson' or 'exact', not {self.trace!r}")
        if self.tanh not in _trace.KERNELS:
            raise ValueError(f"config.tanh must be one of {_trace.KERNELS}, not {self.tanh!r}")
        if self.probe not in PROBES:
            raise ValueError(f"config.probe must be one of {PROBES}, not {self.probe!r}")
        if not self.sigma_max > 0:
            raise ValueError(f"sigma_max must be positive, got {self.sigma_max}")
        if self.batch_size < 1 or self.iterations < 0 or not self.hidden:
            raise ValueError("batch_size >= 1, iterations >= 0 and at least one hidden layer")

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "SoftFlowConfig":
        return cls(**json.loads(text))


def _check_solver(solver: str, step_size: float) -> None:
    if solver in FIXED_STEP_SOLVERS:
        if not 0 < step_size <= 1:
            raise ValueError(f"step size {step_size} of {solver} must be in (0, 1]")
    elif solver not in ADAPTIVE_SOLVERS:
        raise ValueError(f"unknown ODE solver {solver!r}; choose one of "
                         f"{', '.join(FIXED_STEP_SOLVERS + ADAPTIVE_SOLVERS)}")


def _check_states(states, dim: int | None, what: str) -> torch.Tensor:
    """(N, dim) float32 tensor of finite states, or a ValueError that says what is wrong."""
    if not torch.is_tensor(states):
        states = np.asarray(states)
        if not states.flags.writeable:   # read-only demonstration arrays: torch warns on them
            states = states.copy()
    x = torch.as_tensor(states)
    if x.ndim != 2 or (dim is not None and x.shape[1] != dim) or len(x) == 0:
        want = f"(N, {dim})" if dim is not None else "(N, dim)"
        raise ValueError(f"{what} must have shape {want} with N >= 1, got {tuple(x.shape)}")
    if not torch.is_floating_point(x):
        x = x.to(torch.float64)
    bad = ~torch.isfinite(x)
    if bad.any():
        rows = bad.any(1).nonzero().flatten()
        col = int(bad[rows[0]].nonzero()[0])
        raise ValueError(f"{what} contain NaN or inf: {len(rows)} of {len(x)} rows, the first "
                         f"at row {int(rows[0])}, column {col} (value {float(x[rows[0], col])})")
    return x


# -- the flow ------------------------------------------------------------------------------------

class SoftFlow(nn.Module):
    """A (noise-conditioned) continuous normalizing flow over states, standardisation included.

    Buffers: ``mean`` and ``std`` (float64, the standardisation) and ``iterations_trained``.
    ``eval_*`` are the defaults :meth:`log_prob` and :meth:`sample` integrate with.
    """

    def __init__(self, dim: int, hidden: Sequence[int] = (64, 64, 64),
                 noise_conditioned: bool = True, sigma_max: float = 0.1,
                 eval_solver: str = "rk4", eval_step_size: float = 0.25,
                 eval_rtol: float = 1e-5, eval_atol: float = 1e-5,
                 eval_quadrature: int | None = 4, tanh: str = "torch"):
        super().__init__()
        _check_solver(eval_solver, eval_step_size)
        if tanh not in _trace.KERNELS:
            raise ValueError(f"tanh must be one of {_trace.KERNELS}, not {tanh!r}")
        if not hidden:
            raise ValueError("the dynamics network needs at least one hidden layer")
        self._config = dict(dim=int(dim), hidden=[int(h) for h in hidden],
                            noise_conditioned=bool(noise_conditioned), sigma_max=float(sigma_max),
                            eval_solver=eval_solver, eval_step_size=float(eval_step_size),
                            eval_rtol=float(eval_rtol), eval_atol=float(eval_atol),
                            eval_quadrature=None if eval_quadrature is None
                            else int(eval_quadrature), tanh=tanh)
        self.dim, self.hidden = int(dim), tuple(int(h) for h in hidden)
        self.noise_conditioned, self.sigma_max = bool(noise_conditioned), float(sigma_max)
        self.eval_solver, self.eval_step_size = eval_solver, float(eval_step_size)
        self.eval_rtol, self.eval_atol = float(eval_rtol), float(eval_atol)
        self.eval_quadrature = self._config["eval_quadrature"]
        self.net = ODENet(dim, hidden, tanh)
        self.register_buffer("mean", torch.zeros(dim, dtype=torch.float64))
        self.register_buffer("std", torch.ones(dim, dtype=torch.float64))
        self.register_buffer("iterations_trained", torch.tensor(0, dtype=torch.int64))
        self.train_config: SoftFlowConfig | None = None   # set by fit(); saved with the flow

    def config(self) -> dict:
        """The constructor arguments, JSON-able: ``SoftFlow(**flow.config())`` rebuilds it."""
        return dict(self._config)

    @property
    def tanh(self) -> str:
        """The hidden layers' tanh kernel (the network's, which evaluate() reads)."""
        return self.net.tanh_kernel

    # standardisation
    @torch.no_grad()
    def set_standardisation(self, states, std_floor: float = 1e-3) -> None:
        """Per-dimension mean and std (floored at ``std_floor``) of ``states``."""
        x = _check_states(states, self.dim, "states").to(torch.float64)
        self.mean.copy_(x.mean(0))
        self.std.copy_(x.std(0, unbiased=False).clamp_min(std_floor))

    def standardise(self, x: torch.Tensor) -> torch.Tensor:
        return ((x.to(torch.float64) - self.mean) / self.std).to(torch.float32)

    def unstandardise(self, u: torch.Tensor) -> torch.Tensor:
        return (u.to(torch.float64) * self.std + self.mean).to(torch.float32)

    @property
    def log_jacobian_standardisation(self) -> float:
        """log |det d u / d x| = -sum(log std): added to a density of standardised states."""
        return float(-torch.log(self.std).sum())

    def noise_input(self, sigma) -> torch.Tensor:
        """The noise level as the network sees it: sigma / sigma_max * 2 (0 for a plain CNF)."""
        sigma = torch.as_tensor(sigma, dtype=torch.float32).reshape(-1)
        if not self.noise_conditioned:
            if (sigma != 0).any():
                raise ValueError("a plain CNF (noise_conditioned=False) has no noise level; "
                                 "evaluate it at sigma = 0")
            return torch.zeros_like(sigma)
        return sigma / self.sigma_max * 2.0

    # the core: x (standardised) -> z(1), integral of the trace
    def integrate(self, u: torch.Tensor, sigma, trace: str = "exact", solver: str | None = None,
                  step_size: float | None = None, rtol: float | None = None,
                  atol: float | None = None, probe: torch.Tensor | None = None,
                  max_num_steps: int | None = None, quadrature: int | None = None):
        """Solves the augmented ODE from standardised states ``u`` at t = 0 to t = 1.

        Returns ``(log_p, z1, nfe)``: the log-density of ``u`` under the standardised model
        (equation (*)), the end points, and the number of evaluations of f (with a trace or
        not).  ``sigma`` is a scalar or one level per state (standardised units).

        ``quadrature=None`` integrates z and the trace jointly (the textbook way: the trace at
        every stage of every step).  ``quadrature=k`` integrates z alone, with the outputs at
        the k Gauss-Legendre nodes, and the trace only there: ``integral_0^1 tr dt ~
        sum_j w_j tr(t_j, z(t_j))``.  The trace, D times dearer than f, is then computed k times
        instead of at every stage (32 times for 8 rk4 steps); the error is that of the
        quadrature of a smooth function of t, measured by ``dc-lesson perf softflow``.
        """
        if trace not in TRACES:
            raise ValueError(f"trace must be one of {TRACES}, not {trace!r}")
        if trace == "hutchinson" and probe is None:
            raise ValueError("the Hutchinson trace needs a probe (one vector per state)")
        solver = solver or self.eval_solver
        step_size = step_size or self.eval_step_size
        rtol = self.eval_rtol if rtol is None else rtol
        atol = self.eval_atol if atol is None else atol
        noise_in = self.noise_input(sigma)
        if quadrature:
            nodes, weights = gauss_legendre(quadrature)
            path_func = _Dynamics(self.net, noise_in, None)
            (zs,) = solve_path(path_func, (u,), [0.0, *nodes, 1.0], solver, step_size, rtol,
                                atol, max_num_steps)
            trace_func = _Dynamics(self.net, noise_in, trace, probe)
            delta = torch.zeros(len(u), dtype=u.dtype)
            for j, (t, w) in enumerate(zip(nodes, weights)):
                _, tr = trace_func(torch.tensor(t, dtype=u.dtype), (zs[j + 1],))
                delta = delta + w * tr
            z1 = zs[-1]
            nfe = path_func.nfe + trace_func.nfe
        else:
            func = _Dynamics(self.net, noise_in, trace, probe)
            delta0 = torch.zeros(len(u), dtype=u.dtype)
            z1, delta = solve(func, (u, delta0), 0.0, 1.0, solver, step_size, rtol, atol,
                               max_num_steps)
            nfe = func.nfe
        return standard_normal_logpdf(z1) + delta, z1, nfe

    def log_prob(self, states, sigma: float = 0.0, trace: str = "auto",
                 solver: str | None = None, step_size: float | None = None,
                 rtol: float | None = None, atol: float | None = None,
                 quadrature: int | None | str = "default",
                 generator: torch.Generator | None = None, chunk_size: int = 8192
                 ) -> torch.Tensor:
        """log p(states) of the ORIGINAL (unstandardised) states, shape (N,), float32.

        Evaluated at noise level ``sigma`` (0: SoftFlow's density of clean states), without
        gradients, in chunks of ``chunk_size`` states.  ``trace="auto"`` is exact for
        ``dim <= EXACT_TRACE_MAX_DIM`` and Hutchinson (probes from ``generator``) above.
        The solver and ``quadrature`` (see :meth:`integrate`; None: joint integration) default
        to the flow's ``eval_*`` settings.
        """
        x = _check_states(states, self.dim, "states")
        if trace == "auto":
            trace = "exact" if self.dim <= EXACT_TRACE_MAX_DIM else "hutchinson"
        if quadrature == "default":
            quadrature = self.eval_quadrature
        out = []
        with torch.no_grad():
            for start in range(0, len(x), chunk_size):
                u = self.standardise(x[start:start + chunk_size])
                probe = (draw_probe(u.shape, "rademacher", generator)
                         if trace == "hutchinson" else None)
                lp, _, _ = self.integrate(u, sigma, trace, solver, step_size, rtol, atol, probe,
                                          quadrature=quadrature)
                out.append(lp)
        return torch.cat(out) + self.log_jacobian_standardisation

    def reference_log_prob(self, states, sigma: float = 0.0, **kwargs) -> torch.Tensor:
        """log p(states) the reference way: exact trace integrated jointly with z by dopri5 at
        rtol = atol = 1e-5.  Slower; for checking the fast defaults on a flow's own states,
        ``(flow.log_prob(x) - flow.reference_log_prob(x)).abs().mean()``."""
        return self.log_prob(states, sigma, trace="exact", solver="dopri5", rtol=1e-5,
                             atol=1e-5, quadrature=None, **kwargs)

    def sample(self, n: int, generator: torch.Generator | None = None, sigma: float = 0.0,
               solver: str | None = None, step_size: float | None = None) -> torch.Tensor:
        """``n`` states (original units) drawn at noise level ``sigma``: z ~ N(0, I) from
        ``generator``, integrated from t = 1 back to t = 0."""
        z = torch.randn(int(n), self.dim, generator=generator)
        func = _Dynamics(self.net, self.noise_input(sigma), None)
        with torch.no_grad():
            (u,) = solve(func, (z,), 1.0, 0.0, solver or self.eval_solver,
                          step_size or self.eval_step_size, self.eval_rtol, self.eval_atol)
        return self.unstandardise(u)


def draw_probe(shape, kind: str, generator: torch.Generator | None) -> torch.Tensor:
    """A Hutchinson probe: Rademacher (+-1) or standard Gaussian entries."""
    if kind == "gaussian":
        return torch.randn(shape, generator=generator)
    return torch.randint(0, 2, shape, generator=generator).to(torch.float32) * 2 - 1


# -- training ------------------------------------------------------------------------------------

def make_optimizer(flow: SoftFlow, config: SoftFlowConfig) -> torch.optim.Optimizer:
    """Adam with L2 weight decay (SoftFlow's reference optimiser)."""
    return torch.optim.Adam(flow.parameters(), lr=config.lr, weight_decay=config.weight_decay)


def nll_loss(flow: SoftFlow, u: torch.Tensor, config: SoftFlowConfig,
             generator: torch.Generator | None = None):
    """The training loss on a minibatch of standardised states ``u``.

    SoftFlow: sigma ~ U[0, sigma_max] per state, ``u + sigma * eps``, the network told sigma;
    plain CNF: the clean states at sigma = 0.  Returns ``(loss, nfe)``, the loss being the mean
    negative log-density of the (perturbed) standardised states.
    """
    if flow.noise_conditioned:
        sigma = torch.rand(len(u), generator=generator) * config.sigma_max
        u = u + sigma.unsqueeze(1) * torch.randn(u.shape, generator=generator)
    else:
        sigma = torch.zeros(1)   # one level for all: the gates fold into the weights
    probe = draw_probe(u.shape, config.probe, generator) if config.trace == "hutchinson" else None
    log_p, _, nfe = flow.integrate(u, sigma, config.trace, config.solver, config.step_size,
                                   config.rtol, config.atol, probe, config.max_num_steps)
    return -log_p.mean(), nfe


def fit(states, config: SoftFlowConfig = SoftFlowConfig(), progress: bool = True,
        callback: Callable | None = None):
    """Fits a SoftFlow (or, with ``config.noise_conditioned=False``, a plain CNF) to ``states``.

    ``states``: (N, dim) array or tensor, finite.  The standardisation is computed from them and
    then kept.  Returns ``(flow, log)``; see :func:`fit_more` for ``log`` and ``callback``.
    """
    x = _check_states(states, None, "training states")
    init_seed = int(np.random.SeedSequence(config.seed).generate_state(1)[0])
    with torch.random.fork_rng(devices=[]):   # seed the initialisation, leave the global RNG
        torch.manual_seed(init_seed)
        flow = SoftFlow(x.shape[1], config.hidden, config.noise_conditioned, config.sigma_max,
                        config.eval_solver, config.eval_step_size, config.eval_rtol,
                        config.eval_atol, config.eval_quadrature, config.tanh)
    flow.set_standardisation(x, config.std_floor)
    flow.train_config = config
    return fit_more(flow, x, config, progress=progress, callback=callback)


@_timing.timed("flow_fit")
def fit_more(flow: SoftFlow, states, config: SoftFlowConfig | None = None,
             iterations: int | None = None, progress: bool = True,
             callback: Callable | None = None,
             optimizer: torch.optim.Optimizer | None = None):
    """Continues training ``flow`` on ``states`` (DC's Algorithm 1 refits P_w every loop).

    The standardisation is NOT refreshed: it stays as the first fit set it, so log-densities
    (DC's reward) remain comparable across refits.  ``config`` defaults to the one the flow was
    fitted with (its architecture fields must match the flow); ``iterations`` to
    ``config.iterations``.  A fresh Adam is made unless ``optimizer`` is given (pass the same
    one each time to keep its moments).

    ``log`` has one row per gradient step: ``iteration`` (counting all fits of this flow),
    ``nll`` (mean negative log-density of the minibatch in nats per state, original units: for
    SoftFlow the perturbed states at their noise levels), ``nfe`` (evaluations of f in the
    forward solve), ``grad_norm`` and ``seconds``.  ``callback(row, flow)`` is called after
    every step; a true return value stops training.
    """
    config = config or flow.train_config
    if config is None:
        raise ValueError("this flow has no training configuration; pass config")
    for name, have in (("hidden", flow.hidden), ("noise_conditioned", flow.noise_conditioned),
                       ("sigma_max", flow.sigma_max), ("tanh", flow.tanh)):
        if getattr(config, name) != have:
            raise ValueError(f"config.{name} = {getattr(config, name)!r} but the flow was "
                             f"built with {have!r}")
    x = _check_states(states, flow.dim, "training states")
    u_all = flow.standardise(x)
    iterations = config.iterations if iterations is None else int(iterations)
    done = int(flow.iterations_trained)
    seed = int(np.random.SeedSequence([config.seed, done]).generate_state(1)[0])
    generator = torch.Generator().manual_seed(seed)
    optimizer = optimizer or make_optimizer(flow, config)
    params = [p for p in flow.parameters()]
    offset = flow.log_jacobian_standardisation
    n, bs = len(u_all), min(config.batch_size, len(u_all))
    order, pos = torch.randperm(n, generator=generator), 0

    from dc_lesson import progress as _progress
    kind = "SoftFlow" if flow.noise_conditioned else "CNF"
    bar = _progress.bar(total=iterations, desc=f"{kind} fit", unit="it", enabled=progress)
    log: list[dict] = []
    try:
        for i in range(iterations):
            start = time.perf_counter()
            iteration = done + i + 1
            if pos + bs > n:
                order, pos = torch.randperm(n, generator=generator), 0
            u = u_all[order[pos:pos + bs]]
            pos += bs
            try:
                loss, nfe = nll_loss(flow, u, config, generator)
            except FlowTrainingError as e:
                raise FlowTrainingError(f"at iteration {iteration}: {e}") from None
            loss_value = float(loss.detach())
            if not math.isfinite(loss_value):
                raise FlowTrainingError(
                    f"the loss became {loss_value} at iteration {iteration}; training stopped "
                    f"with the flow's last finite parameters. Lower the learning rate "
                    f"({config.lr}), clip gradients (max_grad_norm), or use a tighter solver")
            optimizer.zero_grad()
            loss.backward()
            clip = config.max_grad_norm if config.max_grad_norm is not None else math.inf
            grad_norm = torch.nn.utils.clip_grad_norm_(params, clip)
            if not torch.isfinite(grad_norm):
                raise FlowTrainingError(
                    f"the gradient became non-finite at iteration {iteration} (loss "
                    f"{loss_value}); training stopped with the flow's last finite parameters")
            optimizer.step()
            flow.iterations_trained += 1
            row = {"iteration": iteration, "nll": loss_value - offset, "nfe": nfe,
                   "grad_norm": float(grad_norm), "seconds": time.perf_counter() - start}
            log.append(row)
            bar.update(1)
            bar.set_postfix(nll=f"{row['nll']:.3f}", nfe=nfe)
            if callback is not None and callback(row, flow):
                break
    finally:
        bar.close()
    return flow, log


# -- files ---------------------------------------------------------------------------------------

FLOW_FORMAT = "dc_lesson.softflow"
FLOW_VERSION = 1


def save_flow(flow: SoftFlow, path, meta: dict | None = None) -> pathlib.Path:
    """Saves weights, standardisation, constructor arguments, the training configuration and
    JSON-able ``meta``, atomically."""
    try:
        meta_json = json.dumps(meta or {})
    except TypeError as e:
        raise TypeError(f"flow metadata must be JSON-able: {e}") from None
    cfg = flow.train_config.to_json() if flow.train_config is not None else ""
    return atomic_torch_save({"format": FLOW_FORMAT, "version": FLOW_VERSION,
                              "args": json.dumps(flow.config()), "train_config": cfg,
                              "meta": meta_json, "state_dict": flow.state_dict()}, path)


def load_flow(path, fix: str | None = None) -> SoftFlow:
    """Rebuilds a saved flow (eval mode), loaded with ``weights_only=True``; its metadata is in
    ``flow.meta``.  A missing, damaged or foreign file raises ``FileNotFoundError`` or
    :class:`~dc_lesson.nn.checkpoint.PolicyFileError` naming the file."""
    obj = load_checked(path, FLOW_FORMAT, FLOW_VERSION, "SoftFlow", fix)
    try:
        flow = SoftFlow(**json.loads(obj["args"]))
        flow.load_state_dict(obj["state_dict"])
        flow.train_config = (SoftFlowConfig.from_json(obj["train_config"])
                             if obj["train_config"] else None)
        meta = json.loads(obj["meta"])
    except (KeyError, TypeError, ValueError, RuntimeError) as e:
        raise PolicyFileError(f"SoftFlow file {path} is inconsistent "
                              f"({type(e).__name__}: {e})") from None
    flow.meta = meta
    return flow.eval()


__all__ = ["ADAPTIVE_SOLVERS", "EXACT_TRACE_MAX_DIM", "FIXED_STEP_SOLVERS", "ConcatSquashLinear",
           "FlowTrainingError", "ODENet", "PolicyFileError", "SoftFlow", "SoftFlowConfig", "fit",
           "fit_more", "gauss_legendre", "jacobian_trace_autodiff", "load_flow",
           "make_optimizer", "nll_loss", "save_flow"]
