"""PPO on an imitation reward: the loop GAIL, DRIL, PWIL and NDI share.

Each of them is PPO on a reward it computes from the batch the policy just collected; the
reward (GAIL's: its discriminator's steps on that batch, then -log(1 - D)) and, for DRIL, a
step after PPO's are the learner's own, and everything else is done here, once, so the four
differ only in their rewards:

    collect n_envs x n_steps pairs with the stochastic policy             (ppo.collect_batch)
    r_t <- the learner's reward of the batch                              (hooks.reward)
    advantages <- GAE(r, V); pi, V <- PPO's clipped-surrogate epochs      (ppo.compute_gae,
                                                                           ppo.ppo_update)
    [the learner's own step after PPO's]                                  (hooks.after_update)

* The policy's and the critic's observation normalisers are set once from the expert's states
  and frozen (a BC warm start keeps its meaning, one input scale for all; the reasons are in
  :mod:`dc_lesson.algorithms.gail`'s docstring).
* ``value_warmup`` first iterations train only the critic; the learning rate decays linearly.
* A checkpoint holds the policy, the critic, their optimiser, PPO's generator, the
  environments, the log, and whatever the learner declares in its hooks (networks, optimisers,
  generators, other state), so a resumed run ends identical to an uninterrupted one.

The config of such a learner is a frozen dataclass with the fields ``ppo`` (a
:class:`~dc_lesson.algorithms.ppo.PPOConfig`), ``value_warmup`` and ``seed`` and the methods of
:class:`PPOImitationConfig`.
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
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms import ppo as _ppo
from dc_lesson.algorithms.base import TrainResult, load_run, save_run
from dc_lesson.nn.policies import GaussianPolicy, ValueNetwork


def imitation_ppo_default() -> _ppo.PPOConfig:
    """PPO's settings for the learners on this loop (GAIL's from the start): 8 x 512 steps,
    5 epochs of 8 minibatches, lr 3e-4, no entropy bonus; shared so their costs compare.

    Larger batches and fewer, larger minibatches than PPOConfig's defaults: 40 gradient steps
    per 4096 pairs instead of 320 per 2048 (the update, not the simulator, is what costs here),
    and a smaller learning rate, so a BC start is refined, not replaced."""
    return _ppo.PPOConfig(n_envs=8, n_steps=512, n_epochs=5, n_minibatches=8, lr=3e-4,
                          total_steps=300_000, ent_coef=0.0)


class PPOImitationConfig:
    """Methods of a learner config with ``ppo``, ``value_warmup`` and ``seed`` fields."""

    @property
    def ppo_config(self) -> _ppo.PPOConfig:
        """The PPO settings actually used: ``ppo`` with the run's one seed."""
        return dataclasses.replace(self.ppo, seed=self.seed)

    def check_ppo(self) -> None:
        name = type(self).__name__
        if not isinstance(self.ppo, _ppo.PPOConfig):
            raise TypeError(f"{name}.ppo must be a ppo.PPOConfig, got {type(self.ppo)}")
        if self.ppo.value_warmup is not None:
            raise ValueError(f"{name}.ppo.value_warmup is PPO's own loop's; set "
                             f"{name}.value_warmup (critic-only iterations) instead")
        if not 0 <= self.value_warmup < self.ppo.n_updates:
            raise ValueError(f"{name}.value_warmup = {self.value_warmup} must be >= 0 and leave "
                             f"some of the {self.ppo.n_updates} iterations to the policy")

    def with_steps(self, total_steps: int):
        """The same configuration for ``total_steps`` environment interactions."""
        return dataclasses.replace(self, ppo=dataclasses.replace(self.ppo,
                                                                 total_steps=int(total_steps)))

    # knobs added after studies' cells were listed: named in the JSON only when set (GAIL
    # has had start_log_std from its first cells, so its JSON always names it)
    LATER_KNOBS = ("start_log_std",)

    def to_dict(self) -> dict:
        d = _base.unset_dropped(dataclasses.asdict(self), self.LATER_KNOBS)
        d["ppo"] = json.loads(self.ppo_config.to_json())
        return json.loads(json.dumps(d))

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)


