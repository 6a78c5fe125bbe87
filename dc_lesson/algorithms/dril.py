r"""Disagreement-regularised imitation learning (DRIL, Brantley, Sun, Henaff, ICLR 2020).

The idea.  BC is right where the expert went and may be anything elsewhere; an *ensemble* of BC
policies, each fitted to a bootstrap resample of the demonstrations, agrees with itself where
the data pin the action down and disagrees where they do not.  DRIL keeps the learner where the
ensemble agrees: it minimises BC's loss plus the expected disagreement along its own states,

    min_pi  J_BC(pi) + E_{(s,a) ~ rho_pi} [ C_U(s, a) ],

with the uncertainty cost, for continuous actions (the authors' code), the variance of the
action a along the ensemble's spread of mean actions mu_1(s) .. mu_E(s):

    C(s, a) = a^T Cov_e[mu_e(s)] a,        Cov_e the sample covariance over the E members,

clipped to a reward of +1 where it is at most q, the disagreement's ``quantile`` (0.98) over the
demonstrations' own pairs, and -1 above it:

    r(s, a) = +1 if C(s, a) <= q_0.98{ C(s_E, a_E) }  else  -1.

The RL part (PPO here, as in the authors' MuJoCo runs) optimises that reward; the BC part is a
few BC steps on the expert's pairs after each PPO update ("interleaved").

Pseudo-code (:func:`train`):

    for e in 1..E: mu_e <- BC on a bootstrap resample of the expert pairs   (fit_ensemble)
    q <- quantile_0.98 of C(s_E, a_E) over the expert pairs                 (cost_threshold)
    pi <- BC on the demonstrations (the warm start; the authors start from BC too)
    every iteration:
        collect n_envs x n_steps pairs with the stochastic policy          (ppo.collect_batch)
        r_t <- +1 if C(s_t, clip(a_t)) <= q else -1                        (dril_reward)
        PPO on r                                                           (ppo.ppo_update)
        bc_steps BC minibatch steps of pi on the expert pairs              (bc.bc_step)

Choices the paper or the issue leave open (each a field of :class:`DRILConfig`):

* *Ensemble*: ``ensemble_size`` = 5 (the authors'), each member a :class:`GaussianPolicy` of
  the library's BC (its mean is the member's action), fitted for ``ensemble_epochs`` epochs
  (no early stopping) on n pairs drawn with replacement from the n expert pairs (a bootstrap of
  pairs, as the authors'); the members differ by their resample and their initialisation.
* *The cost* uses the action as applied (clipped to [-1, 1]) and the members' means clipped
  likewise (the authors clip both); Cov with the 1/(E-1) normalisation.
* *Reward normalisation*: none.  The authors divide the reward by a running std of the
  discounted return; +-1 is already on the scale of the tasks' rewards.
* *BC interleaving*: ``bc_steps`` minibatches of ``bc_batch`` expert pairs after each PPO
  update, with their own AdamW at PPO's learning rate (the authors: one epoch of minibatches
  of 100 over 80% of the pairs per PPO update of 2048 interactions).  The preset's 8 is a
  third of their rate at 4 demonstrations and loses cartpole starts the demonstrations do not
  cover; the competence study, and every grid run after it, takes DC's balance instead, one
  BC step per PPO minibatch step (40; ``experiments.studies.competence.FIXES``).  BC would pull the log-std down to the expert's tiny action noise and switch off
  PPO's exploration, so the BC steps move only the mean network.
* The start: with ``policy=None``, :func:`train` fits the BC warm start itself
  (``bc.warm_start_policy``, log-std reset to PPO's); the learning test passes a fresh policy
  to measure DRIL's own gain.  The observation normaliser stays the start policy's, frozen.

What it gives on cartpole (``tests/test_baselines.py``, measured): from a fresh policy (618),
1000 after 30k interactions with 16 BC steps per iteration.  The learner's pairs sat above the
threshold almost always (1 to 2% paid +1): the ensemble agrees to ~0 on the expert's pairs, so
the reward is mostly -1 and the BC steps do most of the work.

Determinism: ``seed`` decides the ensemble's resamples and initialisations, the warm start, the
critic, PPO's generator, the BC minibatches and the episode seeds.  A resumed run refits the
ensemble from the same seed (it is never updated afterwards, so it is the same ensemble).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from dc_lesson import tasks as _tasks
from dc_lesson.checks import check_fields
from dc_lesson.algorithms import _reward_ppo
from dc_lesson.algorithms import bc as _bc
from dc_lesson.algorithms import ppo as _ppo
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms.base import TrainResult, check_inputs
from dc_lesson.nn.policies import ACTION_HIGH, ACTION_LOW, GaussianPolicy


@dataclasses.dataclass(frozen=True)
class DRILConfig(_reward_ppo.PPOImitationConfig):
    """Every knob of DRIL; PPO's own (and the run's length) live in ``ppo``."""

    ppo: _ppo.PPOConfig = dataclasses.field(default_factory=_reward_ppo.imitation_ppo_default)
    ensemble_size: int = 5       # BC policies in the ensemble (the authors: 5)
    ensemble_epochs: int = 50    # epochs of each member's BC fit on its resample
    ensemble_batch: int = 256    # pairs per member minibatch
    ensemble_lr: float = 1e-3    # the members' AdamW learning rate
    quantile: float = 0.98       # the cost's quantile on the demonstrations (the authors: 0.98)
    bc_steps: int = 8            # BC minibatch steps on pi after every PPO update
    bc_batch: int = 256          # expert pairs per such step
    warm_start_epochs: int = 200  # epoch limit of the BC warm start (policy=None)
    value_warmup: int = 2        # first iterations that train only the critic
    start_log_std: float | None = None   # a given (warm) start's log-std is set to this
    #                              first (None: kept); base.START_LOG_STD is the shared rule
    seed: int = 0

    def __post_init__(self):
        # Types first (a bool is no count, NaN or infinity no rate), then DRIL's own ranges.
        check_fields(self, positive=("ensemble_epochs", "ensemble_batch", "ensemble_lr",
                                     "bc_batch", "warm_start_epochs"),
                     non_negative=("bc_steps", "value_warmup", "seed"))
        if self.ensemble_size < 2:
            raise ValueError(f"DRILConfig.ensemble_size must be at least 2 (a covariance needs "
                             f"two members), got {self.ensemble_size}")
        for name in ("ensemble_epochs", "ensemble_batch", "bc_batch", "warm_start_epochs"):
            if getattr(self, name) < 1:
                raise ValueError(f"DRILConfig.{name} must be at least 1, got "
                                 f"{getattr(self, name)}")
        if self.bc_steps < 0 or not 0 < self.quantile < 1 or not self.ensemble_lr > 0:
            raise ValueError("DRILConfig.bc_steps >= 0, 0 < quantile < 1 and ensemble_lr > 0")
        self.check_ppo()


def sized(total_steps: int, seed: int = 0, base: DRILConfig | None = None) -> DRILConfig:
    """DRIL's configuration for ``total_steps`` interactions (see ``_reward_ppo.sized``)."""
    return _reward_ppo.sized(base or DRILConfig(), total_steps, seed)


