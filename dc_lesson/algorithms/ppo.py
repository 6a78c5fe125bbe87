"""Proximal Policy Optimisation, in one file, after CleanRL's ``ppo_continuous_action.py``.

One update of PPO is four steps, each a public function so another algorithm (DC) can reuse
them with its own reward:

1. :func:`collect_batch`: run the stochastic policy for ``n_steps`` in ``n_envs`` environments
   in lockstep (one network call per step for all of them);
2. a reward for every step: the environment's, or any ``reward_fn(batch)``;
3. :func:`compute_gae`: advantages and value targets;
4. :func:`ppo_update`: a few epochs of minibatch gradient steps on the clipped surrogate.

:func:`train` loops over these with logging, a progress bar and checkpoints.

The task ports never terminate: every episode is cut at the fixed horizon.  A cut is not a
terminal state, so the value of the observation an episode ends in is bootstrapped; the batch
keeps that final observation (``next_obs``) apart from the reset observation the environment
continues from.

Determinism: ``config.seed`` decides the network initialisation, one ``torch.Generator`` (action
noise and minibatch order) and the stream of episode seeds, three streams of
:func:`~dc_lesson.algorithms.base.seed_streams` (as :func:`dc_lesson.data.rollout.episode_seeds`
splits its own), so one configuration always gives the same numbers.
A checkpoint stores all of that state, so a resumed run ends exactly where an uninterrupted one
does.

Training-only termination (``config.terminate``, a key of
:data:`~dc_lesson.algorithms.envs.TERMINATIONS`): the task ports never end an episode early,
but for training PPO may treat some states as terminal, as
Gym does with a fallen hopper.  A copy whose observation the named function flags is restarted
at once with the next episode seed (the others run on), and the step into that state is a true
end: its value is not bootstrapped (``next_values`` 0 in :func:`compute_gae`).  Only the
training episodes change; the task, and how an expert is judged, do not.

Unlike CleanRL there is no reward normalisation: the task rewards lie in [0, 1], and an
algorithm that brings its own reward (DC) decides its scale.

Speed (``dc_lesson.nn.fast``): what you read here is what ``train`` runs by default: the loss
of :func:`minibatch_loss` through autograd, AdamW's ``step()``, the rollout through the torch
modules.  Sweep workers and benchmarks turn on ``fast.on()``: a minibatch step on 64-unit
networks is mostly torch's per-call overhead, so there the batch is normalised once per
update, the gradients of the usual loss (no entropy term, no value clipping, no proximal term)
are taken by hand (:func:`dc_lesson.nn.backprop.ppo_grads`), the clip and the fused AdamW step
call their kernels directly, and rollouts take a NumPy forward.  The gradients are autograd's
to the bit; the fused optimiser and the NumPy forward agree with the plain ones to float32
rounding (the module's docstring lists which piece is which).
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
from dc_lesson import tasks as _tasks
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms.base import (TrainResult, check_checkpoint, check_inputs, load_run,
                                       save_run)
# the environments every RL learner steps (re-exported: ``ppo.EnvBatch`` is what they call)
from dc_lesson.algorithms.envs import TERMINATIONS, EnvBatch, SeedStream, termination  # noqa: F401
from dc_lesson.checks import check_fields
from dc_lesson.nn import backprop as _backprop
from dc_lesson.nn import fast as _fast
from dc_lesson.nn.policies import GaussianPolicy, ValueNetwork


@dataclasses.dataclass(frozen=True)
class PPOConfig:
    """Every knob of PPO.  The defaults are CleanRL's for MuJoCo, except where noted."""

    n_envs: int = 8              # environments stepped in lockstep (CleanRL: 1 x 2048 steps)
    n_steps: int = 256           # steps per environment per update: batch = n_envs * n_steps
    gamma: float = 0.99          # discount: values look about 1 / (1 - gamma) = 100 steps ahead
    gae_lambda: float = 0.95     # GAE's mix of one-step (0) and Monte Carlo (1) advantages
    n_epochs: int = 10           # passes over each batch
    n_minibatches: int = 32      # minibatches per pass (each one gradient step)
    clip_coef: float = 0.2       # how far the probability ratio may move before it is clipped
    ent_coef: float = 0.0        # entropy bonus weight (0: the log-std is left to the gradient)
    vf_coef: float = 0.5         # value-loss weight in the joint loss
    max_grad_norm: float = 0.5   # gradient-norm clip, applied to the policy and value separately
    lr: float = 3e-4             # Adam's learning rate
    anneal_lr: bool = True       # decay the learning rate linearly to 0 over the run
    norm_adv: bool = True        # standardise advantages within each minibatch
    norm_obs: bool = True        # running observation normaliser inside both networks
    #                              (cartpole learns faster without it: see tests/test_ppo.py)
    clip_vloss: bool = False     # clip value updates like the ratio (CleanRL: True; here the
    #                              rewards are not normalised, values run to ~100, and a 0.2
    #                              clip would all but freeze the value network)
    target_kl: float | None = None   # stop an update's epochs once the approximate KL exceeds it
    weight_decay: float = 0.0    # AdamW's decoupled weight decay
    hidden: tuple[int, ...] = (64, 64)   # hidden layer sizes of both networks
    log_std_init: float = -0.5   # initial log standard deviation of the actions (CleanRL: 0)
    start_log_std: float | None = None   # a given (warm) start's log-std is set to this
    #                              first (None: kept); base.START_LOG_STD is the shared rule
    total_steps: int = 1_000_000     # environment steps over the run (all environments)
    episode_steps: int | None = None  # cut training episodes after this many steps (None: the
    #                                   task's horizon). A cut is a time limit, so its value is
    #                                   bootstrapped; shorter episodes put more of the data near
    #                                   the start states, where a fallen body has not yet wasted
    #                                   the rest of a 1000-step episode lying still.
    terminate: str | None = None  # training-only termination: a key of TERMINATIONS (None:
    #                               episodes run to the time limit, as the tasks do)
    value_warmup: int | None = None  # first updates that train only the critic (the policy's
    #                               learning rate 0): a fresh critic beside a given start
    #                               otherwise hands the actor advantages that are its own
    #                               error. None: none (one optimiser group, as the stored
    #                               experts were trained). PPO's own loop only: the imitation
    #                               learners have their own value_warmup
    seed: int = 0                # the one seed of the run

    def __post_init__(self):
        check_fields(self, positive=("n_envs", "n_steps", "n_epochs", "n_minibatches",
                                     "clip_coef", "max_grad_norm", "lr", "target_kl",
                                     "total_steps", "episode_steps"),
                     non_negative=("ent_coef", "vf_coef", "weight_decay", "seed"),
                     fraction=("gamma", "gae_lambda"))
        if self.batch_size % self.n_minibatches:
            raise ValueError(f"the batch (n_envs * n_steps = {self.batch_size}) must split into "
                             f"n_minibatches = {self.n_minibatches} equal minibatches")
        if self.n_updates < 1:
            raise ValueError(f"total_steps = {self.total_steps} is less than one batch "
                             f"({self.batch_size} steps)")
        if self.value_warmup is not None and not (
                isinstance(self.value_warmup, int) and not isinstance(self.value_warmup, bool)
                and 0 <= self.value_warmup < self.n_updates):
            raise ValueError(f"PPOConfig.value_warmup = {self.value_warmup!r} must be a whole "
                             f"number from 0 that leaves some of the {self.n_updates} updates "
                             f"to the policy (or None)")

    @property
    def batch_size(self) -> int:
        return self.n_envs * self.n_steps

    @property
    def n_updates(self) -> int:
        return self.total_steps // self.batch_size

    def to_json(self) -> str:
        return json.dumps(_base.unset_dropped(dataclasses.asdict(self)), sort_keys=True)


