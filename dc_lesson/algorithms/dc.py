r"""Distributional Cloning (DC): the paper's Algorithms 1 and 2, and a real consensus ADMM.

**The objective.**  DC maximises the likelihood of the expert's *and* the learner's state-action
pairs under the learner, with the joint density split as P(s, a; pi) = P(s) pi(a | s):

    max_{pi, P}  E_{(s,a) in D_E u D_pi} [ log P(s) + log pi(a | s) ].                   (Eq. 3)

P is a SoftFlow P_w fitted to states (:mod:`dc_lesson.density.softflow`); pi a Gaussian policy.  The
log pi term is BC's (Eq. 1), differentiable in pi.  The log P(s) term depends on pi only through
*which states pi visits*: no gradient flows through sampling, so it is an RL problem with reward
log P_w(s).  The paper splits the two with a copy pi' of the policy:

    max_{pi, pi'}  E_{D_E u D_pi}[log pi(a|s)] + E_{D_E u D_pi'}[log P_w(s)]   s.t. pi = pi' = z
                                                                                          (Eq. 4)

and, "based on consensus optimisation via ADMM", updates pi by a BC step, pi' by a PPO step, and
sets both to their average z = (pi + pi') / 2.

**Algorithm 1 (loops).**  Loop 0 fits P_w on expert states only, then runs Algorithm 2 for N
iterations.  Every later loop samples learner trajectories, refits P_w (continuing from its
weights) on equal numbers of expert and learner states, and runs Algorithm 2 again.

**Algorithm 2 (one iteration, ``update="average"``, the paper's):**

    pi' <- copy(pi)
    B   <- n_envs x n_steps steps sampled with pi'            (PPO's batch; r = reward(log P_w))
    pi  <- BC step(s) on expert pairs + as many pairs of B      (Eq. 4, first term)
    pi' <- PPO update on B                                      (Eq. 4, second term)
    pi  <- (pi + pi') / 2, element-wise over the parameters

**Consensus ADMM (``update="admm"``, beyond the paper).**  The paper's update has no dual
variable and resets both copies to z every iteration: it is parameter averaging.  Real consensus
ADMM (Boyd et al. 2011, section 7.1) keeps two local copies x_1 (BC) and x_2 (PPO), a consensus
z (the policy we evaluate) and scaled duals u_1, u_2:

    x_1 <- BC step(s) on   NLL(x_1)        + rho/2 ||x_1 - z + u_1||^2
    x_2 <- PPO update on   L_PPO(x_2)      + rho/2 ||x_2 - z + u_2||^2   (batch sampled by x_2)
    z   <- mean_i (x_i + u_i)
    u_i <- u_i + x_i - z
    primal residual ||(x_1 - z, x_2 - z)||,  dual residual rho * sqrt(2) * ||z - z_prev||.

The paper's averaging is this with u = 0 and x_i reset to z each iteration.

**Choices the paper leaves open** (each a field of :class:`DCConfig`; the book discusses them):

* *What is averaged* (``average_log_std``): the policy's mean network always; its log-std too by
  default (Alg. 2 averages "pi"); with False, z takes pi''s (PPO's) log-std, so BC, which pulls the
  log-std down to the expert's tiny action noise, cannot switch exploration off.  The observation
  normaliser is BC's, fitted on the expert's states and frozen: identical in both copies, so
  averaging does not touch it, and the reward and the policy see the same inputs all run.  The
  critic belongs to PPO alone (pi has none): it is never averaged and persists across iterations,
  so it does not relearn the values of log P_w from scratch each iteration.
* *Optimiser state* (``optimizer_state``): ``"own"``, pi and pi' keep their own AdamW moments
  across iterations (pi' is overwritten in place by the copy, so its moments carry over);
  ``"reset"`` gives both fresh moments every iteration.
* *Old log-probabilities*: PPO's ratio uses the log-probabilities of the policy that sampled the
  batch, pi' at the iteration's start, which equals pi then: under Alg. 2's order there is no
  choice to make (a test checks the equality).
* *The learner pairs in the BC step* (``bc_learner_pairs``): Alg. 2 takes the BC step on D_E u
  D_pi'.  At the iteration's start pi = pi', and E_{a ~ pi}[grad log pi(a|s)] = 0, so the learner
  half adds no direction in expectation; after the first BC step it pulls pi back towards the
  sampling policy, a trust region.  True (the paper) by default.
* *The reward* (``reward``): log P_w(s') of the state an action led to (so the action that caused
  a state is credited for it).  ``"scaled"`` (default) maps it linearly to [0, 1]: 1 at or above
  the median log-density of the expert's states, 0 at or below ``ell_lo = q_0.01 - (median -
  q_0.01)`` (the expert's 1% quantile, extended below by the same span), clipped between.  The
  raw log-density of a continuous flow runs from about +20 on the expert's manifold to -1e4 far
  off it: as a PPO reward that scale is arbitrary and its tail would swamp the advantages.  The
  cap at the median keeps PPO from chasing the single densest state (a mode-seeking pull of its
  own); the task's rewards are in [0, 1] too, so PPO's settings carry over.  ``"raw"`` uses
  log P_w(s') unchanged.  The quantiles are recomputed after every fit of P_w.  ``"gail"`` (a
  control arm, beyond the paper) replaces P_w by a state-only GAIL discriminator trained every
  iteration, reward -log(1 - D(s')) (:mod:`dc_lesson.algorithms._dc_disc`): what the density
  itself adds, with everything else of Algorithm 2 unchanged; no flow is fitted then.
* *Steps per iteration*: one PPO update of ``ppo.n_epochs`` x ``ppo.n_minibatches`` = 32 minibatch
  steps on pi', and as many BC minibatch steps (``bc_steps``) of ``bc_batch_size`` expert pairs
  (and as many learner pairs) on pi: the same number of optimiser steps on each side of the
  average.  (A first try with 4 BC steps let PPO's side dominate: on reacher4, one seed, the
  scaled return fell from BC's 0.48 to 0.23 in 40 iterations.)
* *Weight decay* (the paper: "weight decay during ADMM"): AdamW's decoupled decay,
  ``weight_decay``, on both copies' parameters (not on the critic).
* *Learning rates*: one ``lr`` for both copies' AdamW (the paper's appendix: 1e-4 with gradient
  clip 0.1, for 1,000 iterations; at our smaller budgets 3e-4 and PPO's clip of 0.5).
* *P_w*: SoftFlow with the library's defaults except a fixed-step rk4 training solver (several
  times cheaper than dopri5, and the reward is evaluated with rk4 too).  The cheapest solver
  settings that keep what DC learns (issue 14): training steps of 0.5 (``flow_step``: two rk4
  steps; held-out NLL no worse than at 0.25, ``dc-lesson perf flow-fit``), the reward's z at
  steps of at most 0.5 between the nodes of a 3-point Gauss-Legendre rule for the trace
  integral (``reward_step``, ``reward_nodes``; on held-out expert states, against the
  reference solver, about 0.04 nats mean error, 0.24 at most, and a rank correlation of 0.99,
  the order being what the scaled reward reads), and the flow's tanh by NumPy's kernel
  (``flow_tanh``; ``density._trace``).  Runs before 2026-12-04 used steps of 0.25, 4 nodes
  and torch's tanh (:data:`STORED_NUMERICS`); ``dc-lesson perf dc-fit --variant defaults``
  compares the two over ten seeds.  Fitted on up to ``flow_states`` expert states in loop 0
  (``flow_iterations`` steps), refitted in later loops on the same number of expert and learner states each
  (``flow_refit_iterations`` steps, a fresh Adam; the standardisation stays the first fit's,
  so rewards stay comparable across loops).
  Learner states for a refit come from ``n_envs`` fresh episodes of the stochastic policy, which
  count as environment interactions.

**Logged every iteration:** BC's NLL, PPO's terms, the mean reward and mean log P_w(s'), the L1
norm of the change of pi's parameters over the iteration (the paper's Figure 6), the L1 distance
between pi and pi' before averaging, the primal and dual residuals (ADMM), environment steps and
steps per second.

**Determinism and checkpoints.**  ``config.seed`` decides the flow's seed, the critic's
initialisation, one torch generator (actions, minibatches, pairs) and the episode seeds.
:func:`train` saves everything (policies, critic, optimisers, flow, consensus variables,
generator, environments, log) atomically after every loop and every ``checkpoint_every``
iterations, and resumes from the file: a resumed run ends identical to an uninterrupted one.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import pathlib
import time
from typing import Callable

import numpy as np
import torch

from dc_lesson import progress as _progress
from dc_lesson import timing as _timing
from dc_lesson.algorithms import _dc_disc
from dc_lesson.algorithms import bc as _bc
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms.base import TrainResult, check_inputs, checkpoint_fix
from dc_lesson.checks import check_fields
from dc_lesson.density import softflow as _softflow
from dc_lesson import tasks as _tasks
from dc_lesson.data import Demonstrations
from dc_lesson.nn import fast as _fast
from dc_lesson.nn.policies import (GaussianPolicy, PolicyFileError, ValueNetwork,
                                atomic_torch_save, load_checked)
from dc_lesson.algorithms.ppo import (EnvBatch, PPOConfig, check_checkpoint, collect_batch, compute_gae,
                           ppo_update)

UPDATES = ("average", "admm")
REWARDS = ("scaled", "raw", "gail")
OPTIMIZER_STATES = ("own", "reset")


# PPO's step on pi' in DC: 8 x 250 steps per iteration, 4 epochs of 8 minibatches (32 gradient
# steps, as many as the BC step takes), the critic 64-64.
_DC_PPO = PPOConfig(n_envs=8, n_steps=250, n_epochs=4, n_minibatches=8, clip_coef=0.2,
                    gamma=0.99, gae_lambda=0.95, vf_coef=0.5, ent_coef=0.0, hidden=(64, 64),
                    anneal_lr=False)


# The flow's numerics of every DC run before 2026-12-04; perf dc-fit and perf runs compare
# today's defaults with them.
STORED_NUMERICS = {"flow_step": 0.25, "reward_step": 0.25, "reward_nodes": 4,
                   "flow_tanh": "torch"}


@dataclasses.dataclass(frozen=True)
class DCConfig:
    """Every knob of DC.  See the module docstring for why each default is what it is."""

    # Algorithm 1
    loops: int = 2               # L: loop 0 (P_w on expert states) plus L - 1 refit loops
    iterations: int = 50         # N: Algorithm 2 iterations per loop
    flow_states: int = 4000      # expert states per fit (and as many learner states in a refit)
    flow_iterations: int = 300   # gradient steps of P_w's first fit (loop 0)
    flow_refit_iterations: int = 100   # gradient steps of each later refit
    flow_hidden: tuple[int, ...] = (64, 64, 64)   # SoftFlow's concat-squash widths
    flow_lr: float = 1e-3        # SoftFlow's Adam learning rate
    sigma_max: float = 0.1       # SoftFlow's noise range (standardised states)
    flow_step: float = 0.5       # rk4 step of P_w's training solve (0.25 costs twice as
    #                              much for a held-out NLL no better; dc-lesson perf flow-fit)
    reward_step: float = 0.5     # largest rk4 step of log P_w's evaluation, the reward
    reward_nodes: int = 3        # Gauss-Legendre nodes of the reward's trace integral
    flow_tanh: str = "numpy"     # the flow's tanh kernel (density._trace): NumPy's or torch's
    # Algorithm 2
    update: str = "average"      # "average" (the paper) or "admm" (consensus ADMM with duals)
    rho: float = 1.0             # ADMM's penalty (update="admm" only)
    bc_step: bool = True         # take the BC step on pi (switch off for the ablation/tests)
    ppo_step: bool = True        # take the PPO step on pi' (likewise)
    bc_steps: int = 32           # BC minibatch steps per iteration: as many as PPO takes
    #                              (ppo.n_epochs x ppo.n_minibatches), so neither dominates
    bc_batch_size: int = 256     # expert pairs per BC step (and as many learner pairs)
    bc_learner_pairs: bool = True    # BC on D_E u D_pi' (the paper) or D_E only
    average_log_std: bool = True     # average the log-std too (False: z takes pi''s)
    optimizer_state: str = "own"     # "own": each copy keeps its AdamW moments; "reset"
    lr: float = 3e-4             # AdamW learning rate of both copies
    weight_decay: float = 1e-4   # AdamW decoupled weight decay ("weight decay during ADMM")
    max_grad_norm: float = 0.5   # gradient clip of both steps
    reward: str = "scaled"       # "scaled": log P_w(s') mapped to [0, 1]; "raw": log P_w(s');
    #                              "gail": GAIL's -log(1 - D(s')), no flow (_dc_disc, a control)
    # PPO's step on pi': PPO's own settings, nested as in GAILConfig.  DC's ``lr``,
    # ``max_grad_norm`` and ``seed`` override ``ppo``'s (one rate for both copies), its
    # learning rate is not annealed, and ``ppo.total_steps`` is unused (loops x iterations).
    ppo: PPOConfig = dataclasses.field(default_factory=lambda: _DC_PPO)
    start_log_std: float | None = None   # a given (warm) start's log-std is set to this
    #                              first (None: kept); base.START_LOG_STD is the shared rule
    seed: int = 0

    def __post_init__(self):
        check_fields(self, positive=("loops", "iterations", "flow_states", "flow_iterations",
                                     "flow_lr", "sigma_max", "flow_step", "reward_step",
                                     "reward_nodes", "rho",
                                     "bc_steps", "bc_batch_size", "lr", "max_grad_norm"),
                     non_negative=("flow_refit_iterations", "weight_decay", "seed"))
        if not isinstance(self.ppo, PPOConfig):
            raise TypeError(f"DCConfig.ppo must be a ppo.PPOConfig, got {type(self.ppo)}")
        for name, allowed in (("update", UPDATES), ("reward", REWARDS),
                              ("optimizer_state", OPTIMIZER_STATES)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"DCConfig.{name} must be one of {allowed}, got "
                                 f"{getattr(self, name)!r}")
        for name in ("loops", "iterations", "bc_steps", "bc_batch_size", "flow_states"):
            if getattr(self, name) < 1:
                raise ValueError(f"DCConfig.{name} must be at least 1, got "
                                 f"{getattr(self, name)}")
        if self.flow_tanh not in _softflow._trace.KERNELS:
            raise ValueError(f"DCConfig.flow_tanh must be one of {_softflow._trace.KERNELS}, "
                             f"got {self.flow_tanh!r}")
        if not (self.lr > 0 and self.rho > 0):
            raise ValueError(f"lr and rho must be positive, got {self.lr} and {self.rho}")

    @property
    def n_envs(self) -> int:
        return self.ppo.n_envs

    @property
    def n_steps(self) -> int:
        return self.ppo.n_steps

    @property
    def batch_size(self) -> int:
        return self.ppo.batch_size

    def ppo_config(self) -> PPOConfig:
        """The PPO settings of the step on pi' (what :func:`ppo.ppo_update` reads)."""
        return dataclasses.replace(self.ppo, lr=self.lr, max_grad_norm=self.max_grad_norm,
                                   anneal_lr=False, total_steps=self.batch_size,
                                   seed=self.seed)

    def with_ppo(self, **changes) -> "DCConfig":
        """The same configuration with some of PPO's settings changed."""
        return dataclasses.replace(self, ppo=dataclasses.replace(self.ppo, **changes))

    def flow_config(self) -> _softflow.SoftFlowConfig:
        return _softflow.SoftFlowConfig(hidden=self.flow_hidden, sigma_max=self.sigma_max,
                                        lr=self.flow_lr, iterations=self.flow_iterations,
                                        solver="rk4", step_size=self.flow_step,
                                        eval_step_size=self.reward_step,
                                        eval_quadrature=self.reward_nodes,
                                        tanh=self.flow_tanh, seed=self.seed)

    def env_steps(self, task: str) -> int:
        """Environment interactions of a whole run: the policy batches plus the learner
        episodes sampled for each refit of P_w (none with ``reward="gail"``: no flow)."""
        horizon = _tasks.spec(task).horizon
        refits = 0 if self.reward == "gail" else self.loops - 1
        return self.loops * self.iterations * self.batch_size + refits * self.n_envs * horizon

    def to_json(self) -> str:
        d = _base.unset_dropped(dataclasses.asdict(self))
        d["ppo"] = json.loads(self.ppo_config().to_json())
        return json.dumps(d, sort_keys=True)