def sized(base, total_steps: int, seed: int):
    """``base`` for a run of ``total_steps`` interactions (GAIL's ``sized``): a run shorter
    than four default batches (only at ``smoke``) collects smaller batches, so it still makes
    four iterations, and warms its critic up for at most one."""
    p = base.ppo
    if total_steps < 4 * p.batch_size:
        n_steps = max(p.n_minibatches, total_steps // (4 * p.n_envs) // p.n_minibatches
                      * p.n_minibatches)
        p = dataclasses.replace(p, n_steps=n_steps)
        base = dataclasses.replace(base, value_warmup=min(base.value_warmup, 1))
    return dataclasses.replace(base, ppo=dataclasses.replace(p, total_steps=int(total_steps)),
                               seed=int(seed))


def make_networks(spec, pcfg: _ppo.PPOConfig, expert_obs: torch.Tensor,
                  policy: GaussianPolicy | None, init_seed: int, *more: Callable):
    """The policy (a fresh one if None, its normaliser set from the expert's states) and a
    critic on the same frozen input scale, drawn from ``init_seed``; then ``more()`` for each
    builder of the learner's own networks, drawn from the same stream after the critic (GAIL's
    discriminator).  Returns ``(policy, value_fn, *built)``."""
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(init_seed)
        if policy is None:
            policy = GaussianPolicy(spec.obs_dim, spec.act_dim, pcfg.hidden,
                                    log_std_init=pcfg.log_std_init, norm_obs=pcfg.norm_obs)
            policy.update_obs_norm(expert_obs)
        value_fn = ValueNetwork(spec.obs_dim, pcfg.hidden, norm_obs=policy.obs_norm is not None)
        built = [build() for build in more]
    if value_fn.obs_norm is not None:
        value_fn.obs_norm.load_state_dict(policy.obs_norm.state_dict())
    return (policy, value_fn, *built)


@dataclasses.dataclass
class Hooks:
    """What a learner plugs into :func:`run`.

    ``reward(batch)`` returns the (n_steps, n_envs) reward and a dict of logged floats;
    ``after_update(batch)`` (optional) runs after PPO's update and returns logged floats;
    ``networks``, ``optimizers`` and ``generators`` are saved in the checkpoint by name, and
    ``get_state()`` / ``set_state(dict)`` any other state (tensors); ``models`` goes into the
    :class:`TrainResult`.  ``optimizer(param_groups, lr=, eps=, weight_decay=)`` builds the
    policy's and the critic's optimiser: torch's AdamW, or (GAIL)
    :func:`dc_lesson.nn.fast.adamw`, the same numbers on the reader's path but fused on the
    fast path, which rounds differently; each learner keeps the one its stored cells used.
    """

    name: str
    reward: Callable
    after_update: Callable | None = None
    networks: dict = dataclasses.field(default_factory=dict)
    optimizers: dict = dataclasses.field(default_factory=dict)
    generators: dict = dataclasses.field(default_factory=dict)
    get_state: Callable | None = None
    set_state: Callable | None = None
    models: dict = dataclasses.field(default_factory=dict)
    optimizer: Callable = torch.optim.AdamW
    shown: tuple[str, ...] = ()   # logged terms the progress bar shows beside the return,
    #                               the reward and the speed (GAIL: D's two accuracies)


CHECKPOINT_VERSION = 1