def preset(budget, seed: int = 0) -> PPOConfig:
    """PPO's configuration at a budget: CleanRL's settings for ``il_steps`` interactions (a
    few tiny updates at ``smoke``)."""
    if budget.is_smoke:
        return PPOConfig(n_envs=2, n_steps=64, n_epochs=2, n_minibatches=4, total_steps=512,
                         seed=seed)
    return PPOConfig(total_steps=budget.il_steps, seed=seed)


# -- 1. collect ----------------------------------------------------------------------------------

@dataclasses.dataclass
class Batch:
    """``n_steps`` steps of ``n_envs`` environments; every tensor is indexed (t, env, ...)."""

    obs: torch.Tensor            # (T, N, obs_dim) the observations acted on (raw)
    actions: torch.Tensor        # (T, N, act_dim) the sampled actions, before clipping
    logprobs: torch.Tensor       # (T, N) log pi(action | obs) at collection time
    env_rewards: torch.Tensor    # (T, N) the environment's rewards
    next_obs: torch.Tensor       # (T, N, obs_dim) what each action led to (final obs at an end)
    dones: torch.Tensor          # (T, N) bool: the episode ended (time limit) after this step
    values: torch.Tensor         # (T, N) V(obs)
    next_values: torch.Tensor    # (T, N) V(next_obs), the bootstrap
    episode_returns: list[float]     # environment returns of the episodes that ended
    advantages: torch.Tensor | None = None   # (T, N), set from compute_gae before ppo_update
    returns: torch.Tensor | None = None      # (T, N) value targets, likewise
    terminals: torch.Tensor | None = None    # (T, N) bool: a training-only terminal state
    #                                          (config.terminate) ended the episode here


