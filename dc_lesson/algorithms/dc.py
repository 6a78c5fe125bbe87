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

**Algorithm 1 (loops),** as :func:`train` runs it (the paper's line numbers on the right):

    for loop = 0 .. L-1:                                                        (line 4)
        Stage 1, P_w (none with reward="gail"):
            loop 0: fit P_w on expert states                                    (lines 1-2)
            later:  T <- n_envs episodes of pi                                  (line 5)
                    refit P_w, from its weights, on n expert + n of T's states  (lines 6-7)
            the reward's scale from log P_w of expert states
        Stage 2: N iterations of Algorithm 2                                    (lines 3, 8)
        (a checkpoint every ``checkpoint_every`` iterations and at the loop's end)

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
  settings that keep what DC learns (issue 14): training steps of 0.5 (``flow.step_size``: two
  rk4 steps; held-out NLL no worse than at 0.25, ``dc-lesson perf flow-fit``), the reward's z
  at steps of at most 0.5 between the nodes of a 3-point Gauss-Legendre rule for the trace
  integral (``flow.eval_step_size``, ``flow.eval_quadrature``; on held-out expert states,
  against the reference solver, about 0.04 nats mean error, 0.24 at most, and a rank
  correlation of 0.99, the order being what the scaled reward reads), and the flow's tanh by
  NumPy's kernel (``flow.tanh``; ``density._trace``).  Runs before 2026-12-04 used steps of 0.25, 4 nodes
  and torch's tanh (:data:`STORED_NUMERICS`); ``dc-lesson perf dc-fit --variant defaults``
  compares the two over ten seeds.  Fitted on up to ``flow_states`` expert states in loop 0
  (``flow.iterations`` steps), refitted in later loops on the same number of expert and
  learner states each (``flow_refit_iterations`` steps, a fresh Adam; the standardisation
  stays the first fit's, so rewards stay comparable across loops).
  Learner states for a refit come from ``n_envs`` fresh episodes of the stochastic policy, which
  count as environment interactions.

**Logged every iteration:** BC's NLL, PPO's terms, the mean reward and mean log P_w(s'), the L1
norm of the change of pi's parameters over the iteration (the paper's Figure 6), the L1 distance
between pi and pi' before averaging, the primal and dual residuals (ADMM), environment steps and
steps per second.

**Determinism and checkpoints.**  ``config.seed`` decides the flow's seed, the critic's
initialisation, one torch generator (actions, minibatches, pairs) and the episode seeds.
:func:`train` saves everything (policies, critic, optimisers, flow, consensus variables,
generator, environments, log) with :func:`~dc_lesson.algorithms.base.save_run` at the end of
every loop and every ``checkpoint_every`` iterations, and resumes from the file: a resumed run
ends identical to an uninterrupted one.  Algorithm 2's two updates live in
:mod:`dc_lesson.algorithms._dc_consensus` (:func:`parameter_averaging`, :func:`consensus_admm`).
"""

from __future__ import annotations

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
from dc_lesson.algorithms._dc_consensus import (Learner, average_into, consensus_admm,
                                                copy_into, flat, make_learner,
                                                parameter_averaging, policy_parameters,
                                                sample_bc_pairs)
from dc_lesson.algorithms.base import TrainResult, check_inputs, load_run, save_run
from dc_lesson.checks import check_fields
from dc_lesson.density import softflow as _softflow
from dc_lesson import tasks as _tasks
from dc_lesson.data import Demonstrations
from dc_lesson.nn.policies import GaussianPolicy
from dc_lesson.algorithms.ppo import EnvBatch, PPOConfig, collect_batch

UPDATES = ("average", "admm")
REWARDS = ("scaled", "raw", "gail")
OPTIMIZER_STATES = ("own", "reset")


# PPO's step on pi' in DC: 8 x 250 steps per iteration, 4 epochs of 8 minibatches (32 gradient
# steps, as many as the BC step takes), the critic 64-64.
_DC_PPO = PPOConfig(n_envs=8, n_steps=250, n_epochs=4, n_minibatches=8, clip_coef=0.2,
                    gamma=0.99, gae_lambda=0.95, vf_coef=0.5, ent_coef=0.0, hidden=(64, 64),
                    anneal_lr=False)


# P_w's settings in DC: SoftFlow's defaults but for 300 steps of a fixed-step rk4 fit at step
# 0.5, the reward's solve at steps of at most 0.5 with a 3-node trace rule, and NumPy's tanh
# (the module docstring gives the measurements behind each).
_DC_FLOW = _softflow.SoftFlowConfig(hidden=(64, 64, 64), sigma_max=0.1, lr=1e-3, iterations=300,
                                    solver="rk4", step_size=0.5, eval_step_size=0.5,
                                    eval_quadrature=3, tanh="numpy")

# The flow's numerics of every DC run before 2026-12-04 (changes to ``DCConfig.flow``); perf
# dc-fit and perf runs compare today's defaults with them.
STORED_NUMERICS = {"step_size": 0.25, "eval_step_size": 0.25, "eval_quadrature": 4,
                   "tanh": "torch"}

# The stored form of ``DCConfig.flow``: every cell listed before the flow's settings were nested
# names them by these flat names (stored name -> SoftFlowConfig field), so ``to_json`` keeps
# them and the stored cells keep their identity; any other flow setting that differs from
# ``_DC_FLOW`` is stored under "flow".
FLOW_STORED_NAMES = {"flow_iterations": "iterations", "flow_hidden": "hidden", "flow_lr": "lr",
                     "sigma_max": "sigma_max", "flow_step": "step_size",
                     "reward_step": "eval_step_size", "reward_nodes": "eval_quadrature",
                     "flow_tanh": "tanh"}

# PPO settings DC sets itself, each for a reason; a ``ppo`` that sets one to neither DC's own
# PPO default (``_DC_PPO``) nor what DC uses is refused, never silently overridden.
PPO_SET_BY_DC = {"lr": "DC's one AdamW rate for both copies: set DCConfig.lr instead",
                 "max_grad_norm": "DC's one clip for both steps: set DCConfig.max_grad_norm "
                                  "instead",
                 "anneal_lr": "DC's rate is not annealed: set ppo.anneal_lr=False"}


@dataclasses.dataclass(frozen=True)
class DCConfig:
    """Every knob of DC.  See the module docstring for why each default is what it is."""

    # Algorithm 1
    loops: int = 2               # L: loop 0 (P_w on expert states) plus L - 1 refit loops
    iterations: int = 50         # N: Algorithm 2 iterations per loop
    flow_states: int = 4000      # expert states per fit (and as many learner states in a refit)
    flow_refit_iterations: int = 100   # gradient steps of each later refit
    # P_w: SoftFlow's own settings, nested (the module docstring says why each differs from
    # SoftFlow's defaults).  ``flow.iterations`` is loop 0's fit; ``flow.seed`` is not read
    # (the fit's seed is a stream of DC's ``seed``), so a non-zero one is refused.
    flow: _softflow.SoftFlowConfig = dataclasses.field(default_factory=lambda: _DC_FLOW)
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
        check_fields(self, positive=("loops", "iterations", "flow_states", "rho",
                                     "bc_steps", "bc_batch_size", "lr", "max_grad_norm"),
                     non_negative=("flow_refit_iterations", "weight_decay", "seed"))
        if not isinstance(self.ppo, PPOConfig):
            raise TypeError(f"DCConfig.ppo must be a ppo.PPOConfig, got {type(self.ppo)}")
        _base.check_flow(self)
        if self.ppo.value_warmup is not None:   # never read by DC's loop: refuse, not ignore
            raise ValueError("DCConfig.ppo.value_warmup is PPO's own loop's; DC's critic "
                             "trains with its PPO step from the first iteration")
        for name, why in PPO_SET_BY_DC.items():
            value = getattr(self.ppo, name)
            if value not in (getattr(self.ppo_config, name), getattr(_DC_PPO, name)):
                raise ValueError(f"DCConfig.ppo.{name} = {value!r} is not read: {why}")
        for name, allowed in (("update", UPDATES), ("reward", REWARDS),
                              ("optimizer_state", OPTIMIZER_STATES)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"DCConfig.{name} must be one of {allowed}, got "
                                 f"{getattr(self, name)!r}")
        for name in ("loops", "iterations", "bc_steps", "bc_batch_size", "flow_states"):
            if getattr(self, name) < 1:
                raise ValueError(f"DCConfig.{name} must be at least 1, got "
                                 f"{getattr(self, name)}")
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

    @property
    def ppo_config(self) -> PPOConfig:
        """The PPO settings of the step on pi' (what :func:`ppo.ppo_update` reads): ``ppo``
        with the settings of :data:`PPO_SET_BY_DC`, one batch per update and the run's seed."""
        return dataclasses.replace(self.ppo, lr=self.lr, max_grad_norm=self.max_grad_norm,
                                   anneal_lr=False, total_steps=self.batch_size,
                                   seed=self.seed)

    def with_ppo(self, **changes) -> "DCConfig":
        """The same configuration with some of PPO's settings changed."""
        return dataclasses.replace(self, ppo=dataclasses.replace(self.ppo, **changes))

    def with_flow(self, **changes) -> "DCConfig":
        """The same configuration with some of P_w's SoftFlow settings changed."""
        return dataclasses.replace(self, flow=dataclasses.replace(self.flow, **changes))

    def env_steps(self, task: str) -> int:
        """Environment interactions of a whole run: the policy batches plus the learner
        episodes sampled for each refit of P_w (none with ``reward="gail"``: no flow)."""
        horizon = _tasks.spec(task).horizon
        refits = 0 if self.reward == "gail" else self.loops - 1
        return self.loops * self.iterations * self.batch_size + refits * self.n_envs * horizon

    def to_json(self) -> str:
        d = _base.unset_dropped(dataclasses.asdict(self))
        d["ppo"] = json.loads(self.ppo_config.to_json())
        d.update(_base.stored_flow(d.pop("flow"), FLOW_STORED_NAMES, _DC_FLOW))
        return json.dumps(d, sort_keys=True)


# -- presets -------------------------------------------------------------------------------------

# The settings of every DC run of the benchmarks; the iterations follow the budget.
DC_DEFAULTS = dict(loops=2)


def preset(budget, seed: int = 0, **overrides) -> DCConfig:
    """DC's configuration for a budget: ``il_steps`` interactions split over the loops."""
    base = DCConfig(**{**DC_DEFAULTS, **overrides, "seed": seed})
    if budget.is_smoke:
        base = dataclasses.replace(base.with_ppo(n_envs=2, n_steps=64, n_minibatches=4,
                                                 n_epochs=2).with_flow(iterations=5,
                                                                       hidden=(16, 16)),
                                   flow_states=300, flow_refit_iterations=3, bc_steps=4,
                                   bc_batch_size=64)
    if "iterations" not in overrides:
        per_loop = max(1, budget.il_steps // (base.loops * base.batch_size))
        base = dataclasses.replace(base, iterations=per_loop)
    return base


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


# -- Algorithm 1 ---------------------------------------------------------------------------------

expert_pairs = _bc.pairs   # all (state, action) pairs of the demonstrations, as tensors


def expert_states(demos: Demonstrations) -> torch.Tensor:
    """The expert states P_w is fitted on: every observation of each whole demonstration
    (its last too, which no action follows); of a subsampled one (``data.subsample``) the
    kept steps' states only, since the protocol shows the learner no others."""
    return torch.from_numpy(np.concatenate([t.observations if t.kept is None
                                            else t.observations[t.kept]
                                            for t in demos.trajectories]))


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
    run = _setup(task, demos, config, policy)
    done = 0   # iterations of Algorithm 2 run so far, over all loops
    if checkpoint is not None and pathlib.Path(checkpoint).exists():
        done = _resume(run, checkpoint)
    N = config.iterations
    bar = _progress.bar(total=config.loops * N, initial=done, desc=f"DC {task}", unit="it",
                        enabled=progress)
    first_loop, first_it = divmod(done, N)
    try:
        for loop in range(first_loop, config.loops):
            first = first_it if loop == first_loop else 0   # > 0: resumed mid-loop, P_w loaded
            if first == 0 and run.disc is None:             # Stage 1, P_w (Alg. 1):
                t0 = time.perf_counter()
                if loop == 0:                               # lines 1-2: expert states only
                    states = _subsample(run.expert_states, config.flow_states, run.generator)
                    run.flow, flog = _softflow.fit(states, run.flow_config, progress=False)
                else:                                       # lines 5-7: pi's states too
                    states = _expert_and_learner_states(run)
                    run.flow, flog = _softflow.fit_more(run.flow, states, run.flow_config,
                                                        iterations=config.flow_refit_iterations,
                                                        progress=False)
                _rescale(run, loop, flog, t0)
            for it in range(first, N):                      # Stage 2, lines 3 and 8
                row = _iteration(run, loop, it)             # one iteration of Algorithm 2
                bar.update(1)
                bar.set_postfix(loop=loop, r=f"{row['reward_mean']:.2f}",
                                dpi=f"{row['param_change_l1']:.2f}")
                if callback is not None and callback(row, run.learner.pi):
                    return _result(run)
                if checkpoint is not None and ((it + 1) % checkpoint_every == 0 or it + 1 == N):
                    _save(run, checkpoint, loop * N + it + 1)
            if stop_after_loop is not None and loop >= stop_after_loop:
                break
    finally:
        bar.close()
    return _result(run)


@dataclasses.dataclass
class _Run:
    """A run between two iterations: what a checkpoint holds, and the expert's data."""
    task: str
    config: DCConfig
    learner: Learner
    generator: torch.Generator   # actions, minibatches, pairs, subsamples, refit episodes
    envs: EnvBatch
    expert_obs: torch.Tensor     # the expert's pairs (BC)
    expert_act: torch.Tensor
    expert_states: torch.Tensor  # every expert state (P_w)
    flow_config: _softflow.SoftFlowConfig
    disc: _dc_disc.DiscriminatorReward | None   # reward="gail": in place of P_w
    flow: _softflow.SoftFlow | None = None
    scale: RewardScale | None = None
    log: list = dataclasses.field(default_factory=list)
    env_steps: int = 0


def _setup(task, demos, config: DCConfig, policy) -> _Run:
    """The warm start (fitted here if None), the seeds, the copies, the generator, the
    environments and the expert's data."""
    spec = _tasks.spec(task)
    check_inputs(task, demos, policy)
    if policy is None:
        policy = _bc.warm_start_policy(demos, config.seed)
    _base.set_start_noise(policy, config.start_log_std)
    flow_seed, init_seed, sample_seed, env_seed = _base.seed_streams(
        config.seed, "flow", "init", "sample", "env")
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(init_seed)
        learner = make_learner(policy, config, spec.obs_dim)
    generator = torch.Generator().manual_seed(sample_seed)
    # ppo.terminate: a training-only termination (hopper-fall; None in the presets)
    envs = EnvBatch(task, config.n_envs, env_seed, None, config.ppo.terminate)
    expert_obs, expert_act = expert_pairs(demos)
    e_states = expert_states(demos)
    disc = (_dc_disc.DiscriminatorReward(e_states, spec.obs_dim, flow_seed)
            if config.reward == "gail" else None)
    return _Run(task, config, learner, generator, envs, expert_obs, expert_act, e_states,
                dataclasses.replace(config.flow, seed=flow_seed), disc)


def _expert_and_learner_states(run: _Run) -> torch.Tensor:
    """Alg. 1, lines 5-6: ``n_envs`` fresh episodes of pi, then as many of their states as of
    the expert's (at most ``flow_states`` each), for P_w's refit."""
    visited = _learner_states(run.task, run.learner, run.config, run.generator)
    run.env_steps += visited.shape[0]
    n = min(run.config.flow_states, len(visited), len(run.expert_states))
    return torch.cat([_subsample(run.expert_states, n, run.generator),
                      _subsample(visited, n, run.generator)])


def _rescale(run: _Run, loop: int, flog: list, t0: float) -> None:
    """The reward's scale from log P_w of expert states, after a fit; logs the loop's flow row
    (``t0``: when the stage began)."""
    expert = _subsample(run.expert_states, 2000, run.generator)
    run.scale = RewardScale.from_expert(state_log_density(run.flow, expert).numpy())
    run.log.append({"kind": "flow", "loop": loop, "env_steps": run.env_steps,
                    "flow_nll": float(np.mean([r["nll"] for r in flog[-20:]])),
                    "flow_seconds": time.perf_counter() - t0,
                    "reward_low": run.scale.low, "reward_high": run.scale.high})


def _iteration(run: _Run, loop: int, it: int) -> dict:
    """Stage 2, one iteration of Algorithm 2: pi' samples a batch, its next states are scored,
    and the paper's averaging or consensus ADMM updates the copies.  Returns the log row."""
    c, L = run.config, run.learner
    start = time.perf_counter()
    if c.update == "average":
        copy_into(L.pi_prime, L.pi)                                   # Alg. 2, line 3
    batch = collect_batch(run.envs, L.pi_prime, L.value_fn, c.n_steps, run.generator)  # line 4
    if run.disc is None:
        logp = state_log_density(run.flow, batch.next_obs)
        rewards, disc_terms = (logp if c.reward == "raw" else run.scale(logp)), {}
    else:
        rewards, disc_terms = run.disc(batch.next_obs, run.generator)
        logp = torch.full_like(rewards, math.nan)
    update = parameter_averaging if c.update == "average" else consensus_admm   # lines 5-8
    terms = update(L, batch, rewards, run.expert_obs, run.expert_act, c, run.generator)
    run.env_steps += c.batch_size
    row = {"kind": "iteration", "loop": loop, "iteration": it + 1, "env_steps": run.env_steps,
           "reward_mean": float(rewards.mean()), "log_p_mean": float(logp.mean()),
           "episode_return": (float(np.mean(batch.episode_returns))
                              if batch.episode_returns else math.nan),
           **terms, **disc_terms,
           "steps_per_second": c.batch_size / (time.perf_counter() - start)}
    run.log.append(row)
    return row


def _result(run: _Run) -> TrainResult:
    pi = run.learner.pi
    pi.meta = {**getattr(pi, "meta", {}), "algorithm": "dc",
               "dc_config": json.loads(run.config.to_json())}
    return TrainResult(pi, run.log, {"flow": run.flow, "value": run.learner.value_fn}, "dc")


def _subsample(x: torch.Tensor, n: int, generator: torch.Generator) -> torch.Tensor:
    if len(x) <= n:
        return x
    return x[torch.randperm(len(x), generator=generator)[:n]]


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


# -- checkpoints (base.save_run) -----------------------------------------------------------------

CHECKPOINT_FORMAT = "dc_lesson.dc.checkpoint"
# Version 1 was DC's own layout (before issue 37); load_checked refuses it with the fix.
CHECKPOINT_VERSION = 2


def _parts(run: _Run) -> tuple[dict, dict]:
    """The networks and optimisers a checkpoint holds, by name (not the flow, which a resumed
    run builds from the file)."""
    L = run.learner
    networks = {"pi": L.pi, "pi_prime": L.pi_prime, "value": L.value_fn}
    optimizers = {"opt_bc": L.opt_bc, "opt_ppo": L.opt_ppo}
    if L.pi_bc is not None:
        networks["pi_bc"] = L.pi_bc
    if run.disc is not None:
        networks["disc"], optimizers["opt_disc"] = run.disc.disc, run.disc.optimizer
    return networks, optimizers


def _save(run: _Run, path, done: int) -> None:
    networks, optimizers = _parts(run)
    flow = {}
    if run.flow is not None:
        networks["flow"] = run.flow
        flow = {"flow_train_config": run.flow.train_config.to_json(),
                "scale": [run.scale.low, run.scale.high]}
    save_run(path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, task=run.task,
             config_json=run.config.to_json(), update=done, networks=networks,
             optimizers=optimizers, generators={"generator": run.generator}, envs=run.envs,
             log=run.log, duals=run.learner.duals or [], **flow)


def _resume(run: _Run, path) -> int:
    """Restores ``run`` from ``path``; returns the iterations done."""
    networks, optimizers = _parts(run)
    done, run.log, ckpt = load_run(
        path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, "DC checkpoint", task=run.task,
        saved_config=lambda c: json.loads(c["config"]),
        now_config=json.loads(run.config.to_json()), networks=networks,
        optimizers=optimizers, generators={"generator": run.generator}, envs=run.envs)
    if run.learner.duals is not None:
        run.learner.duals = [u.clone() for u in ckpt["duals"]]
    if run.disc is None:
        run.flow = _softflow.SoftFlow(**json.loads(ckpt["flow_args"]))
        run.flow.load_state_dict(ckpt["flow"])
        run.flow.train_config = _softflow.SoftFlowConfig.from_json(ckpt["flow_train_config"])
        run.scale = RewardScale(*ckpt["scale"])
    run.env_steps = run.log[-1]["env_steps"] if run.log else 0
    return done


__all__ = ["CHECKPOINT_FORMAT", "CHECKPOINT_VERSION", "DCConfig", "DC_DEFAULTS", "Learner",
           "RewardScale", "STORED_NUMERICS", "average_into", "consensus_admm", "copy_into",
           "expert_pairs", "expert_states", "flat", "make_learner", "parameter_averaging",
           "policy_parameters", "preset", "sample_bc_pairs", "state_log_density", "train"]