def preset(budget, seed: int = 0) -> DRILConfig:
    """DRIL at a budget: ``il_steps`` interactions; a tiny ensemble fit at ``smoke``."""
    cfg = sized(budget.il_steps, seed)
    if budget.is_smoke:
        cfg = dataclasses.replace(cfg, ensemble_epochs=2, warm_start_epochs=2, bc_steps=2)
    return cfg


# -- the ensemble and its cost -------------------------------------------------------------------

def fit_ensemble(obs: torch.Tensor, act: torch.Tensor, config: DRILConfig, seed: int,
                 hidden=(64, 64)) -> list[GaussianPolicy]:
    """``ensemble_size`` BC policies, each on a bootstrap resample of the pairs (obs, act)."""
    members = []
    n = len(obs)
    for e, s in enumerate(_base.seed_streams(seed, *(f"member {i}"
                                                     for i in range(config.ensemble_size)))):
        g = torch.Generator().manual_seed(int(s))
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(int(s))
            member = GaussianPolicy(obs.shape[1], act.shape[1], hidden, norm_obs=True)
        idx = torch.randint(n, (n,), generator=g)            # the bootstrap resample
        member.update_obs_norm(obs[idx])
        opt = torch.optim.AdamW(member.parameters(), lr=config.ensemble_lr)
        for _ in range(config.ensemble_epochs):
            order = idx[torch.randperm(n, generator=g)]
            for lo in range(0, n, config.ensemble_batch):
                j = order[lo:lo + config.ensemble_batch]
                _bc.bc_step(member, opt, obs[j], act[j])
        members.append(member.eval())
    return members