def collect_batch(envs: EnvBatch, policy: GaussianPolicy, value_fn: ValueNetwork,
                  n_steps: int, generator: torch.Generator) -> Batch:
    """Runs the stochastic policy for ``n_steps`` steps in every environment of ``envs``."""
    T, N = n_steps, len(envs)
    obs_dim, act_dim = envs.spec.obs_dim, envs.spec.act_dim
    obs, next_obs = torch.zeros(T, N, obs_dim), torch.zeros(T, N, obs_dim)
    actions, logprobs = torch.zeros(T, N, act_dim), torch.zeros(T, N)
    rewards, dones = torch.zeros(T, N), torch.zeros(T, N, dtype=torch.bool)
    terminals = torch.zeros(T, N, dtype=torch.bool)
    finished: list[float] = []
    sampler = (_fast.GaussianSampler(policy)
               if _fast.enabled() and isinstance(policy, GaussianPolicy) else None)
    with torch.no_grad():
        for t in range(T):
            obs[t] = torch.from_numpy(envs.obs)
            # Store the raw sample and its log-prob; the environment applies it clipped.
            with _timing.phase("policy"):
                if sampler is not None:   # NumPy forward, the same noise (dc_lesson.nn.fast)
                    a, lp = sampler(envs.obs, generator)
                    actions[t], logprobs[t] = torch.from_numpy(a), torch.from_numpy(lp)
                else:
                    actions[t] = policy.sample(obs[t], generator)
                    logprobs[t] = policy.log_prob(obs[t], actions[t])
            with _timing.phase("env"):
                o, r, d, f = envs.step(actions[t].numpy())
            next_obs[t], rewards[t], dones[t] = (torch.from_numpy(o), torch.from_numpy(r),
                                                 torch.from_numpy(d))
            terminals[t] = torch.from_numpy(envs.last_terminal)
            finished += f
        # Values in two batched passes rather than one per step.
        with _timing.phase("value"):
            values, next_values = value_fn(obs), value_fn(next_obs)
    return Batch(obs, actions, logprobs, rewards, next_obs, dones, values, next_values, finished,
                 terminals=terminals)


# -- 3. advantages -------------------------------------------------------------------------------

@_timing.timed("gae")
def compute_gae(rewards: torch.Tensor, values: torch.Tensor, next_values: torch.Tensor,
                dones: torch.Tensor, gamma: float, gae_lambda: float,
                terminals: torch.Tensor | None = None):
    """Generalised advantage estimation over (T, N) tensors: returns (advantages, targets).

        delta_t = r_t + gamma * V(s'_t) - V(s_t)          s'_t: what step t led to
        A_t     = delta_t + gamma * lambda * A_{t+1}      A_{t+1} = 0 across an episode end

    A time-limit end still bootstraps through V(s'_t) (the episode was cut, not finished); only
    the sum stops there, because step t+1 belongs to the next episode.  A true terminal state
    (none in these tasks) would be passed as ``next_values[t] = 0``; ``terminals`` (T, N) bool
    does that for the steps a training-only termination ended.  The value targets are
    ``A_t + V(s_t)``.
    """
    if terminals is not None:
        next_values = next_values * (1.0 - terminals.to(next_values.dtype))
    advantages = torch.zeros_like(rewards)
    next_advantage = torch.zeros_like(rewards[0])
    continues = 1.0 - dones.to(rewards.dtype)
    for t in reversed(range(len(rewards))):
        delta = rewards[t] + gamma * next_values[t] - values[t]
        next_advantage = delta + gamma * gae_lambda * continues[t] * next_advantage
        advantages[t] = next_advantage
    return advantages, advantages + values