def run(task: str, config, hooks: Hooks, policy: GaussianPolicy, value_fn: ValueNetwork,
        sample_seed: int, env_seed: int, *, progress: bool, checkpoint, callback,
        checkpoint_every: int) -> TrainResult:
    """The loop of the module docstring; returns the learner's :class:`TrainResult`."""
    pcfg = config.ppo_config
    # two parameter groups, so the value warm-up can hold the policy still
    optimizer = hooks.optimizer([{"params": list(policy.parameters())},
                                 {"params": list(value_fn.parameters())}],
                                lr=pcfg.lr, eps=1e-5, weight_decay=pcfg.weight_decay)
    generator = torch.Generator().manual_seed(sample_seed)
    # ppo.terminate (a training-only termination, e.g. hopper-fall; None in the presets)
    envs = _ppo.EnvBatch(task, pcfg.n_envs, env_seed, pcfg.episode_steps, pcfg.terminate)
    networks = {"policy": policy, "value": value_fn, **hooks.networks}
    optimizers = {"optimizer": optimizer, **hooks.optimizers}
    generators = {"generator": generator, **hooks.generators}
    fmt = f"dc_lesson.{hooks.name}.checkpoint"
    first, log = 0, []
    if checkpoint is not None and pathlib.Path(checkpoint).exists():
        first, log, ckpt = load_run(
            checkpoint, fmt, CHECKPOINT_VERSION, f"{hooks.name.upper()} checkpoint", task=task,
            saved_config=lambda c: json.loads(c["config"]), now_config=config.to_dict(),
            networks=networks, optimizers=optimizers, generators=generators, envs=envs)
        if hooks.set_state is not None:
            hooks.set_state(ckpt["state"])

    n_updates = pcfg.n_updates
    bar = _progress.bar(total=n_updates, initial=first, desc=f"{hooks.name.upper()} {task}",
                        unit="iter", enabled=progress)
    last_return = math.nan     # the bar shows the last batch's that finished an episode
    for update in range(first, n_updates):
        start = time.perf_counter()
        lr = pcfg.lr * (1 - update / n_updates) if pcfg.anneal_lr else pcfg.lr
        optimizer.param_groups[0]["lr"] = 0.0 if update < config.value_warmup else lr
        optimizer.param_groups[1]["lr"] = lr

        batch = _ppo.collect_batch(envs, policy, value_fn, pcfg.n_steps, generator)
        rewards, reward_terms = hooks.reward(batch)
        batch.advantages, batch.returns = _ppo.compute_gae(
            rewards, batch.values, batch.next_values, batch.dones, pcfg.gamma, pcfg.gae_lambda,
            batch.terminals)
        terms = _ppo.ppo_update(policy, value_fn, optimizer, batch, pcfg, generator)
        extra = hooks.after_update(batch) if hooks.after_update is not None else {}

        row = {"update": update + 1, "steps": (update + 1) * pcfg.batch_size, "lr": lr,
               "policy_frozen": update < config.value_warmup,
               "reward_mean": float(rewards.mean()), "reward_std": float(rewards.std()),
               **reward_terms, **terms, **extra,
               "episode_return": (float(np.mean(batch.episode_returns))
                                  if batch.episode_returns else math.nan),
               "n_episodes": len(batch.episode_returns),
               "steps_per_second": pcfg.batch_size / (time.perf_counter() - start)}
        log.append(row)
        done = update + 1 == n_updates
        if checkpoint is not None and ((update + 1) % checkpoint_every == 0 or done):
            state = hooks.get_state() if hooks.get_state is not None else {}
            save_run(checkpoint, fmt, CHECKPOINT_VERSION, task=task,
                     config_json=config.to_json(), update=update + 1, networks=networks,
                     optimizers=optimizers, generators=generators, envs=envs, log=log,
                     state=state)
        bar.update(1)
        if batch.episode_returns:
            last_return = row["episode_return"]
        bar.set_postfix(ret=f"{last_return:.0f}", r=f"{row['reward_mean']:.2f}",
                        **{k: f"{row[k]:.2f}" for k in hooks.shown},
                        sps=f"{row['steps_per_second']:.0f}")
        if callback is not None and callback(row, policy):
            break
    bar.close()
    policy.meta = {**getattr(policy, "meta", {}), "algorithm": hooks.name,
                   f"{hooks.name}_config": config.to_dict(), "task": task}
    return TrainResult(policy, log, {**hooks.models, "value": value_fn}, hooks.name)
