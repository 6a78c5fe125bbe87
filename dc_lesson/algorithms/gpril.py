r"""Generative predecessor models for imitation learning (GPRIL, Schroecker, Vecerik, Scholz,
ICLR 2019).

The idea.  BC raises log pi(a_E | s_E) on the expert's pairs only.  GPRIL also asks: which
states and actions *lead to* the expert's states?  If the learner, acting from (s, a), tends to
reach an expert state s_E some steps later, then taking a in s is a way back onto the
demonstrations, and the policy should learn it too.  A generative model of predecessors,

    B(s_t, a_t | s_{t+j}) = B_s(s_t | s_{t+j}) B_a(a_t | s_t, s_{t+j}),    j ~ Geometric(1 - gamma),

is fitted to the learner's *own* experience (any behaviour: the model describes the dynamics,
not the expert), and the policy is trained by likelihood on the expert's pairs and on
predecessors sampled from the expert's states:

    max_pi  E_{(s_E,a_E)} [ log pi(a_E | s_E) ]
          + w E_{s_E, (s~, a~) ~ B(. | s_E)} [ log pi(a~ | s~) ].

The horizon j ~ Geometric(1 - gamma) on {1, 2, ...} (P(j) = (1 - gamma) gamma^{j-1}, mean
1 / (1 - gamma)) makes B the discounted predecessor distribution, the time-reversed analogue of
a discounted occupancy.  Both factors are masked autoregressive flows (MAF, Papamakarios et
al. 2017) conditioned on the future state: a stack of MADE layers, each an affine map

    u_i = (x_i - mu_i(x_{<i}, c)) exp(-alpha_i(x_{<i}, c)),   log|du/dx| = - sum_i alpha_i,

with the order of the dimensions reversed between layers and u ~ N(0, I).

Pseudo-code (:func:`train`):

    every iteration:
        collect n_envs x n_steps steps with the stochastic policy into the buffer (collect)
        model_steps times:                                                (model_step)
            (s_t, a_t, s_{t+j}) from the buffer, j ~ Geometric(1 - gamma)  (sample_tuples)
            B_s, B_a <- Adam step on -log B_s(s_t|s_{t+j}) - log B_a(a_t|s_t, s_{t+j})
        policy_steps times:                                               (policy_step)
            s_E, a_E from the demonstrations; s~ ~ B_s(.|s_E), a~ ~ B_a(.|s~, s_E)
            pi <- AdamW step on -log pi(a_E|s_E) - w log pi(clip(a~)|s~)

The paper reports GPRIL gave no meaningful results on DC's multi-mode tasks; it is here,
faithfully, so that claim can be checked.

Choices the papers leave open (each a field of :class:`GPRILConfig`):

* *Horizon*: ``gamma`` = 0.9 (mean 10 steps).  A tuple's j is drawn first, then a start time
  uniformly among the buffer's rows with j rows after it; a start whose future step lies in
  another episode is redrawn (so very long horizons are slightly under-represented near
  episode ends; with 1000-step episodes and a mean of 10 this is negligible).
* *The flows*: ``flow_layers`` = 3 MADE layers of ``flow_hidden`` = (64, 64) tanh units, the
  log-scale soft-clipped to (-5, 5) by 5 tanh(alpha / 5); inputs and contexts standardised by
  the mean and std (floored at 1e-3) of the learner's first batch, then fixed: the flows model
  the learner's experience, whose spread is much wider than the expert's (a balanced
  cartpole's cos has std 1e-4).  Written here, in about 80 lines, rather than taken from a
  flow library (``nflows`` and ``zuko`` would add a dependency for two small models).
* *The buffer*: the last ``buffer_steps`` steps of every environment (FIFO).
* *Updates*: ``model_steps`` Adam steps on the flows and ``policy_steps`` AdamW steps on the
  policy per iteration, ``w`` = ``predecessor_weight`` = 1; the policy's log-std is learnt by
  the likelihood (nothing else sets it, so exploration shrinks as the policy fits).
* Predecessor actions are clipped to the bounds before their log-likelihood.

What it gives on cartpole (``tests/test_baselines.py``, measured, 20k interactions from a
fresh policy at 618): with w = 0 (BC inside this loop) 1000; with w = 1, 425.  Early on, the
predecessors of expert states are drawn from flows of a poor learner's own experience, so they
carry that learner's actions.

Speed (sweep workers and benchmarks run ``fast.on()``, :mod:`dc_lesson.nn.fast`): the flows'
sampler runs in NumPy (:meth:`MADE.numpy_invert`: each pass multiplies only the weight blocks
it needs; an iteration's predecessors for every policy step in one batch), rollouts take the
NumPy forward and the optimisers are fused: the same computations to float32 rounding
(``tests/test_baselines.py``), so a run on either path is another sample of the same
experiment.  About 1.6 times faster on hopper (``data/results/perf_runs_gpril.json``,
``perf/HISTORY.md``).  The competence study's GPRIL cells were computed before this path
existed (torch's kernels throughout).

Determinism: ``seed`` decides the initialisations, one generator for actions and episodes'
seeds, one for the buffer's tuples and the flows' samples, and one for the expert minibatches.
A checkpoint holds the networks, optimisers, generators, environments and the buffer.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
import time

import numpy as np
import torch
from torch import nn

from dc_lesson import progress as _progress
from dc_lesson import tasks as _tasks
from dc_lesson.checks import check_fields
from dc_lesson.algorithms import bc as _bc
from dc_lesson.algorithms import ppo as _ppo
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms.base import TrainResult, check_inputs, load_run, save_run
from dc_lesson.nn import fast as _fast
from dc_lesson.nn.policies import ACTION_HIGH, ACTION_LOW, GaussianPolicy

LOG_2PI = math.log(2 * math.pi)


@dataclasses.dataclass(frozen=True)
class GPRILConfig:
    """Every knob of GPRIL."""

    n_envs: int = 8              # environments stepped in lockstep
    n_steps: int = 250           # steps per environment per iteration
    total_steps: int = 300_000   # environment interactions over the run
    episode_steps: int | None = None   # cut training episodes (None: the task's horizon)
    terminate: str | None = None   # a training-only termination (ppo.TERMINATIONS, e.g.
    #                                hopper-fall): a fallen episode ends, its buffer with it
    gamma: float = 0.9           # the horizon j ~ Geometric(1 - gamma): mean 1 / (1 - gamma)
    buffer_steps: int = 2000     # steps kept per environment (FIFO)
    flow_hidden: tuple[int, ...] = (64, 64)
    flow_layers: int = 3
    flow_lr: float = 1e-3
    model_steps: int = 50        # flow gradient steps per iteration
    model_batch: int = 256
    policy_steps: int = 50       # policy gradient steps per iteration
    policy_batch: int = 256      # expert pairs (and as many predecessors) per step
    predecessor_weight: float = 1.0   # w
    lr: float = 1e-3             # the policy's AdamW learning rate
    hidden: tuple[int, ...] = (64, 64)
    log_std_init: float = -0.5
    start_log_std: float | None = None   # a given (warm) start's log-std is set to this
    #                              first (None: kept); base.START_LOG_STD is the shared rule
    seed: int = 0

    def __post_init__(self):
        # Types first (a 0-wide layer, a bool for a count, an infinite rate), then the ranges.
        check_fields(self, positive=("n_envs", "n_steps", "total_steps", "episode_steps",
                                     "buffer_steps", "flow_layers", "flow_lr", "model_batch",
                                     "policy_batch", "lr"),
                     non_negative=("model_steps", "policy_steps", "predecessor_weight", "seed"))
        if not 0 < self.gamma < 1:
            raise ValueError(f"GPRILConfig.gamma must be in (0, 1), got {self.gamma}")
        for name in ("n_envs", "n_steps", "buffer_steps", "flow_layers", "model_batch",
                     "policy_batch"):
            if getattr(self, name) < 1:
                raise ValueError(f"GPRILConfig.{name} must be at least 1, got "
                                 f"{getattr(self, name)}")
        if self.n_updates < 1:
            raise ValueError(f"total_steps = {self.total_steps} is less than one batch "
                             f"({self.n_envs * self.n_steps} steps)")
        if self.predecessor_weight < 0 or not (self.lr > 0 and self.flow_lr > 0):
            raise ValueError("GPRILConfig.predecessor_weight >= 0, lr > 0 and flow_lr > 0")

    @property
    def n_updates(self) -> int:
        return self.total_steps // (self.n_envs * self.n_steps)

    def with_steps(self, total_steps: int) -> "GPRILConfig":
        return dataclasses.replace(self, total_steps=int(total_steps))

    def to_dict(self) -> dict:
        return json.loads(json.dumps(_base.unset_dropped(dataclasses.asdict(self),
                                                         ("start_log_std", "terminate"))))

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)


def sized(total_steps: int, seed: int = 0, base: GPRILConfig | None = None) -> GPRILConfig:
    """GPRIL for ``total_steps`` interactions; a short run (``smoke``) takes smaller batches
    so it still makes four iterations."""
    cfg = base or GPRILConfig()
    if total_steps < 4 * cfg.n_envs * cfg.n_steps:
        cfg = dataclasses.replace(cfg, n_steps=max(8, total_steps // (4 * cfg.n_envs)))
    return dataclasses.replace(cfg, total_steps=int(total_steps), seed=int(seed))


def preset(budget, seed: int = 0) -> GPRILConfig:
    """GPRIL at a budget: ``il_steps`` interactions; few model and policy steps at smoke."""
    cfg = sized(budget.il_steps, seed)
    if budget.is_smoke:
        cfg = dataclasses.replace(cfg, model_steps=3, policy_steps=3, flow_hidden=(16, 16),
                                  model_batch=64, policy_batch=64)
    return cfg


# -- a conditional masked autoregressive flow ------------------------------------------------

class MADE(nn.Module):
    """mu(x_{<i}, c), alpha(x_{<i}, c) for i = 1..D: masked tanh MLP; the context c reaches
    every hidden unit.  Hidden unit k has degree m_k = k mod D (0: context only) and sees the
    inputs of degree <= m_k; output i (degree i) sees the hidden units with m_k < i."""

    def __init__(self, dim: int, context_dim: int, hidden=(64, 64)):
        super().__init__()
        degrees = [torch.arange(1, dim + 1)] + [torch.arange(h) % dim for h in hidden]
        self.layers, self.masks = nn.ModuleList(), []
        for i, h in enumerate(hidden):
            self.layers.append(nn.Linear(degrees[i].numel(), h))
            self.masks.append((degrees[i + 1][:, None] >= degrees[i][None, :]).float())
        self.out = nn.Linear(hidden[-1], 2 * dim)
        out_mask = (torch.arange(1, dim + 1)[:, None] > degrees[-1][None, :]).float()
        self.masks.append(torch.cat([out_mask, out_mask]))
        self.context = nn.Linear(context_dim, hidden[0])
        for i, m in enumerate(self.masks):
            self.register_buffer(f"mask{i}", m)
        nn.init.zeros_(self.out.weight)      # starts as the identity map
        nn.init.zeros_(self.out.bias)

    def forward(self, x: torch.Tensor, c: torch.Tensor):
        return self.frozen(c)(x)

    def frozen(self, c: torch.Tensor):
        """``x -> forward(x, c)`` with the masked weights and the context's projection computed
        once: sampling calls it D times per layer with the same weights and context (the
        same operations on the same values, so the same numbers as :meth:`forward`)."""
        weights = [layer.weight * getattr(self, f"mask{i}") for i, layer in enumerate(self.layers)]
        w_out = self.out.weight * getattr(self, f"mask{len(self.layers)}")
        context = self.context(c)

        def apply(x: torch.Tensor):
            h = x
            for i, layer in enumerate(self.layers):
                h = nn.functional.linear(h, weights[i], layer.bias)
                h = torch.tanh(h + context if i == 0 else h)
            mu, alpha = nn.functional.linear(h, w_out, self.out.bias).chunk(2, -1)
            return mu, 5.0 * torch.tanh(alpha / 5.0)
        return apply

    @torch.no_grad()
    def numpy_invert(self, c: np.ndarray, y: np.ndarray) -> np.ndarray:
        """x with x_i = mu_i(x_{<i}, c) + y_i exp(alpha_i(x_{<i}, c)), i = 1..D, in NumPy: the
        D passes of :meth:`ConditionalMAF.sample` on the reader's path, to float32 rounding
        (the fast path, :mod:`dc_lesson.nn.fast`).  Output i sees only the hidden units of
        degree <= i, and they only the inputs before i: with the units sorted by degree, pass i
        multiplies the leading blocks of the weights; with a column of ones and the context
        before x in one column-major input, the first layer is one product on a contiguous
        block."""
        n_rows, dim, c_dim = len(c), self.out.weight.shape[0] // 2, c.shape[1]
        degree = [np.arange(layer.weight.shape[0]) % dim for layer in self.layers]
        order = [np.argsort(d, kind="stable") for d in degree]
        counts = [np.searchsorted(np.sort(d), np.arange(dim), side="right") for d in degree]
        w = [(layer.weight * getattr(self, f"mask{k}")).numpy() for k, layer in
             enumerate(self.layers)]
        o0 = order[0]
        first = np.concatenate([(self.layers[0].bias + self.context.bias).numpy()[o0][None],
                                self.context.weight.numpy()[o0].T, w[0][o0].T])
        rest = [(w[k][np.ix_(order[k], order[k - 1])].T, self.layers[k].bias.numpy()[order[k]])
                for k in range(1, len(w))]
        w_out = (self.out.weight * getattr(self, f"mask{len(self.layers)}")).numpy()
        w_out, b_out = w_out[:, order[-1]].T, self.out.bias.numpy()
        inputs = np.empty((n_rows, 1 + c_dim + dim), np.float32, order="F")
        inputs[:, 0], inputs[:, 1:1 + c_dim] = 1.0, c
        for i in range(dim):
            n = counts[0][i]
            # (contiguous blocks: a strided one multiplies at half the speed)
            h = inputs[:, :1 + c_dim + i] @ np.ascontiguousarray(first[:1 + c_dim + i, :n])
            np.tanh(h, out=h)
            for k, (wk, bk) in enumerate(rest, 1):
                m = counts[k][i]
                h = h @ np.ascontiguousarray(wk[:n, :m])
                h += bk[:m]
                np.tanh(h, out=h)
                n = m
            out = h @ np.ascontiguousarray(w_out[:n, [i, dim + i]]) + b_out[[i, dim + i]]
            inputs[:, 1 + c_dim + i] = out[:, 0] + y[:, i] * np.exp(5.0 * np.tanh(out[:, 1] / 5.0))
        return inputs[:, 1 + c_dim:]


class ConditionalMAF(nn.Module):
    """p(x | c): ``n_layers`` MADE affine layers, dimension order reversed between them, on
    standardised x and c (the statistics are buffers: ``x_mean`` ... ``c_std``)."""

    def __init__(self, dim: int, context_dim: int, hidden=(64, 64), n_layers: int = 3):
        super().__init__()
        self._config = dict(dim=int(dim), context_dim=int(context_dim),
                            hidden=[int(h) for h in hidden], n_layers=int(n_layers))
        self.dim = int(dim)
        self.mades = nn.ModuleList(MADE(dim, context_dim, hidden) for _ in range(n_layers))
        for name, n in (("x_mean", dim), ("x_std", dim), ("c_mean", context_dim),
                        ("c_std", context_dim)):
            self.register_buffer(name, torch.zeros(n) if "mean" in name else torch.ones(n))

    def config(self) -> dict:
        return dict(self._config)

    @torch.no_grad()
    def set_standardisation(self, x_mean, x_std, c_mean, c_std) -> None:
        for name, v in (("x_mean", x_mean), ("x_std", x_std), ("c_mean", c_mean),
                        ("c_std", c_std)):
            getattr(self, name).copy_(torch.as_tensor(v, dtype=torch.float32))

    def to_base(self, x, c):
        """u (the base variable) and log|du/dx| of data x given context c."""
        u = (torch.as_tensor(x, dtype=torch.float32) - self.x_mean) / self.x_std
        c = (torch.as_tensor(c, dtype=torch.float32) - self.c_mean) / self.c_std
        logdet = -torch.log(self.x_std).sum().expand(u.shape[:-1])
        for made in self.mades:
            mu, alpha = made(u, c)
            u = ((u - mu) * torch.exp(-alpha)).flip(-1)     # the next layer's order: reversed
            logdet = logdet - alpha.sum(-1)
        return u, logdet

    def log_prob(self, x, c) -> torch.Tensor:
        u, logdet = self.to_base(x, c)
        return -0.5 * (u ** 2).sum(-1) - 0.5 * self.dim * LOG_2PI + logdet

    @torch.no_grad()
    def sample(self, c, generator: torch.Generator | None = None,
               noise: torch.Tensor | None = None) -> torch.Tensor:
        """One x per context row: invert the layers, one dimension at a time.  ``noise``: the
        base draws u (rows, D) to invert, instead of drawing them from ``generator``."""
        c = (torch.as_tensor(c, dtype=torch.float32) - self.c_mean) / self.c_std
        u = torch.randn(c.shape[0], self.dim, generator=generator) if noise is None else noise
        if _fast.enabled():   # the same passes in NumPy (MADE.numpy_invert)
            c_np, u_np = c.numpy(), u.numpy()
            for made in reversed(self.mades):
                u_np = made.numpy_invert(c_np, u_np[:, ::-1])
            return torch.from_numpy(np.ascontiguousarray(u_np)) * self.x_std + self.x_mean
        for made in reversed(self.mades):
            y, x = u.flip(-1), torch.zeros_like(u)
            step = made.frozen(c)
            for i in range(self.dim):              # x_i needs x_{<i}: D passes
                mu, alpha = step(x)
                x[:, i] = mu[:, i] + y[:, i] * torch.exp(alpha[:, i])
            u = x
        return u * self.x_std + self.x_mean


# -- horizons, the buffer and the predecessors -----------------------------------------------

def sample_horizons(n: int, gamma: float, generator: torch.Generator) -> torch.Tensor:
    """n draws of j ~ Geometric(1 - gamma) on {1, 2, ...}: P(j) = (1 - gamma) gamma^(j-1),
    by inversion, j = ceil(log U / log gamma)."""
    u = torch.rand(n, generator=generator, dtype=torch.float64).clamp_min(1e-300)
    return torch.ceil(torch.log(u) / math.log(gamma)).clamp_min(1).long()


class Buffer:
    """The last ``capacity`` steps of every environment: obs (T, N, d), act, episode ids."""

    def __init__(self, capacity: int):
        self.capacity = int(capacity)
        self.obs = self.act = self.episode = None

    def add(self, obs, act, episode) -> None:
        if self.obs is None:
            self.obs, self.act, self.episode = obs, act, episode
        else:
            self.obs = torch.cat([self.obs, obs])[-self.capacity:]
            self.act = torch.cat([self.act, act])[-self.capacity:]
            self.episode = torch.cat([self.episode, episode])[-self.capacity:]

    def state(self) -> dict:
        return {"obs": self.obs, "act": self.act, "episode": self.episode}

    def load(self, state: dict) -> None:
        self.obs, self.act, self.episode = state["obs"], state["act"], state["episode"]


def sample_tuples(buffer: Buffer, n: int, gamma: float, generator: torch.Generator):
    """n tuples (s_t, a_t, s_{t+j}) of one episode each, j ~ Geometric(1 - gamma)."""
    T, N = buffer.episode.shape
    out, have = [], 0
    for _ in range(100):
        j = sample_horizons(n, gamma, generator)
        ok = j < T
        j = j[ok]
        t = (torch.rand(len(j), generator=generator, dtype=torch.float64) * (T - j)).long()
        e = torch.randint(N, (len(j),), generator=generator)
        same = buffer.episode[t, e] == buffer.episode[t + j, e]
        t, j, e = t[same], j[same], e[same]
        out.append((buffer.obs[t, e], buffer.act[t, e], buffer.obs[t + j, e], j))
        have += len(j)
        if have >= n:
            break
    s, a, f, j = (torch.cat(x)[:n] for x in zip(*out))
    return s, a, f, j


def predecessors(state_flow: ConditionalMAF, action_flow: ConditionalMAF, targets,
                 generator: torch.Generator):
    """s~ ~ B_s(. | s_E), a~ ~ B_a(. | s~, s_E) for target states s_E (n, d)."""
    s = state_flow.sample(targets, generator)
    a = action_flow.sample(torch.cat([s, targets], -1), generator)
    return s, a


def all_predecessors(state_flow: ConditionalMAF, action_flow: ConditionalMAF, e_obs,
                     steps: int, batch: int, expert_gen: torch.Generator,
                     model_gen: torch.Generator):
    """The fast path's policy steps (:mod:`dc_lesson.nn.fast`): every step's expert indices
    and predecessors, drawn in the reader's order (per step: the indices, then B_s's noise,
    then B_a's) but sampled in one pass of each flow, which the policy steps leave unchanged.
    Returns the indices and both samples, split per step."""
    idx, us, ua = [], [], []
    for _ in range(steps):
        idx.append(torch.randint(len(e_obs), (batch,), generator=expert_gen))
        us.append(torch.randn(batch, state_flow.dim, generator=model_gen))
        ua.append(torch.randn(batch, action_flow.dim, generator=model_gen))
    targets = e_obs[torch.cat(idx)]
    s = state_flow.sample(targets, noise=torch.cat(us))
    a = action_flow.sample(torch.cat([s, targets], -1), noise=torch.cat(ua))
    return idx, s.split(batch), a.split(batch)


def standardise(state_flow: ConditionalMAF, action_flow: ConditionalMAF, buffer: Buffer,
                floor: float = 1e-3) -> None:
    """Both flows' standardisation from the learner's steps in ``buffer`` (std floored)."""
    s = buffer.obs.reshape(-1, buffer.obs.shape[-1])
    a = buffer.act.reshape(-1, buffer.act.shape[-1])
    sm, ss = s.mean(0), s.std(0).clamp_min(floor)
    state_flow.set_standardisation(sm, ss, sm, ss)
    action_flow.set_standardisation(a.mean(0), a.std(0).clamp_min(floor), torch.cat([sm, sm]),
                                    torch.cat([ss, ss]))


# -- the learner ---------------------------------------------------------------------------------

CHECKPOINT_FORMAT, CHECKPOINT_VERSION = "dc_lesson.gpril.checkpoint", 1


def train(task: str, demos, config: GPRILConfig = GPRILConfig(), *,
          policy: GaussianPolicy | None = None, progress: bool = True, checkpoint=None,
          callback=None, checkpoint_every: int = 10) -> TrainResult:
    """GPRIL on ``task``; returns a :class:`TrainResult` (``models["state_flow"]`` B_s,
    ``models["action_flow"]`` B_a).  ``policy``, ``checkpoint`` and ``callback`` as in GAIL.
    ``log``: per iteration the flows' mean NLLs, the policy's expert and predecessor NLLs, its
    log-std, the mean horizon of the tuples, the training episodes' return, steps per second."""
    spec = _tasks.spec(task)
    check_inputs(task, demos, policy)
    init_seed, sample_seed, env_seed, model_seed, expert_seed = _base.seed_streams(
        config.seed, "init", "sample", "env", "model", "expert")
    e_obs, e_act = _bc.pairs(demos)
    _base.set_start_noise(policy, config.start_log_std)   # a given start's noise
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(init_seed)
        if policy is None:
            policy = GaussianPolicy(spec.obs_dim, spec.act_dim, config.hidden,
                                    log_std_init=config.log_std_init, norm_obs=True)
            policy.update_obs_norm(e_obs)
        state_flow = ConditionalMAF(spec.obs_dim, spec.obs_dim, config.flow_hidden,
                                    config.flow_layers)
        action_flow = ConditionalMAF(spec.act_dim, 2 * spec.obs_dim, config.flow_hidden,
                                     config.flow_layers)
    # fused on the fast path (dc_lesson.nn.fast)
    flow_opt = _fast.adam([*state_flow.parameters(), *action_flow.parameters()],
                          lr=config.flow_lr)
    pi_opt = _fast.adamw(policy.parameters(), lr=config.lr)
    generator = torch.Generator().manual_seed(sample_seed)
    model_gen = torch.Generator().manual_seed(model_seed)
    expert_gen = torch.Generator().manual_seed(expert_seed)
    envs = _ppo.EnvBatch(task, config.n_envs, env_seed, config.episode_steps, config.terminate)
    buffer, episode = Buffer(config.buffer_steps), 0
    networks = {"policy": policy, "state_flow": state_flow, "action_flow": action_flow}
    optimizers = {"flow_optimizer": flow_opt, "optimizer": pi_opt}
    generators = {"generator": generator, "model_generator": model_gen,
                  "expert_generator": expert_gen}
    first, log = 0, []
    if checkpoint is not None and pathlib.Path(checkpoint).exists():
        first, log, ckpt = load_run(checkpoint, CHECKPOINT_FORMAT, CHECKPOINT_VERSION,
                                    "GPRIL checkpoint", task=task,
                                    saved_config=lambda c: json.loads(c["config"]),
                                    now_config=config.to_dict(), networks=networks,
                                    optimizers=optimizers, generators=generators, envs=envs)
        buffer.load(ckpt["buffer"])
        episode = int(ckpt["episode"])

    bar = _progress.bar(total=config.n_updates, initial=first, desc=f"GPRIL {task}",
                        unit="iter", enabled=progress)
    for update in range(first, config.n_updates):
        start = time.perf_counter()
        # 1. the learner's own experience
        obs, act, ep, finished = [], [], [], []
        sampler = _fast.GaussianSampler(policy) if _fast.enabled() else None
        with torch.no_grad():
            for _ in range(config.n_steps):
                o = torch.from_numpy(envs.obs).float()
                a = (torch.from_numpy(sampler(envs.obs, generator)[0]) if sampler is not None
                     else policy.sample(o, generator))
                _, _, done, f = envs.step(a.numpy())
                obs.append(o)
                act.append(a.clamp(ACTION_LOW, ACTION_HIGH))
                ep.append(torch.full((config.n_envs,), episode))
                finished += f
                episode += int(done.any())   # the copies end their episodes together
        buffer.add(torch.stack(obs), torch.stack(act), torch.stack(ep))
        if update == 0:   # the flows' input scale: the first batch's, then fixed
            standardise(state_flow, action_flow, buffer)

        # 2. the predecessor models on it
        model_terms = []
        for _ in range(config.model_steps):
            s, a, fut, j = sample_tuples(buffer, config.model_batch, config.gamma, model_gen)
            nll_s = -state_flow.log_prob(s, fut).mean()
            nll_a = -action_flow.log_prob(a, torch.cat([s, fut], -1)).mean()
            _fast.zero_grad(flow_opt)
            (nll_s + nll_a).backward()
            _fast.optimizer_step(flow_opt)
            model_terms.append((float(nll_s.detach()), float(nll_a.detach()),
                                float(j.double().mean())))

        # 3. the policy by likelihood on the expert's pairs and their predecessors
        pi_terms = []
        drawn = (all_predecessors(state_flow, action_flow, e_obs, config.policy_steps,
                                  config.policy_batch, expert_gen, model_gen)
                 if _fast.enabled() and config.policy_steps else None)
        for k in range(config.policy_steps):
            if drawn is None:
                i = torch.randint(len(e_obs), (config.policy_batch,), generator=expert_gen)
                ps, pa = predecessors(state_flow, action_flow, e_obs[i], model_gen)
            else:
                i, ps, pa = drawn[0][k], drawn[1][k], drawn[2][k]
            nll_e = -policy.log_prob(e_obs[i], e_act[i]).mean()
            nll_p = -policy.log_prob(ps, pa.clamp(ACTION_LOW, ACTION_HIGH)).mean()
            _fast.zero_grad(pi_opt)
            (nll_e + config.predecessor_weight * nll_p).backward()
            _fast.optimizer_step(pi_opt)
            pi_terms.append((float(nll_e.detach()), float(nll_p.detach())))

        mt = np.mean(model_terms, 0) if model_terms else [math.nan] * 3
        pt = np.mean(pi_terms, 0) if pi_terms else [math.nan] * 2
        row = {"update": update + 1, "steps": (update + 1) * config.n_envs * config.n_steps,
               "state_flow_nll": float(mt[0]), "action_flow_nll": float(mt[1]),
               "horizon_mean": float(mt[2]), "expert_nll": float(pt[0]),
               "predecessor_nll": float(pt[1]), "log_std": float(policy.log_std.detach().mean()),
               "episode_return": float(np.mean(finished)) if finished else math.nan,
               "n_episodes": len(finished),
               "steps_per_second": config.n_envs * config.n_steps
               / (time.perf_counter() - start)}
        log.append(row)
        done = update + 1 == config.n_updates
        if checkpoint is not None and ((update + 1) % checkpoint_every == 0 or done):
            save_run(checkpoint, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, task=task,
                     config_json=config.to_json(), update=update + 1, networks=networks,
                     optimizers=optimizers, generators=generators, envs=envs, log=log,
                     buffer=buffer.state(), episode=episode)
        bar.update(1)
        bar.set_postfix(nll_e=f"{row['expert_nll']:.2f}", nll_p=f"{row['predecessor_nll']:.2f}")
        if callback is not None and callback(row, policy):
            break
    bar.close()
    policy.meta = {**getattr(policy, "meta", {}), "algorithm": "gpril",
                   "gpril_config": config.to_dict(), "task": task}
    return TrainResult(policy, log, {"state_flow": state_flow, "action_flow": action_flow},
                       "gpril")


__all__ = ["Buffer", "ConditionalMAF", "GPRILConfig", "MADE", "all_predecessors",
           "predecessors", "preset",
           "sample_horizons", "sample_tuples", "sized", "train"]