@torch.no_grad()
def disagreement(members, obs, act) -> torch.Tensor:
    """C(s, a) = a^T Cov_e[mu_e(s)] a for (..., obs_dim) states and (..., act_dim) actions,
    ``members`` any callables giving mean actions; actions and means clipped to the bounds."""
    obs = torch.as_tensor(obs, dtype=torch.float32)
    a = torch.as_tensor(act, dtype=torch.float32).clamp(ACTION_LOW, ACTION_HIGH)
    mu = torch.stack([m(obs).clamp(ACTION_LOW, ACTION_HIGH) for m in members])   # (E, ..., A)
    centred = mu - mu.mean(0)
    # a^T Cov a = sum_e (a . (mu_e - mean))^2 / (E - 1)
    return ((centred * a).sum(-1) ** 2).sum(0) / (len(members) - 1)


def cost_threshold(members, expert_obs, expert_act, quantile: float = 0.98) -> float:
    """q: the ``quantile`` of C over the expert's own pairs."""
    return float(np.quantile(disagreement(members, expert_obs, expert_act).numpy(), quantile))


def dril_reward(cost: torch.Tensor, threshold: float) -> torch.Tensor:
    """+1 where the cost is at most the threshold, -1 above it."""
    return torch.where(cost <= threshold, 1.0, -1.0)


# -- the learner ---------------------------------------------------------------------------------

def train(task: str, demos, config: DRILConfig = DRILConfig(), *,
          policy: GaussianPolicy | None = None, progress: bool = True, checkpoint=None,
          callback=None, checkpoint_every: int = 10) -> TrainResult:
    """DRIL on ``task`` from ``demos``; returns a :class:`TrainResult` (``models["ensemble"]``,
    a ``torch.nn.ModuleList`` of the members, and ``models["value"]``).

    ``policy``: where to start (trained in place); None fits the BC warm start on ``demos``.
    ``checkpoint`` / ``checkpoint_every`` / ``callback`` as in GAIL.  ``log``: one row per
    iteration, PPO's terms plus ``reward_mean``, ``cost_mean``, ``share_below`` (of the
    batch's pairs rewarded +1), ``threshold`` and ``bc_nll`` (mean over the BC steps).
    """
    spec = _tasks.spec(task)
    check_inputs(task, demos, policy)
    pcfg = config.ppo_config
    init_seed, sample_seed, env_seed, ens_seed, bc_seed = _base.seed_streams(
        config.seed, "init", "sample", "env", "ens", "bc")
    e_obs, e_act = _bc.pairs(demos)
    members = fit_ensemble(e_obs, e_act, config, ens_seed, pcfg.hidden)
    threshold = cost_threshold(members, e_obs, e_act, config.quantile)
    if policy is None:
        policy = _bc.warm_start_policy(demos, config.seed, max_epochs=config.warm_start_epochs)
    _base.set_start_noise(policy, config.start_log_std)
    policy, value_fn = _reward_ppo.make_networks(spec, pcfg, e_obs, policy, init_seed)
    bc_opt = torch.optim.AdamW(policy.mean_net.parameters(), lr=pcfg.lr)
    bc_gen = torch.Generator().manual_seed(bc_seed)

    def reward(batch):
        cost = disagreement(members, batch.obs, batch.actions)
        r = dril_reward(cost, threshold)
        return r, {"cost_mean": float(cost.mean()), "threshold": threshold,
                   "share_below": float((r > 0).float().mean())}

    def bc_updates(batch):
        nll = []
        for _ in range(config.bc_steps):
            i = torch.randint(len(e_obs), (config.bc_batch,), generator=bc_gen)
            nll.append(_bc.bc_step(policy, bc_opt, e_obs[i], e_act[i], pcfg.max_grad_norm)["nll"])
        return {"bc_nll": float(np.mean(nll)) if nll else float("nan")}

    hooks = _reward_ppo.Hooks("dril", reward, bc_updates, optimizers={"bc_optimizer": bc_opt},
                              generators={"bc_generator": bc_gen},
                              models={"ensemble": torch.nn.ModuleList(members)})
    return _reward_ppo.run(task, config, hooks, policy, value_fn, sample_seed, env_seed,
                           progress=progress, checkpoint=checkpoint, callback=callback,
                           checkpoint_every=checkpoint_every)


__all__ = ["DRILConfig", "cost_threshold", "disagreement", "dril_reward", "fit_ensemble",
           "preset", "sized", "train"]