# -- parameters as flat vectors ------------------------------------------------------------------

# The settings of every DC run of the benchmarks; the iterations follow the budget.
DC_DEFAULTS = dict(loops=2)


def preset(budget, seed: int = 0, **overrides) -> DCConfig:
    """DC's configuration for a budget: ``il_steps`` interactions split over the loops."""
    base = DCConfig(**{**DC_DEFAULTS, **overrides, "seed": seed})
    if budget.is_smoke:
        base = dataclasses.replace(base.with_ppo(n_envs=2, n_steps=64, n_minibatches=4,
                                                 n_epochs=2),
                                   flow_states=300, flow_iterations=5, flow_refit_iterations=3,
                                   flow_hidden=(16, 16), bc_steps=4, bc_batch_size=64)
    if "iterations" not in overrides:
        per_loop = max(1, budget.il_steps // (base.loops * base.batch_size))
        base = dataclasses.replace(base, iterations=per_loop)
    return base


def policy_parameters(policy: GaussianPolicy, include_log_std: bool = True) -> list:
    """The parameters DC averages: the mean network's, and the log-std if asked (a mixture
    policy, whose spreads are outputs of its network, averages all its parameters)."""
    if not policy.gaussian:
        return list(policy.parameters())
    return list(policy.mean_net.parameters()) + ([policy.log_std] if include_log_std else [])


def flat(params) -> torch.Tensor:
    return torch.cat([p.detach().reshape(-1) for p in params])


@torch.no_grad()
def average_into(target: GaussianPolicy, other: GaussianPolicy,
                 average_log_std: bool = True) -> None:
    """target <- (target + other) / 2, element-wise, over the mean network's parameters and
    (with ``average_log_std``) the log-std; without it, target takes other's log-std."""
    for p, q in zip(policy_parameters(target, False), policy_parameters(other, False)):
        p.add_(q).mul_(0.5)
    if not target.gaussian:
        return     # a mixture: its spreads are network outputs, averaged with the rest
    if average_log_std:
        target.log_std.add_(other.log_std).mul_(0.5)
    else:
        target.log_std.copy_(other.log_std)


@torch.no_grad()
def copy_into(target: torch.nn.Module, source: torch.nn.Module) -> None:
    """Copies parameters and buffers in place (so an optimiser holding ``target``'s tensors
    keeps its state)."""
    for p, q in zip(target.parameters(), source.parameters()):
        p.copy_(q)
    for b, c in zip(target.buffers(), source.buffers()):
        b.copy_(c)


# -- the reward ----------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class RewardScale:
    """The linear map of log P_w to [0, 1]: 0 at ``low``, 1 at ``high`` (module docstring)."""
    low: float
    high: float

    @classmethod
    def from_expert(cls, expert_logp: np.ndarray) -> "RewardScale":
        q01, q50 = np.quantile(np.asarray(expert_logp, np.float64), [0.01, 0.5])
        span = max(float(q50 - q01), 1e-3)
        return cls(low=float(q01 - span), high=float(q50))

    def __call__(self, logp: torch.Tensor) -> torch.Tensor:
        return ((logp - self.low) / (self.high - self.low)).clamp(0.0, 1.0)


@_timing.timed("log_p")
def state_log_density(flow: _softflow.SoftFlow, states: torch.Tensor) -> torch.Tensor:
    """log P_w of (..., obs_dim) states, same leading shape."""
    shape = states.shape[:-1]
    with torch.no_grad():
        logp = flow.log_prob(states.reshape(-1, states.shape[-1]))
    return logp.reshape(shape)


# -- one iteration of Algorithm 2 -----------------------------------------------------------------

@dataclasses.dataclass
class Learner:
    """Everything Algorithm 2 updates.  ``pi`` is the policy (z under ADMM); ``pi_prime`` its
    PPO copy; ``pi_bc`` the BC copy x_1 under ADMM (None under averaging, where pi itself takes
    the BC step); ``duals`` the scaled dual vectors (u_1, u_2) under ADMM."""
    pi: GaussianPolicy
    pi_prime: GaussianPolicy
    value_fn: ValueNetwork
    opt_bc: torch.optim.Optimizer
    opt_ppo: torch.optim.Optimizer
    pi_bc: GaussianPolicy | None = None
    duals: list | None = None


def make_learner(policy: GaussianPolicy, config: DCConfig, obs_dim: int) -> Learner:
    """The two copies, the critic and their optimisers, from a (BC-initialised) policy."""
    pi = policy
    pi_prime = copy.deepcopy(policy)
    value_fn = ValueNetwork(obs_dim, config.ppo.hidden, norm_obs=pi.obs_norm is not None)
    if pi.obs_norm is not None:   # the critic sees the policy's (frozen) normalisation
        value_fn.obs_norm.load_state_dict(pi.obs_norm.state_dict())
    pi_bc = copy.deepcopy(policy) if config.update == "admm" else None
    bc_target = pi_bc if pi_bc is not None else pi
    opt_bc = _fast.adamw(bc_target.parameters(), lr=config.lr, eps=1e-5,
                               weight_decay=config.weight_decay)
    # Weight decay on the policy copy only, not on the critic.
    opt_ppo = _fast.adamw([{"params": list(pi_prime.parameters()),
                                  "weight_decay": config.weight_decay},
                                 {"params": list(value_fn.parameters()), "weight_decay": 0.0}],
                                lr=config.lr, eps=1e-5)
    duals = None
    if config.update == "admm":
        n = flat(policy_parameters(pi)).numel()
        duals = [torch.zeros(n), torch.zeros(n)]
    return Learner(pi, pi_prime, value_fn, opt_bc, opt_ppo, pi_bc, duals)


def sample_bc_pairs(expert_obs: torch.Tensor, expert_act: torch.Tensor, batch, config: DCConfig,
                    generator: torch.Generator):
    """One BC minibatch: ``bc_batch_size`` expert pairs and (with ``bc_learner_pairs``) as many
    pairs of the learner batch, drawn uniformly with ``generator``."""
    i = torch.randint(len(expert_obs), (config.bc_batch_size,), generator=generator)
    obs, act = expert_obs[i], expert_act[i]
    if config.bc_learner_pairs:
        lo = batch.obs.reshape(-1, batch.obs.shape[-1])
        la = batch.actions.reshape(-1, batch.actions.shape[-1])
        j = torch.randint(len(lo), (config.bc_batch_size,), generator=generator)
        obs, act = torch.cat([obs, lo[j]]), torch.cat([act, la[j]])
    return obs, act


def _reset_moments(opt: torch.optim.Optimizer) -> None:
    opt.state.clear()


def _proximal(policy: GaussianPolicy, target: torch.Tensor, rho: float):
    """rho/2 ||x - target||^2 over the policy's averaged parameters, as a closure."""
    def term():
        x = torch.cat([p.reshape(-1) for p in policy_parameters(policy)])
        return 0.5 * rho * ((x - target) ** 2).sum()
    return term


def admm_iteration(learner: Learner, batch, rewards: torch.Tensor, expert_obs: torch.Tensor,
                   expert_act: torch.Tensor, config: DCConfig,
                   generator: torch.Generator) -> dict:
    """One iteration of Algorithm 2 on a batch already sampled by ``learner.pi_prime`` (with
    its ``rewards``): the BC step, the PPO step and the averaging (or the ADMM updates).

    Returns the logged terms.  Under ``update="average"`` the caller has made pi' a copy of pi
    before sampling (see :func:`train`).
    """
    L, c = learner, config
    if c.optimizer_state == "reset":
        _reset_moments(L.opt_bc)
        _reset_moments(L.opt_ppo)
    before = flat(policy_parameters(L.pi))
    admm = c.update == "admm"
    out: dict = {}

    # -- the BC step (Eq. 4, first term) on pi (x_1 under ADMM)
    bc_model = L.pi_bc if admm else L.pi
    prox_bc = prox_ppo = None
    if admm:
        z = before
        prox_bc = _proximal(L.pi_bc, z - L.duals[0], c.rho)
        prox_ppo = _proximal(L.pi_prime, z - L.duals[1], c.rho)
    bc_terms = []
    if c.bc_step:
        for _ in range(c.bc_steps):
            obs, act = sample_bc_pairs(expert_obs, expert_act, batch, c, generator)
            bc_terms.append(_bc.bc_step(bc_model, L.opt_bc, obs, act, c.max_grad_norm,
                                        extra_loss=prox_bc))
    out["bc_nll"] = float(np.mean([t["nll"] for t in bc_terms])) if bc_terms else math.nan

    # -- the PPO step (Eq. 4, second term) on pi'
    if c.ppo_step:
        batch.advantages, batch.returns = compute_gae(rewards, batch.values, batch.next_values,
                                                      batch.dones, c.ppo.gamma, c.ppo.gae_lambda,
                                                      batch.terminals)
        ppo_terms = ppo_update(L.pi_prime, L.value_fn, L.opt_ppo, batch, c.ppo_config(),
                               generator, extra_loss=prox_ppo)
        out.update({f"ppo_{k}": v for k, v in ppo_terms.items()})

    x_bc = flat(policy_parameters(bc_model))
    x_rl = flat(policy_parameters(L.pi_prime))
    out["pi_pi_prime_l1"] = float((x_bc - x_rl).abs().sum())

    # -- the consensus
    if not admm:
        # With one step switched off its copy is still the start, so the average halves the
        # other step: what the paper's update does to each step on its own.
        average_into(L.pi, L.pi_prime, c.average_log_std)
    else:
        with torch.no_grad():
            u1, u2 = L.duals
            z_new = 0.5 * ((x_bc + u1) + (x_rl + u2))
            u1 += x_bc - z_new
            u2 += x_rl - z_new
            _set_flat(policy_parameters(L.pi), z_new)
            out["primal_residual"] = float(torch.sqrt(((x_bc - z_new) ** 2).sum()
                                                      + ((x_rl - z_new) ** 2).sum()))
            out["dual_residual"] = float(c.rho * math.sqrt(2.0)
                                         * torch.sqrt(((z_new - before) ** 2).sum()))
    after = flat(policy_parameters(L.pi))
    out["param_change_l1"] = float((after - before).abs().sum())
    out["log_std"] = float(L.pi.log_std.detach().mean()) if L.pi.gaussian else math.nan
    return out


@torch.no_grad()
def _set_flat(params, vector: torch.Tensor) -> None:
    i = 0
    for p in params:
        n = p.numel()
        p.copy_(vector[i:i + n].reshape(p.shape))
        i += n


# -- checkpoints ---------------------------------------------------------------------------------

CHECKPOINT_FORMAT = "dc_lesson.dc.checkpoint"
CHECKPOINT_VERSION = 1


def _state(learner: Learner) -> dict:
    out = {"pi": learner.pi.state_dict(), "pi_prime": learner.pi_prime.state_dict(),
           "value": learner.value_fn.state_dict(), "opt_bc": learner.opt_bc.state_dict(),
           "opt_ppo": learner.opt_ppo.state_dict()}
    if learner.pi_bc is not None:
        out["pi_bc"] = learner.pi_bc.state_dict()
        out["duals"] = [u.clone() for u in learner.duals]
    return out


def _load_state(learner: Learner, state: dict) -> None:
    learner.pi.load_state_dict(state["pi"])
    learner.pi_prime.load_state_dict(state["pi_prime"])
    learner.value_fn.load_state_dict(state["value"])
    learner.opt_bc.load_state_dict(state["opt_bc"])
    learner.opt_ppo.load_state_dict(state["opt_ppo"])
    if learner.pi_bc is not None:
        learner.pi_bc.load_state_dict(state["pi_bc"])
        learner.duals = [u.clone() for u in state["duals"]]


# -- Algorithm 1 ---------------------------------------------------------------------------------

expert_pairs = _bc.pairs   # all (state, action) pairs of the demonstrations, as tensors


def _subsample(x: torch.Tensor, n: int, generator: torch.Generator) -> torch.Tensor:
    if len(x) <= n:
        return x
    return x[torch.randperm(len(x), generator=generator)[:n]]


def train(task: str, demos: Demonstrations, config: DCConfig = DCConfig(), *,
          policy: GaussianPolicy | None = None, progress: bool = True, checkpoint=None,
          callback: Callable | None = None, checkpoint_every: int = 25,
          stop_after_loop: int | None = None) -> TrainResult:
    """Runs DC (Algorithm 1 with Algorithm 2 inside) from ``policy``; returns a
    :class:`TrainResult` (the policy, the log, ``models["flow"]`` and ``models["value"]``).

    ``policy`` is normally BC's warm start (:func:`dc_lesson.algorithms.bc.warm_start`); it is
    updated in place.  None fits that warm start here, on ``demos`` with ``config.seed``.
    ``log`` has one row per iteration (module docstring) plus ``loop``, ``iteration``,
    ``env_steps``, ``episode_return`` (mean task return of the episodes pi' finished in the
    batch, NaN if none) and per-loop flow rows (``kind == "flow"``: the fit's final NLL, its
    seconds, the reward scale).  ``checkpoint``: a file to save to after every loop and every
    ``checkpoint_every`` iterations, and to resume from.  ``stop_after_loop``: return after
    that loop (0-based), as an interruption would.  ``callback(row, policy)`` after each
    iteration; a true value stops the run.
    """
    spec = _tasks.spec(task)
    check_inputs(task, demos, policy)
    if policy is None:
        policy = _bc.warm_start_policy(demos, config.seed)
    _base.set_start_noise(policy, config.start_log_std)
    flow_seed, init_seed, sample_seed, env_seed = (
        int(s) for s in np.random.SeedSequence(config.seed).generate_state(4))
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(init_seed)
        learner = make_learner(policy, config, spec.obs_dim)
    generator = torch.Generator().manual_seed(sample_seed)
    # ppo.terminate: a training-only termination (hopper-fall; None in the presets)
    envs = EnvBatch(task, config.n_envs, env_seed, None, config.ppo.terminate)
    expert_obs, expert_act = expert_pairs(demos)
    expert_states = torch.from_numpy(np.concatenate([t.observations for t in demos.trajectories]))
    flow_config = dataclasses.replace(config.flow_config(), seed=flow_seed)

    flow, scale, log = None, None, []
    disc = (_dc_disc.DiscriminatorReward(expert_states, spec.obs_dim, flow_seed)
            if config.reward == "gail" else None)
    loop, it = 0, 0   # the next (loop, iteration) to run; it == 0: the loop's flow fit is next
    if checkpoint is not None and pathlib.Path(checkpoint).exists():
        loop, it, flow, scale, log = _load_checkpoint(checkpoint, task, config, learner,
                                                      generator, envs, disc)

    total = config.loops * config.iterations
    bar = _progress.bar(total=total, initial=loop * config.iterations + it, desc=f"DC {task}",
                        unit="it", enabled=progress)
    env_steps = log[-1]["env_steps"] if log else 0
    stopped = False
    try:
        while loop < config.loops and not stopped:
            if it == 0 and disc is None:   # Stage 1: fit (loop 0) or refit P_w
                t0 = time.perf_counter()
                if loop == 0:
                    states = _subsample(expert_states, config.flow_states, generator)
                    flow, flog = _softflow.fit(states, flow_config, progress=False)
                else:
                    learner_states = _learner_states(task, learner, config, generator)
                    env_steps += learner_states.shape[0]
                    n = min(config.flow_states, len(learner_states), len(expert_states))
                    states = torch.cat([_subsample(expert_states, n, generator),
                                        _subsample(learner_states, n, generator)])
                    flow, flog = _softflow.fit_more(flow, states, flow_config,
                                                    iterations=config.flow_refit_iterations,
                                                    progress=False)
                scale = RewardScale.from_expert(
                    state_log_density(flow, _subsample(expert_states, 2000, generator)).numpy())
                log.append({"kind": "flow", "loop": loop, "env_steps": env_steps,
                            "flow_nll": float(np.mean([r["nll"] for r in flog[-20:]])),
                            "flow_seconds": time.perf_counter() - t0,
                            "reward_low": scale.low, "reward_high": scale.high})
            while it < config.iterations:
                start = time.perf_counter()
                if config.update == "average":
                    copy_into(learner.pi_prime, learner.pi)   # Alg. 2: copy pi to pi'
                batch = collect_batch(envs, learner.pi_prime, learner.value_fn,
                                      config.n_steps, generator)
                disc_row = {}
                if disc is None:
                    logp = state_log_density(flow, batch.next_obs)
                    rewards = logp if config.reward == "raw" else scale(logp)
                else:
                    rewards, disc_row = disc(batch.next_obs, generator)
                    logp = torch.full_like(rewards, math.nan)
                row = admm_iteration(learner, batch, rewards, expert_obs, expert_act, config,
                                     generator)
                row.update(disc_row)
                env_steps += config.batch_size
                it += 1
                row = {"kind": "iteration", "loop": loop, "iteration": it,
                       "env_steps": env_steps, "reward_mean": float(rewards.mean()),
                       "log_p_mean": float(logp.mean()),
                       "episode_return": (float(np.mean(batch.episode_returns))
                                          if batch.episode_returns else math.nan),
                       **row, "steps_per_second": config.batch_size
                       / (time.perf_counter() - start)}
                log.append(row)
                bar.update(1)
                bar.set_postfix(loop=loop, r=f"{row['reward_mean']:.2f}",
                                dpi=f"{row['param_change_l1']:.2f}")
                if callback is not None and callback(row, learner.pi):
                    stopped = True
                    break
                if checkpoint is not None and it % checkpoint_every == 0 \
                        and it < config.iterations:
                    _save_checkpoint(checkpoint, task, config, loop, it, learner, flow, scale,
                                     generator, envs, log, disc)
            if stopped:
                break
            loop, it = loop + 1, 0
            if checkpoint is not None:
                _save_checkpoint(checkpoint, task, config, loop, it, learner, flow, scale,
                                 generator, envs, log, disc)
            if stop_after_loop is not None and loop > stop_after_loop:
                break
    finally:
        bar.close()
    learner.pi.meta = {**getattr(learner.pi, "meta", {}), "algorithm": "dc",
                       "dc_config": json.loads(config.to_json())}
    return TrainResult(learner.pi, log, {"flow": flow, "value": learner.value_fn}, "dc")


@_timing.timed("refit_rollout")
def _learner_states(task: str, learner: Learner, config: DCConfig,
                    generator: torch.Generator) -> torch.Tensor:
    """Alg. 1, line 5: ``n_envs`` whole episodes of the stochastic policy pi, from initial
    states and action noise drawn with ``generator`` (apart from PPO's running episodes)."""
    from dc_lesson.data import rollout as _rollout
    from dc_lesson.nn.policies import StochasticPolicy
    seed = int(torch.randint(2 ** 31 - 1, (1,), generator=generator))
    trajs = _rollout.collect(task, StochasticPolicy(learner.pi, seed=seed), config.n_envs,
                             seed=seed, batch=config.n_envs, progress=False)
    return torch.from_numpy(np.concatenate([t.observations[1:] for t in trajs]))


def _save_checkpoint(path, task, config, loop, it, learner, flow, scale, generator, envs, log,
                     disc=None):
    no_flow = flow is None   # reward="gail": a discriminator instead
    atomic_torch_save({
        "format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION, "task": task,
        "config": config.to_json(), "loop": loop, "iteration": it,
        "learner": _state(learner),
        "policy_args": json.dumps(learner.pi.config()),
        "flow_args": "null" if no_flow else json.dumps(flow.config()),
        "flow": {} if no_flow else flow.state_dict(),
        "flow_train_config": "null" if no_flow else flow.train_config.to_json(),
        "scale": [] if no_flow else [scale.low, scale.high],
        "disc": {} if disc is None else disc.state_dict(), "generator": generator.get_state(),
        "envs": envs.state_dict(), "log": json.dumps(log)}, path)


def _load_checkpoint(path, task, config, learner, generator, envs, disc=None):
    ckpt = load_checked(path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, "DC checkpoint",
                        checkpoint_fix(path))
    check_checkpoint(path, ckpt, task, json.loads(ckpt["config"]),
                     json.loads(config.to_json()), what="DC checkpoint")
    if json.loads(ckpt["policy_args"]) != learner.pi.config():
        raise PolicyFileError(f"DC checkpoint {path} holds a policy built as "
                              f"{ckpt['policy_args']}, not {json.dumps(learner.pi.config())}")
    _load_state(learner, ckpt["learner"])
    generator.set_state(ckpt["generator"])
    envs.load_state_dict(ckpt["envs"])
    flow = scale = None
    if disc is not None:
        disc.load_state_dict(ckpt["disc"])
    elif json.loads(ckpt["flow_args"]) is not None:   # None: saved before loop 0's fit
        flow = _softflow.SoftFlow(**json.loads(ckpt["flow_args"]))
        flow.load_state_dict(ckpt["flow"])
        flow.train_config = _softflow.SoftFlowConfig.from_json(ckpt["flow_train_config"])
        scale = RewardScale(*ckpt["scale"])
    return int(ckpt["loop"]), int(ckpt["iteration"]), flow, scale, json.loads(ckpt["log"])


__all__ = ["DCConfig", "DC_DEFAULTS", "STORED_NUMERICS", "preset", "Learner", "RewardScale", "admm_iteration", "average_into", "copy_into",
           "expert_pairs", "flat", "make_learner", "policy_parameters", "sample_bc_pairs",
           "state_log_density", "train"]