# -- 4. update -----------------------------------------------------------------------------------

def clipped_surrogate(new_logp: torch.Tensor, old_logp: torch.Tensor, advantages: torch.Tensor,
                      clip_coef: float):
    """PPO's policy loss, -mean(min(r A, clip(r, 1-c, 1+c) A)) with r = pi_new / pi_old.

    Returns (loss, approx_kl, clip_fraction); approx_kl is the low-variance estimator
    mean((r - 1) - log r) of KL(old || new).
    """
    log_ratio = new_logp - old_logp
    ratio = log_ratio.exp()
    neg_adv = -advantages
    loss = torch.max(neg_adv * ratio, neg_adv * ratio.clamp(1 - clip_coef, 1 + clip_coef)).mean()
    with torch.no_grad():
        approx_kl = ((ratio - 1) - log_ratio).mean()
        clip_fraction = ((ratio - 1).abs() > clip_coef).float().mean()
    return loss, approx_kl, clip_fraction


def value_loss(new_values: torch.Tensor, old_values: torch.Tensor, targets: torch.Tensor,
               clip_coef: float | None = None) -> torch.Tensor:
    """0.5 * mean squared error; with ``clip_coef``, the pessimistic max of that and the error
    of the value moved at most ``clip_coef`` from its old value (CleanRL's ``clip_vloss``)."""
    loss = (new_values - targets) ** 2
    if clip_coef is not None:
        clipped = old_values + (new_values - old_values).clamp(-clip_coef, clip_coef)
        loss = torch.max(loss, (clipped - targets) ** 2)
    return 0.5 * loss.mean()


def explained_variance(predictions: torch.Tensor, targets: torch.Tensor) -> float:
    """1 - Var(targets - predictions) / Var(targets): 1 is perfect, 0 no better than a mean."""
    var = targets.var()
    return float("nan") if var == 0 else float(1 - (targets - predictions).var() / var)


def minibatch_loss(policy, value_fn, zp, zv, act, olp, ov, adv, tg, config: PPOConfig,
                   normalised: bool = False, generator=None, extra_loss=None) -> dict:
    """One minibatch's loss, ``clipped surrogate - ent_coef * entropy + vf_coef * value
    loss (+ extra_loss())``, under ``"loss"``, with the terms ``ppo_update`` logs.

    ``zp`` and ``zv`` are observations, or with ``normalised`` (the fast path's batch,
    normalised once per update) each network's normalised inputs."""
    if normalised:       # the Gaussian's terms without a Normal: the same bits
        new_logp, entropy = policy.log_prob_entropy(zp, act)
        entropy = entropy.mean()
        new_values = value_fn.value_of(zv)
    elif policy.gaussian:
        dist = policy.distribution(zp)
        new_logp = dist.log_prob(act).sum(-1)
        entropy = dist.entropy().sum(-1).mean()
        new_values = value_fn(zv)
    else:     # a mixture (nn.mixture): its exact density, a sampled entropy estimate
        new_logp = policy.log_prob(zp, act)
        entropy = policy.entropy(zp, generator).mean()
        new_values = value_fn(zv)
    pg_loss, approx_kl, clip_fraction = clipped_surrogate(new_logp, olp, adv, config.clip_coef)
    v_loss = value_loss(new_values, ov, tg, config.clip_coef if config.clip_vloss else None)
    if config.ent_coef:
        loss = pg_loss - config.ent_coef * entropy + config.vf_coef * v_loss
    else:   # a zero weight's term would add -0.0 to the log-std's gradient, which changes
        #     no bit: left out of the backward pass
        loss = pg_loss + config.vf_coef * v_loss
    if extra_loss is not None:
        loss = loss + extra_loss()
    return {"loss": loss, "policy_loss": pg_loss, "value_loss": v_loss, "entropy": entropy,
            "approx_kl": approx_kl, "clip_fraction": clip_fraction}


