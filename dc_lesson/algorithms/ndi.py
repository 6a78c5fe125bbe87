r"""Neural density imitation (NDI, Kim, Garg, Menda, Fong, Eysenbach, Levine, Ermon, ICML 2021).

The objective.  NDI imitates by maximum occupancy-entropy RL: it maximises the expert's
log-density along the learner's own state-action distribution rho_pi, plus the entropy of
that distribution,

    max_pi  E_{(s,a) ~ rho_pi} [ log q(s, a) ]  +  lambda H(rho_pi),                  (NDI)

which for lambda = 1 is -KL(rho_pi || q) (the reverse KL to the expert's occupancy: mass where
the expert has none is punished, modes the learner skips are not, except through the entropy
term).  Phase 1 fits q to the expert's pairs once, with a density model (the paper: an
autoregressive flow or an energy-based model); phase 2 is RL on the reward log q with an
entropy bonus.  H(rho_pi) = H(s) + E_s H(pi(.|s)); NDI bounds the state part from below with
its SAELBO estimator and leaves the policy part to its RL learner's entropy term.

Our stand-in for SAELBO is a k-nearest-neighbour (Kozachenko-Leonenko) estimate of the state
entropy over each batch's N states s_i (standardised, dimension d, eps_i the distance to the
k-th nearest other state):

    H_kNN = psi(N) - psi(k) + log V_d + (d / N) sum_i log eps_i,     V_d = pi^{d/2} / Gamma(d/2 + 1),

and each state's reward share is its term h_i = psi(N) - psi(k) + log V_d + d log eps_i, so
the batch mean of the bonus is the estimate itself (a particle-based entropy reward, as in
APT, Liu and Abbeel 2021).  The reward of step t is

    r_t = scale(log q(s_t, a_t)) + lambda * h(s'_t).

Pseudo-code (:func:`train`):

    q <- SoftFlow fitted to up to flow_pairs expert (s, a)                   (phase 1)
    every iteration:                                                         (phase 2)
        collect n_envs x n_steps pairs with the stochastic policy           (ppo.collect_batch)
        r_t <- scale(log q(s_t, clip(a_t))) + lambda h_kNN(s'_t)             (Reward)
        PPO on r                                                             (ppo.ppo_update)

Choices (each a field of :class:`NDIConfig`):

* *The density model* is SoftFlow, the library's own (:mod:`dc_lesson.density.softflow`,
  chapter 3), not NDI's MADE/MAF or EBM: the same family DC uses, so the two differ in what
  they do with a density, not in the density.  Fitted with DC's settings (rk4, step 0.25).
* *On (s, a)*, not on s: NDI's objective is the state-action occupancy, and only a model of
  (s, a) pays the learner for the expert's *actions*; DC, by contrast, models s alone and gets
  the actions from its BC term.  The action enters as applied (clipped to the bounds).
* *The reward's scale* (``reward="scaled"``): log q mapped linearly to [0, 1] exactly as DC
  maps log P_w (``dc.RewardScale``: 1 at the expert's median, 0 at q_0.01 - (median - q_0.01)),
  because a flow's raw log-density runs from about +20 to -1e4 and its tail would swamp PPO's
  advantages; ``"raw"`` uses log q unchanged.
* *Entropy*: the kNN bonus above, with ``knn_k`` = 5 neighbours over the whole batch's next
  states, standardised by the expert's state statistics, weight ``entropy_coef`` (lambda; the
  policy part of H(rho_pi) is PPO's ``ent_coef``, 0 by default as in GAIL).
* PPO with GAIL's settings, the frozen expert normaliser and the critic warm-up
  (:mod:`dc_lesson.algorithms._reward_ppo`); NDI used SAC.

What it gives on reacher1 (``tests/test_baselines.py``, measured): from a fresh policy that
stays still (return 0), 940 after 40k interactions; from the BC warm start (578), 678.

Determinism: ``seed`` decides the flow's fit, the network initialisation, PPO's generator and
the episode seeds.  A resumed run refits q from the same seed (q is never updated afterwards,
so it is the same density).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch
from scipy import special

from dc_lesson import tasks as _tasks
from dc_lesson.checks import check_fields
from dc_lesson.algorithms import _reward_ppo
from dc_lesson.algorithms import bc as _bc
from dc_lesson.algorithms import ppo as _ppo
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms.base import TrainResult, check_inputs
from dc_lesson.algorithms.dc import RewardScale
from dc_lesson.density import softflow as _softflow
from dc_lesson.nn.policies import ACTION_HIGH, ACTION_LOW, GaussianPolicy

REWARDS = ("scaled", "raw")


# q's settings: SoftFlow's defaults but for 300 steps of a fixed-step rk4 fit at step 0.25
# (DC's loop-0 fit as it was when NDI was written).
_NDI_FLOW = _softflow.SoftFlowConfig(hidden=(64, 64, 64), sigma_max=0.1, lr=1e-3, iterations=300,
                                     solver="rk4", step_size=0.25)
# The stored form of ``NDIConfig.flow`` (see ``base.stored_flow``): the flat names every NDI
# cell was listed with before the nesting.
FLOW_STORED_NAMES = {"flow_iterations": "iterations", "flow_hidden": "hidden", "flow_lr": "lr",
                     "sigma_max": "sigma_max"}


@dataclasses.dataclass(frozen=True)
class NDIConfig(_reward_ppo.PPOImitationConfig):
    """Every knob of NDI; PPO's own (and the run's length) live in ``ppo``."""

    ppo: _ppo.PPOConfig = dataclasses.field(default_factory=_reward_ppo.imitation_ppo_default)
    flow_pairs: int = 4000       # expert (s, a) pairs q is fitted on (a subsample)
    # q: SoftFlow's own settings, nested; ``flow.seed`` is not read (the fit takes a stream of
    # NDI's ``seed``), so a non-zero one is refused.
    flow: _softflow.SoftFlowConfig = dataclasses.field(default_factory=lambda: _NDI_FLOW)
    reward: str = "scaled"       # "scaled": log q mapped to [0, 1] as DC's; "raw": log q
    entropy_coef: float = 0.01   # lambda, the weight of the kNN state-entropy bonus
    knn_k: int = 5               # neighbours of the entropy estimate
    value_warmup: int = 2        # first iterations that train only the critic
    bc_warm_start: bool = True   # the benchmark starts from bc.warm_start
    start_log_std: float | None = None   # a given (warm) start's log-std is set to this
    #                              first (None: kept); base.START_LOG_STD is the shared rule
    seed: int = 0

    def __post_init__(self):
        # Types first (a 0-wide layer, knn_k=True, an infinite rate), then NDI's own ranges.
        check_fields(self, positive=("flow_pairs", "knn_k"),
                     non_negative=("entropy_coef", "value_warmup", "seed"))
        if self.reward not in REWARDS:
            raise ValueError(f"NDIConfig.reward must be one of {REWARDS}, got {self.reward!r}")
        if self.flow_pairs < 2 or self.knn_k < 1:
            raise ValueError("NDIConfig.flow_pairs >= 2, knn_k >= 1")
        if self.entropy_coef < 0:
            raise ValueError(f"NDIConfig.entropy_coef must be >= 0, got {self.entropy_coef}")
        _base.check_flow(self)
        self.check_ppo()

    def to_dict(self) -> dict:
        d = super().to_dict()
        d.update(_base.stored_flow(d.pop("flow"), FLOW_STORED_NAMES, _NDI_FLOW))
        return d

    def with_flow(self, **changes) -> "NDIConfig":
        """The same configuration with some of q's SoftFlow settings changed."""
        return dataclasses.replace(self, flow=dataclasses.replace(self.flow, **changes))


