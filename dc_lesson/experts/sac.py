"""Soft actor-critic (Haarnoja et al. 2018), the off-policy learner behind the network experts
of ``walker``, ``ant`` and ``humanoid``: ``dc-lesson expert train --task NAME``
(:mod:`dc_lesson.experts.network` holds the recipes).

Why SAC here: the library's PPO stayed below the floors on these tasks after 5M interactions
(walker 328, ant 160; ``data/experts/walker-ppo.json``), and the sampling planner that meets them
is not a Markov policy, so BC cannot clone it (scaled return about 0). SAC reuses every
transition many times, which on a 2-core machine is what matters.

One readable loop, CleanRL's ``sac_continuous_action.py`` with every detail named:

* a tanh-squashed Gaussian actor, a = tanh(u), u ~ N(mu(s), sigma(s)^2), log-prob corrected by
  sum log(1 - tanh(u)^2) (Appendix C of the paper);
* two Q networks and their Polyak-averaged targets (tau = 0.005); the target is
  r + gamma * (min_j Q'_j(s', a') - alpha log pi(a'|s')), a' ~ pi(.|s');
* the entropy temperature alpha tuned towards the target entropy -act_dim;
* the fixed horizon is a time limit, not a terminal state, so the target bootstraps there;
  only a *training-only* termination (``terminate``, a name in ``tasks.TERMINATIONS``, as
  PPO's ``terminate``: Gym's fallen humanoid) ends an episode early, and its last transition
  is terminal (no bootstrap). The tasks themselves never end early;
* optional expert demonstrations (``demo_fraction`` > 0, RLPD's symmetric sampling, Ball et
  al. 2023): their transitions (r from the task, never terminal) fill a second buffer, and that
  share of every minibatch is drawn from it, the rest from the agent's own buffer (tried on
  the humanoid and rejected: the measurements are with its recipe,
  :data:`dc_lesson.experts.network.SAC_RECIPES`);
* optional LayerNorm in the critics' hidden layers (``critic_layer_norm``, RLPD's other
  ingredient), which keeps Q near the data's values when demonstrations sit beside the
  agent's own transitions;
* optional starts from demonstrated states (``demo_starts``: that share of training episodes
  begins at a state drawn uniformly from the demonstrations, recovered by replaying their
  actions from their initial states: reference state initialisation, Peng et al. 2018,
  DeepMimic), the humanoid's recipe, for SAC alone never saw a humanoid get up. The
  evaluations always start from the task's own initial states;
* ``learning_starts`` uniformly random actions first; then one gradient step per environment
  step; the actor and alpha every ``policy_frequency`` steps, that many times (CleanRL's
  delayed update).

The two Q networks are one module whose weights carry a leading ensemble axis (a batched
matrix product), which on one CPU thread is about twice as fast as two separate networks and
gives the same function.

Checkpoints (``data/experts/checkpoints/UNIT.sac``, not committed: the replay buffer is
hundreds of MB) hold the networks, optimisers, buffer, generators and environment state, so a
run cut by a session's end resumes exactly where it stopped. The finished actor becomes a
:class:`~dc_lesson.nn.policies.GaussianPolicy` expert by distillation
(:func:`dc_lesson.experts.network.distil`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json as _json
import math
import pathlib
import time

import numpy as np
import torch
from torch import nn
import torch.nn.functional as F

from dc_lesson import tasks as _tasks
from dc_lesson.nn.checkpoint import ModelFileError, atomic_torch_save, load_checked

CHECKPOINT_FORMAT, CHECKPOINT_VERSION = "dc_lesson.sac", 1


@dataclasses.dataclass(frozen=True)
class SACConfig:
    total_steps: int = 1_000_000
    buffer_size: int = 1_000_000
    gamma: float = 0.99
    tau: float = 0.005               # Polyak averaging of the target Q networks
    batch_size: int = 256
    learning_starts: int = 5_000     # random actions before the first update
    policy_lr: float = 3e-4
    q_lr: float = 1e-3
    policy_frequency: int = 2        # actor and alpha updated every 2 steps, twice (CleanRL)
    hidden: tuple = (256, 256)
    log_std_min: float = -5.0
    log_std_max: float = 2.0
    autotune: bool = True            # alpha tuned towards entropy -act_dim
    alpha: float = 0.2               # the fixed temperature when not autotuned
    log_every: int = 5_000           # a log row (and an evaluation) every this many steps
    checkpoint_every: int = 25_000
    eval_episodes: int = 2
    terminate: str | None = None     # a training-only termination (tasks.TERMINATIONS)
    demo_fraction: float = 0.0       # share of each minibatch from demonstrations (RLPD: 0.5)
    critic_layer_norm: bool = False  # LayerNorm in the Q networks' hidden layers (RLPD)
    demo_starts: float = 0.0         # share of training episodes begun at a demonstrated state
    seed: int = 0

    def __post_init__(self):
        for name in ("total_steps", "buffer_size", "batch_size", "policy_frequency",
                     "log_every", "checkpoint_every", "eval_episodes"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"SACConfig.{name} must be a positive integer, got {v!r}")
        if isinstance(self.learning_starts, bool) or not isinstance(self.learning_starts, int) \
                or not self.batch_size <= self.learning_starts:
            raise ValueError(f"SACConfig.learning_starts must be an integer >= batch_size "
                             f"({self.batch_size}), got {self.learning_starts!r}")
        for name in ("policy_lr", "q_lr", "tau", "alpha"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"SACConfig.{name} must be a positive finite number, got {v!r}")
        if not (isinstance(self.demo_fraction, (int, float)) and not
                isinstance(self.demo_fraction, bool) and 0 <= self.demo_fraction < 1):
            raise ValueError(f"SACConfig.demo_fraction must be a number in [0, 1), got "
                             f"{self.demo_fraction!r}")
        if not (isinstance(self.demo_starts, (int, float)) and not
                isinstance(self.demo_starts, bool) and 0 <= self.demo_starts <= 1):
            raise ValueError(f"SACConfig.demo_starts must be a number in [0, 1], got "
                             f"{self.demo_starts!r}")
        if not isinstance(self.critic_layer_norm, bool):
            raise ValueError(f"SACConfig.critic_layer_norm must be True or False, got "
                             f"{self.critic_layer_norm!r}")
        if not 0 < self.gamma < 1 or self.tau > 1:
            raise ValueError("SACConfig needs 0 < gamma < 1 and 0 < tau <= 1")
        if self.terminate is not None and self.terminate not in _tasks.TERMINATIONS:
            raise ValueError(f"SACConfig.terminate must be one of "
                             f"{', '.join(_tasks.TERMINATIONS)} or None, got {self.terminate!r}")
        if not self.hidden or any(isinstance(h, bool) or not isinstance(h, int) or h < 1
                                  for h in self.hidden):
            raise ValueError(f"SACConfig.hidden must be positive layer widths, got "
                             f"{self.hidden!r}")


# -- networks --------------------------------------------------------------------------------

class Actor(nn.Module):
    """mu(s) and log sigma(s) from one ReLU MLP; actions a = tanh(u)."""

    def __init__(self, obs_dim, act_dim, hidden, log_std_min, log_std_max):
        super().__init__()
        layers, d = [], obs_dim
        for h in hidden:
            layers += [nn.Linear(d, h), nn.ReLU()]
            d = h
        self.trunk = nn.Sequential(*layers)
        self.mu = nn.Linear(d, act_dim)
        self.log_std = nn.Linear(d, act_dim)
        self.log_std_min, self.log_std_max = log_std_min, log_std_max

    def forward(self, obs):
        h = self.trunk(obs)
        # squashed into [min, max] as CleanRL does, so sigma never explodes or vanishes
        log_std = torch.tanh(self.log_std(h))
        log_std = self.log_std_min + 0.5 * (self.log_std_max - self.log_std_min) * (log_std + 1)
        return self.mu(h), log_std

    def sample(self, obs, generator=None):
        """(a, log pi(a|s), tanh(mu)): a reparameterised sample and its corrected log-prob."""
        mu, log_std = self(obs)
        std = log_std.exp()
        u = mu + std * torch.randn(mu.shape, generator=generator)
        a = torch.tanh(u)
        logp = (-0.5 * ((u - mu) / std) ** 2 - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)
        logp = logp - torch.log(1 - a.pow(2) + 1e-6).sum(-1)
        return a, logp, torch.tanh(mu)

    def act_numpy(self, obs: np.ndarray) -> np.ndarray:
        """The deterministic action tanh(mu(s)) for a NumPy batch (the expert's action)."""
        with torch.no_grad():
            return torch.tanh(self(torch.as_tensor(obs, dtype=torch.float32))[0]).numpy()


class TwinQ(nn.Module):
    """Two Q networks as one: weights (2, in, out), one batched matmul per layer.

    ``layer_norm``: each hidden layer's pre-activations normalised over its units (no learnt
    scale or shift), as RLPD's critics (Ball et al. 2023), which keeps Q from extrapolating
    far above the data at actions no transition holds."""

    def __init__(self, in_dim, hidden, n=2, layer_norm: bool = False):
        super().__init__()
        self.layer_norm = bool(layer_norm)
        dims = [in_dim, *hidden, 1]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for a, b in zip(dims[:-1], dims[1:]):
            w = torch.empty(n, a, b)
            for k in range(n):   # nn.Linear's default initialisation, per member
                lin = nn.Linear(a, b)
                w[k] = lin.weight.detach().T
            self.weights.append(nn.Parameter(w))
            bound = 1 / math.sqrt(a)
            self.biases.append(nn.Parameter(torch.empty(n, 1, b).uniform_(-bound, bound)))

    def forward(self, obs, act):
        """Q values, shape (2, B)."""
        x = torch.cat([obs, act], -1).unsqueeze(0).expand(len(self.weights[0]), -1, -1)
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            x = torch.baddbmm(b, x, w)
            if i < len(self.weights) - 1:
                if self.layer_norm:
                    x = F.layer_norm(x, x.shape[-1:])
                x = F.relu(x)
        return x.squeeze(-1)


# -- the loop --------------------------------------------------------------------------------

def evaluate(task: str, actor: Actor, episodes: int, seed: int) -> float:
    """Mean return of the deterministic action tanh(mu) over ``episodes`` fresh episodes."""
    env = _tasks.load_vec(task, episodes)
    obs, _ = env.reset(seed + np.arange(episodes))
    total = np.zeros(episodes)
    done = False
    while not done:
        obs, r, _, done = env.step(actor.act_numpy(obs))
        total += r
    return float(total.mean())


def _alpha_of(cfg, log_alpha):
    return log_alpha.exp().item() if cfg.autotune else cfg.alpha


def demo_buffer(task: str, trajectories) -> dict[str, np.ndarray]:
    """The transitions of ``trajectories`` (whole episodes of ``task``) as a replay buffer.

    Every transition bootstraps (``done`` 0): the demonstrations end at the time limit."""
    trajectories = list(trajectories)
    if not trajectories or any(getattr(t, "task", None) != task for t in trajectories):
        raise ValueError(f"SAC's demonstrations must be {task} trajectories (at least one), "
                         f"e.g. dc_lesson.data.load_demos({task!r}).trajectories")
    cat = lambda f: np.concatenate([f(t) for t in trajectories]).astype(np.float32)  # noqa: E731
    obs = cat(lambda t: t.observations[:-1])
    return {"obs": obs, "act": cat(lambda t: t.actions), "rew": cat(lambda t: t.rewards),
            "next_obs": cat(lambda t: t.observations[1:]), "done": np.zeros(len(obs), np.float32)}


def demo_states(task: str, trajectories) -> np.ndarray:
    """The simulator states (``TaskEnv.get_state``) before each action of ``trajectories``,
    by replaying the actions from each one's initial state: (sum of lengths, state size)."""
    env = _tasks.make(task)
    out = []
    for t in trajectories:
        env.reset(seed=t.seed)
        env.set_state(t.initial_state)
        for a in t.actions:
            out.append(env.get_state())
            env.step(a)
    return np.stack(out)


def _digest(buffer) -> str:
    h = hashlib.sha256()
    for k in sorted(buffer):
        h.update(np.ascontiguousarray(buffer[k]).tobytes())
    return h.hexdigest()


def train(task: str, config: SACConfig = SACConfig(), checkpoint=None, progress=None,
          stop_after_seconds: float | None = None, demonstrations=None) -> dict:
    """Trains SAC on ``task``'s own reward; returns ``{"actor", "log", "done", ...}``.

    ``checkpoint``: a path; resumed from when it exists (same config required), written every
    ``checkpoint_every`` steps (always at an episode's end, so the environment restarts from a
    seed and the resumed run is the uninterrupted one, bit for bit at one thread).
    ``stop_after_seconds``: stop at the first checkpoint after this much wall time (a chunk).
    ``progress``: a callable given each log row. ``demonstrations``: the trajectories that
    ``demo_fraction`` samples from and ``demo_starts`` starts at (required exactly when either
    is above 0; a resumed run must be given the same ones, checked by their digest).
    """
    cfg = config
    if (cfg.demo_fraction > 0 or cfg.demo_starts > 0) != (demonstrations is not None):
        raise ValueError("SAC takes demonstrations exactly when SACConfig.demo_fraction or "
                         f"demo_starts is above 0 (they are {cfg.demo_fraction} and "
                         f"{cfg.demo_starts}): pass both or neither")
    demo = demo_buffer(task, demonstrations) if demonstrations is not None else None
    demo_sha = _digest(demo) if demo is not None else None
    n_demo = int(round(cfg.batch_size * cfg.demo_fraction))
    starts = demo_states(task, demonstrations) if cfg.demo_starts > 0 else None
    spec = _tasks.SPECS[_tasks.check_name(task)]
    if cfg.checkpoint_every % spec.horizon or cfg.log_every % spec.horizon:
        raise ValueError(f"checkpoint_every and log_every must be multiples of {task}'s "
                         f"horizon ({spec.horizon}), so a checkpoint falls between episodes")
    obs_dim, act_dim = spec.obs_dim, spec.act_dim
    torch.manual_seed(cfg.seed)
    actor = Actor(obs_dim, act_dim, cfg.hidden, cfg.log_std_min, cfg.log_std_max)
    qf = TwinQ(obs_dim + act_dim, cfg.hidden, layer_norm=cfg.critic_layer_norm)
    qf_target = TwinQ(obs_dim + act_dim, cfg.hidden, layer_norm=cfg.critic_layer_norm)
    qf_target.load_state_dict(qf.state_dict())
    log_alpha = torch.zeros(1, requires_grad=True)
    target_entropy = -float(act_dim)
    q_opt = torch.optim.Adam(qf.parameters(), lr=cfg.q_lr, fused=True)
    pi_opt = torch.optim.Adam(actor.parameters(), lr=cfg.policy_lr, fused=True)
    a_opt = torch.optim.Adam([log_alpha], lr=cfg.q_lr)
    n = min(cfg.buffer_size, cfg.total_steps)
    buf = {"obs": np.zeros((n, obs_dim), np.float32), "act": np.zeros((n, act_dim), np.float32),
           "rew": np.zeros(n, np.float32), "next_obs": np.zeros((n, obs_dim), np.float32),
           "done": np.zeros(n, np.float32)}   # 1: a training-only terminal transition
    rng = np.random.default_rng(cfg.seed)           # random actions, minibatch indices
    gen = torch.Generator().manual_seed(cfg.seed)   # the actor's sampling noise
    step, size, ptr, episode, log, seconds = 0, 0, 0, 0, [], 0.0
    ckpt = pathlib.Path(checkpoint) if checkpoint else None
    if ckpt is not None and ckpt.exists():
        fix = f"delete {ckpt} to train from the start"
        st = load_checked(ckpt, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, "SAC checkpoint", fix)
        # total_steps only says where the run stops (and sizes the buffer, which a run of at
        # most buffer_size steps never fills), so a run may be extended: the same run as an
        # uninterrupted longer one
        if not isinstance(st.get("config"), dict) or \
                {**json_config(SACConfig()), **st["config"], "total_steps": cfg.total_steps} \
                != json_config(cfg):
            raise ValueError(f"the SAC checkpoint {ckpt} was made with another configuration; "
                             f"delete it to train from the start")
        if isinstance(st.get("step"), int) and st["step"] > cfg.total_steps:
            raise ValueError(f"the SAC checkpoint {ckpt} is at step {st.get('step')}, past "
                             f"total_steps = {cfg.total_steps}; give at least that many, or "
                             f"{fix}")
        if st.get("demos_sha256") != demo_sha:
            raise ValueError(f"the SAC checkpoint {ckpt} was made with other demonstrations; "
                             f"pass the same ones, or {fix}")
        try:   # a file that passed its checksum but lacks a part (a bare KeyError names none)
            actor.load_state_dict(st["actor"]); qf.load_state_dict(st["qf"])
            qf_target.load_state_dict(st["qf_target"])
            with torch.no_grad():
                log_alpha.copy_(st["log_alpha"])
            for o, s in zip((q_opt, pi_opt, a_opt), st["opts"]):
                o.load_state_dict(s)
            size, ptr, step, episode = st["size"], st["ptr"], st["step"], st["episode"]
            if size == step:   # nothing overwritten yet: the next slot, in a longer buffer too
                ptr = step % n
            for k in buf:   # a checkpoint from before ``done`` existed holds no terminal
                if k in st["buffer"]:
                    buf[k][:size] = st["buffer"][k].numpy()
            rng.bit_generator.state = _json.loads(st["np_rng"])
            gen.set_state(st["torch_gen"])
            log, seconds = _json.loads(st["log"]), st["seconds"]
        except (KeyError, TypeError, ValueError, RuntimeError) as e:
            raise ModelFileError(f"SAC checkpoint {ckpt} is inconsistent "
                                 f"({type(e).__name__}: {e}); {fix}") from None

    def save():
        atomic_torch_save({
            "format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION,
            "config": json_config(cfg), "actor": actor.state_dict(), "qf": qf.state_dict(),
            "qf_target": qf_target.state_dict(), "log_alpha": log_alpha.detach().clone(),
            "opts": [o.state_dict() for o in (q_opt, pi_opt, a_opt)],
            "buffer": {k: torch.from_numpy(v[:size].copy()) for k, v in buf.items()},
            "size": size, "ptr": ptr, "step": step, "episode": episode,
            "np_rng": _json.dumps(rng.bit_generator.state), "torch_gen": gen.get_state(),
            "log": _json.dumps(log), "seconds": seconds, "demos_sha256": demo_sha}, ckpt)

    env = _tasks.make(task)
    t_chunk = time.perf_counter()
    t_last = t_chunk
    q_hist, pi_hist, ret_hist = [], [], []
    terminal = _tasks.TERMINATIONS[cfg.terminate] if cfg.terminate else None
    while step < cfg.total_steps:
        first_step = step
        # one episode (the fixed horizon; a time limit, so every target bootstraps)
        obs = env.reset(seed=cfg.seed * 1_000_003 + episode)
        if starts is not None and rng.random() < cfg.demo_starts:
            obs = env.set_state(starts[rng.integers(len(starts))])
        ep_ret = 0.0
        for _ in range(spec.horizon):
            if step < cfg.learning_starts:
                act = rng.uniform(-1, 1, act_dim).astype(np.float32)
            else:
                with torch.no_grad():
                    a, _, _ = actor.sample(torch.as_tensor(obs, dtype=torch.float32)[None],
                                           generator=gen)
                act = a[0].numpy()
            next_obs, r, _ = env.step(act)
            ended = bool(terminal(next_obs[None])[0]) if terminal is not None else False
            buf["obs"][ptr], buf["act"][ptr], buf["rew"][ptr] = obs, act, r
            buf["next_obs"][ptr], buf["done"][ptr] = next_obs, float(ended)
            ptr, size = (ptr + 1) % n, min(size + 1, n)
            obs, ep_ret, step = next_obs, ep_ret + r, step + 1
            if step > cfg.learning_starts:
                idx = rng.integers(0, size, cfg.batch_size - n_demo)
                b = {k: torch.from_numpy(v[idx]) for k, v in buf.items()}
                if n_demo:
                    d_idx = rng.integers(0, len(demo["obs"]), n_demo)
                    b = {k: torch.cat([v, torch.from_numpy(demo[k][d_idx])]) for k, v in b.items()}
                alpha = _alpha_of(cfg, log_alpha)
                # critic: soft Bellman target from the twin targets' minimum
                with torch.no_grad():
                    na, nlogp, _ = actor.sample(b["next_obs"], generator=gen)
                    q_next = qf_target(b["next_obs"], na).min(0).values - alpha * nlogp
                    target = b["rew"] + cfg.gamma * (1 - b["done"]) * q_next
                q_loss = F.mse_loss(qf(b["obs"], b["act"]),
                                    target.expand(2, -1), reduction="none").mean(1).sum()
                q_opt.zero_grad(); q_loss.backward(); q_opt.step()
                q_hist.append(q_loss.item())
                if step % cfg.policy_frequency == 0:
                    for _ in range(cfg.policy_frequency):
                        pa, logp, _ = actor.sample(b["obs"], generator=gen)
                        pi_loss = (alpha * logp - qf(b["obs"], pa).min(0).values).mean()
                        pi_opt.zero_grad(); pi_loss.backward(); pi_opt.step()
                        pi_hist.append(pi_loss.item())
                        if cfg.autotune:
                            a_loss = -(log_alpha.exp() * (logp.detach()
                                                          + target_entropy)).mean()
                            a_opt.zero_grad(); a_loss.backward(); a_opt.step()
                            alpha = log_alpha.exp().item()
                with torch.no_grad():   # Polyak averaging of the targets
                    for p, pt in zip(qf.parameters(), qf_target.parameters()):
                        pt.lerp_(p, cfg.tau)
            if ended or step >= cfg.total_steps:
                break
        episode += 1
        ret_hist.append(ep_ret)
        # a log row (a checkpoint) when the episode crossed a multiple of log_every
        # (checkpoint_every): at every such multiple when episodes run the whole horizon
        if step // cfg.log_every > first_step // cfg.log_every:
            now = time.perf_counter()
            seconds += now - t_last
            row = {"steps": step, "train_return": float(np.mean(ret_hist)),
                   "eval_return": evaluate(task, actor, cfg.eval_episodes,
                                           10_000_000 + step),
                   "q_loss": float(np.mean(q_hist)) if q_hist else None,
                   "pi_loss": float(np.mean(pi_hist)) if pi_hist else None,
                   "alpha": _alpha_of(cfg, log_alpha),
                   "seconds": round(seconds, 1),
                   "steps_per_second": round(cfg.log_every / max(now - t_last, 1e-9), 1)}
            t_last = time.perf_counter()
            log.append(row)
            q_hist, pi_hist, ret_hist = [], [], []
            if progress:
                progress(row)
        if ckpt is not None and (step // cfg.checkpoint_every > first_step // cfg.checkpoint_every
                                 or step >= cfg.total_steps):
            save()
            if stop_after_seconds is not None and \
                    time.perf_counter() - t_chunk >= stop_after_seconds:
                break
    return {"actor": actor, "log": log, "done": step >= cfg.total_steps, "steps": step}


def json_config(cfg: SACConfig) -> dict:
    return _json.loads(_json.dumps(dataclasses.asdict(cfg)))