@_timing.timed("ppo_update")
def ppo_update(policy: GaussianPolicy, value_fn: ValueNetwork, optimizer: torch.optim.Optimizer,
               batch: Batch, config: PPOConfig,
               generator: torch.Generator | None = None,
               extra_loss: Callable[[], torch.Tensor] | None = None) -> dict:
    """``n_epochs`` passes of minibatch gradient steps on one batch; returns the logged terms
    (means over the minibatches).  ``generator`` draws the minibatch order; ``extra_loss()``,
    if given, is added to every minibatch's loss (consensus ADMM's proximal term in
    :mod:`dc_lesson.algorithms.dc`)."""
    if batch.advantages is None or batch.returns is None:
        raise ValueError("set batch.advantages and batch.returns (from compute_gae) first")
    # From here on time and environment do not matter: every step is one sample.
    obs = batch.obs.reshape(-1, batch.obs.shape[-1])
    actions = batch.actions.reshape(-1, batch.actions.shape[-1])
    old_logp, old_values = batch.logprobs.reshape(-1), batch.values.reshape(-1)
    advantages, targets = batch.advantages.reshape(-1), batch.returns.reshape(-1)
    n = len(obs)
    size = n // config.n_minibatches
    fast = _fast.enabled()        # the same numbers by faster kernels (dc_lesson.nn.fast)
    normalised = fast and policy.gaussian
    if normalised:
        # The normalisers are frozen during an update, so each network's inputs are the same
        # numbers in every epoch: normalise the batch once (elementwise, so minibatch by
        # minibatch would give the same bits), not once per minibatch step.
        with torch.no_grad():
            z_pi, z_v = policy.normalise(obs), value_fn.normalise(obs)
    else:
        z_pi = z_v = obs
    # The common case (no entropy term, no value clipping, no proximal term, tanh MLPs)
    # differentiated by hand on the fast path (dc_lesson.nn.backprop): the same gradients.
    by_hand = (normalised and extra_loss is None and not config.ent_coef
               and not config.clip_vloss and _backprop.supported(policy.mean_net)
               and _backprop.supported(value_fn.net))
    pi_params, v_params = list(policy.parameters()), list(value_fn.parameters())
    terms: dict[str, list[float]] = {k: [] for k in (
        "policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction",
        "grad_norm_policy", "grad_norm_value")}
    epochs = 0
    for _ in range(config.n_epochs):
        epochs += 1
        epoch_kl = []
        order = torch.randperm(n, generator=generator)
        # One gather per epoch, then every minibatch is a slice of it: the same rows in the
        # same order as indexing each minibatch, with one copy instead of n_minibatches.
        shuffled = [x[order] for x in (z_pi, z_v, actions, old_logp, old_values, advantages,
                                       targets)]
        for start in range(0, n, size):
            zp, zv, act, olp, ov, adv, tg = (x[start:start + size] for x in shuffled)
            if config.norm_adv:
                adv = (adv - adv.mean()) / (adv.std() + 1e-8)
            if by_hand:
                _fast.zero_grad(optimizer)
                now = _backprop.ppo_grads(policy, value_fn, zp, zv, act, olp, adv, tg,
                                          config.clip_coef, config.vf_coef)
            else:
                now = minibatch_loss(policy, value_fn, zp, zv, act, olp, ov, adv, tg, config,
                                     normalised, generator, extra_loss)
                optimizer.zero_grad()
                now.pop("loss").backward()
            # Clip each network on its own: the value loss, with targets up to 1 / (1 - gamma),
            # would otherwise take the whole norm and shrink the policy's step.
            if fast:     # torch's kernels without their wrappers: the same bits
                gn_pi = _fast.clip_grad_norm_(pi_params, config.max_grad_norm)
                gn_v = _fast.clip_grad_norm_(v_params, config.max_grad_norm)
                _fast.optimizer_step(optimizer)
            else:
                gn_pi = torch.nn.utils.clip_grad_norm_(pi_params, config.max_grad_norm)
                gn_v = torch.nn.utils.clip_grad_norm_(v_params, config.max_grad_norm)
                optimizer.step()

            for k, v in (*now.items(), ("grad_norm_policy", gn_pi), ("grad_norm_value", gn_v)):
                terms[k].append(float(v.detach()))
            epoch_kl.append(float(now["approx_kl"]))
        if config.target_kl is not None and np.mean(epoch_kl) > config.target_kl:
            break   # the policy has moved far enough from the one that collected the batch
    out = {k: float(np.mean(v)) for k, v in terms.items()}
    out["explained_variance"] = explained_variance(old_values, targets)
    out["epochs"] = epochs
    out["action_std"] = (float(policy.log_std.detach().exp().mean()) if policy.gaussian
                         else math.nan)
    return out