def sized(total_steps: int, seed: int = 0, base: NDIConfig | None = None) -> NDIConfig:
    """NDI's configuration for ``total_steps`` interactions (see ``_reward_ppo.sized``)."""
    return _reward_ppo.sized(base or NDIConfig(), total_steps, seed)


def preset(budget, seed: int = 0) -> NDIConfig:
    """NDI at a budget: ``il_steps`` interactions; a tiny flow at ``smoke``."""
    cfg = sized(budget.il_steps, seed)
    if budget.is_smoke:
        cfg = dataclasses.replace(cfg, flow_pairs=300).with_flow(iterations=5, hidden=(16, 16))
    return cfg


# -- the reward ----------------------------------------------------------------------------------

def pair_inputs(obs, act) -> torch.Tensor:
    """(s, clip(a)) concatenated: the point q is evaluated at."""
    obs = torch.as_tensor(obs, dtype=torch.float32)
    act = torch.as_tensor(act, dtype=torch.float32).clamp(ACTION_LOW, ACTION_HIGH)
    return torch.cat([obs, act], -1)


def log_density(density, obs, act) -> torch.Tensor:
    """log q(s, a) for (..., obs_dim) and (..., act_dim), any ``density`` with ``log_prob``
    of (n, obs_dim + act_dim) rows (a SoftFlow, a torch distribution)."""
    x = pair_inputs(obs, act)
    with torch.no_grad():
        return density.log_prob(x.reshape(-1, x.shape[-1])).reshape(x.shape[:-1])