# -- checkpoints ---------------------------------------------------------------------------------

CHECKPOINT_FORMAT = "dc_lesson.ppo.checkpoint"
CHECKPOINT_VERSION = 1


def save_checkpoint(path, *, task: str, config: PPOConfig, update: int, policy, value_fn,
                    optimizer, generator: torch.Generator, envs: EnvBatch, log: list) -> None:
    """Everything a run needs to go on exactly as if it had not stopped, written atomically."""
    save_run(path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, task=task, config_json=config.to_json(),
             update=update, networks={"policy": policy, "value": value_fn},
             optimizers={"optimizer": optimizer}, generators={"generator": generator},
             envs=envs, log=log)


def _saved_config(ckpt: dict) -> dict:
    # A knob added to PPOConfig after the checkpoint was written takes its default value.
    # (to_json leaves an unset later knob out, so it is left out here too)
    defaults = {f.name: f.default for f in dataclasses.fields(PPOConfig)}
    return json.loads(json.dumps(_base.unset_dropped({**defaults, **json.loads(ckpt["config"])})))


def load_checkpoint(path, *, task: str, config: PPOConfig, policy, value_fn, optimizer,
                    generator: torch.Generator, envs: EnvBatch) -> tuple[int, list]:
    """Restores a run saved by :func:`save_checkpoint` in place; returns (update, log)."""
    update, log, _ = load_run(path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, "PPO checkpoint",
                              task=task, saved_config=_saved_config,
                              now_config=json.loads(config.to_json()),
                              networks={"policy": policy, "value": value_fn},
                              optimizers={"optimizer": optimizer},
                              generators={"generator": generator}, envs=envs)
    return update, log


# -- the loop ------------------------------------------------------------------------------------

RewardFn = Callable[[Batch], "torch.Tensor | np.ndarray"]