def knn_entropy_terms(x: torch.Tensor, k: int = 5, chunk: int = 2048) -> torch.Tensor:
    """The Kozachenko-Leonenko terms h_i of (N, d) points (module docstring); their mean is
    the kNN estimate of the points' differential entropy (nats)."""
    x = torch.as_tensor(x, dtype=torch.float64)
    n, d = x.shape
    if n <= k:
        raise ValueError(f"a {k}-nearest-neighbour entropy needs more than {k} points, got {n}")
    eps = torch.empty(n, dtype=torch.float64)
    for lo in range(0, n, chunk):
        dist = torch.cdist(x[lo:lo + chunk], x)
        eps[lo:lo + chunk] = dist.topk(k + 1, largest=False).values[:, k]   # [0] is itself
    log_vd = 0.5 * d * math.log(math.pi) - math.lgamma(0.5 * d + 1)
    const = special.digamma(n) - special.digamma(k) + log_vd
    return const + d * torch.log(eps.clamp_min(1e-12))


@dataclasses.dataclass
class Reward:
    """r = scale(log q(s, a)) + entropy_coef * h_kNN(s'), the states standardised by
    ``state_mean`` / ``state_std`` for the entropy term; ``scale`` None means raw log q."""

    density: object
    scale: RewardScale | None
    entropy_coef: float
    state_mean: torch.Tensor
    state_std: torch.Tensor
    k: int = 5

    def __call__(self, obs, act, next_obs) -> tuple[torch.Tensor, dict]:
        logq = log_density(self.density, obs, act)
        r = logq if self.scale is None else self.scale(logq)
        terms = {"log_q_mean": float(logq.mean())}
        if self.entropy_coef > 0:
            s = (torch.as_tensor(next_obs, dtype=torch.float32) - self.state_mean) / self.state_std
            h = knn_entropy_terms(s.reshape(-1, s.shape[-1]), self.k).reshape(r.shape)
            r = r + self.entropy_coef * h.to(r.dtype)
            terms["state_entropy"] = float(h.mean())
        return r, terms

    def of_batch(self, batch) -> tuple[torch.Tensor, dict]:
        return self(batch.obs, batch.actions, batch.next_obs)


def fit_density(demos, config: NDIConfig, seed: int) -> _softflow.SoftFlow:
    """Phase 1: SoftFlow on up to ``flow_pairs`` expert (s, a), drawn with ``seed``."""
    obs, act = _bc.pairs(demos)
    x = pair_inputs(obs, act)
    g = torch.Generator().manual_seed(seed)
    if len(x) > config.flow_pairs:
        x = x[torch.randperm(len(x), generator=g)[:config.flow_pairs]]
    flow, _ = _softflow.fit(x, dataclasses.replace(config.flow, seed=seed),
                            progress=False)
    return flow


# -- the learner ---------------------------------------------------------------------------------

def train(task: str, demos, config: NDIConfig = NDIConfig(), *,
          policy: GaussianPolicy | None = None, progress: bool = True, checkpoint=None,
          callback=None, checkpoint_every: int = 10) -> TrainResult:
    """NDI on ``task`` from ``demos``; returns a :class:`TrainResult` (``models["flow"]``, q,
    and ``models["value"]``).  ``policy`` where to start (None: fresh), ``checkpoint`` /
    ``callback`` as in GAIL.  ``log``: PPO's terms plus ``reward_mean``, ``log_q_mean`` and
    ``state_entropy`` (the batch's kNN estimate)."""
    spec = _tasks.spec(task)
    check_inputs(task, demos, policy)
    pcfg = config.ppo_config
    init_seed, sample_seed, env_seed, flow_seed = _base.seed_streams(
        config.seed, "init", "sample", "env", "flow")
    e_obs, e_act = _bc.pairs(demos)
    flow = fit_density(demos, config, flow_seed)
    scale = None
    if config.reward == "scaled":
        g = torch.Generator().manual_seed(flow_seed)
        i = torch.randperm(len(e_obs), generator=g)[:2000]
        scale = RewardScale.from_expert(log_density(flow, e_obs[i], e_act[i]).numpy())
    reward = Reward(flow, scale, config.entropy_coef, e_obs.mean(0),
                    e_obs.std(0).clamp_min(1e-3), config.knn_k)
    _base.set_start_noise(policy, config.start_log_std)   # a given start's noise
    policy, value_fn = _reward_ppo.make_networks(spec, pcfg, e_obs, policy, init_seed)
    hooks = _reward_ppo.Hooks("ndi", reward.of_batch, models={"flow": flow})
    return _reward_ppo.run(task, config, hooks, policy, value_fn, sample_seed, env_seed,
                           progress=progress, checkpoint=checkpoint, callback=callback,
                           checkpoint_every=checkpoint_every)


__all__ = ["NDIConfig", "Reward", "fit_density", "knn_entropy_terms", "log_density",
           "pair_inputs", "preset", "sized", "train"]