def train(task: str, demos=None, config: PPOConfig = PPOConfig(), *,
          policy: GaussianPolicy | None = None, progress: bool = True, checkpoint=None,
          callback: Callable | None = None, reward_fn: RewardFn | None = None,
          checkpoint_every: int = 10) -> TrainResult:
    """Trains a Gaussian policy on ``task`` with PPO; returns a :class:`TrainResult` (the
    policy, the log, ``models["value"]``).

    Args:
        task: a task name.
        demos: unused: PPO learns from the task's reward (or ``reward_fn``), not from
            demonstrations; the argument is there so every learner is called alike.
        config: the hyperparameters and the seed.
        reward_fn: ``reward_fn(batch)`` gives a (n_steps, n_envs) reward from ``batch.obs``,
            ``batch.actions`` and ``batch.next_obs``; None uses the environment's reward.
        policy: a policy to start from (a fresh :class:`GaussianPolicy` by default).
        callback: called as ``callback(row, policy)`` after every update; a true return
            value stops training.
        progress: show a progress bar.
        checkpoint: a file path; the run is saved there every ``checkpoint_every`` updates and
            at the end, and resumes from it when it exists.

    ``log`` has one row per update: the terms of :func:`ppo_update`, the mean environment
    return of the episodes that ended in the batch (NaN if none did) and steps per second.
    """
    spec = _tasks.spec(task)
    check_inputs(task, None, policy)
    # A given start keeps its own input scale: its normaliser is frozen and the critic reads
    # it. (Merging the rollouts' statistics into it changed the function the start computes:
    # a perfect cartpole BC start fell to about 0 within 20,000 interactions on 3 of 3 seeds,
    # and kept 1.00 on 2 of 3 with it frozen; issue 38's probe.)
    frozen_norm = policy is not None and policy.obs_norm is not None
    _base.set_start_noise(policy, config.start_log_std)
    init_seed, sample_seed, env_seed = _base.seed_streams(config.seed, "init", "sample", "env")
    # Seed the initialisation without changing the caller's global torch RNG.
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(init_seed)
        if policy is None:
            policy = GaussianPolicy(spec.obs_dim, spec.act_dim, config.hidden,
                                    log_std_init=config.log_std_init, norm_obs=config.norm_obs)
        value_fn = ValueNetwork(spec.obs_dim, config.hidden, norm_obs=config.norm_obs)
    if frozen_norm and value_fn.obs_norm is not None:
        value_fn.obs_norm.load_state_dict(policy.obs_norm.state_dict())
    # With a critic warm-up, two groups so it can hold the policy still (the same numbers per
    # parameter; one group otherwise, as the stored experts' optimiser state has it)
    params = ([{"params": list(policy.parameters())}, {"params": list(value_fn.parameters())}]
              if config.value_warmup is not None else
              [*policy.parameters(), *value_fn.parameters()])
    optimizer = _fast.adamw(params, lr=config.lr, eps=1e-5, weight_decay=config.weight_decay)
    warmup = config.value_warmup or 0
    generator = torch.Generator().manual_seed(sample_seed)
    envs = EnvBatch(task, config.n_envs, env_seed, config.episode_steps, config.terminate)
    first, log = 0, []
    if checkpoint is not None and pathlib.Path(checkpoint).exists():
        first, log = load_checkpoint(checkpoint, task=task, config=config, policy=policy,
                                     value_fn=value_fn, optimizer=optimizer,
                                     generator=generator, envs=envs)

    bar = _progress.bar(total=config.n_updates, initial=first, desc=f"PPO {task}",
                        unit="update", enabled=progress)
    last_return = math.nan
    for update in range(first, config.n_updates):
        start = time.perf_counter()
        lr = config.lr * (1 - update / config.n_updates) if config.anneal_lr else config.lr
        for group in optimizer.param_groups:
            group["lr"] = lr
        if update < warmup:
            optimizer.param_groups[0]["lr"] = 0.0      # the policy's group: held still

        batch = collect_batch(envs, policy, value_fn, config.n_steps, generator)
        if reward_fn is None:
            rewards = batch.env_rewards
        else:
            rewards = torch.as_tensor(reward_fn(batch), dtype=torch.float32)
            if rewards.shape != batch.env_rewards.shape:
                raise ValueError(f"reward_fn returned shape {tuple(rewards.shape)}, expected "
                                 f"(n_steps, n_envs) = {tuple(batch.env_rewards.shape)}")
        batch.advantages, batch.returns = compute_gae(
            rewards, batch.values, batch.next_values, batch.dones, config.gamma,
            config.gae_lambda, batch.terminals)
        terms = ppo_update(policy, value_fn, optimizer, batch, config, generator)
        # New observation statistics only now, so the update saw the inputs the batch was
        # collected with (its stored log-probabilities were computed on those).
        if not frozen_norm:
            policy.update_obs_norm(batch.obs)
            value_fn.update_obs_norm(batch.obs)

        if batch.episode_returns:
            last_return = float(np.mean(batch.episode_returns))
        row = {"update": update + 1, "steps": (update + 1) * config.batch_size,
               "lr": lr, **({"policy_frozen": update < warmup} if warmup else {}), **terms,
               "reward_mean": float(rewards.mean()),
               "episode_return": (float(np.mean(batch.episode_returns))
                                  if batch.episode_returns else math.nan),
               "n_episodes": len(batch.episode_returns),
               "steps_per_second": config.batch_size / (time.perf_counter() - start)}
        log.append(row)
        done = update + 1 == config.n_updates
        if checkpoint is not None and ((update + 1) % checkpoint_every == 0 or done):
            save_checkpoint(checkpoint, task=task, config=config, update=update + 1,
                            policy=policy, value_fn=value_fn, optimizer=optimizer,
                            generator=generator, envs=envs, log=log)
        bar.update(1)
        bar.set_postfix(ret=f"{last_return:.0f}", kl=f"{terms['approx_kl']:.3f}",
                        sps=f"{row['steps_per_second']:.0f}")
        if callback is not None and callback(row, policy):
            break
    bar.close()
    return TrainResult(policy, log, {"value": value_fn}, "ppo")


__all__ = ["Batch", "EnvBatch", "PPOConfig", "preset", "SeedStream", "TERMINATIONS", "check_checkpoint", "clipped_surrogate", "collect_batch",
           "compute_gae", "explained_variance", "load_checkpoint", "minibatch_loss", "ppo_update",
           "save_checkpoint", "train", "value_loss"]
