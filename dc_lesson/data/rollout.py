"""Collecting episodes from a policy into :class:`~dc_lesson.data.Trajectory` records.

A *policy* is either a callable mapping a batch of observations, shape (B, obs_dim) float32, to
a batch of actions (B, act_dim), or a ``torch.nn.Module`` (called under ``no_grad`` on a float32
tensor; if it has an ``act`` method, that is called instead of ``forward``).  Episodes are run
``batch`` at a time in lockstep, so a network policy is evaluated once per time step for the
whole batch rather than once per environment.

A policy with memory or with a per-episode choice (an expert that picks a target by a coin
flip, say) may define ``reset(seeds)``: :func:`collect` calls it with the batch's episode seeds
(an int64 array) before the first step of every batch, so its choices are a deterministic
function of the episode seed.

A policy that plans on the simulator (``dc_lesson.experts.planner``) may define
``attach(venv)``: :func:`collect` hands it the running environments before the first batch;
it reads their physics states and never changes them.

Seeds: episode ``i`` of ``collect(..., seed=s)`` starts from the task's initial-state
distribution seeded with ``episode_seeds(s, n)[i]``, so the same call gives the same episodes,
and the first k episodes of a longer call are the same as those of a shorter one.
"""

from __future__ import annotations

import numbers
from typing import Callable, Union

import numpy as np

from dc_lesson import tasks as _tasks
from dc_lesson.data.types import Trajectory

Policy = Union[Callable[[np.ndarray], np.ndarray], "torch.nn.Module"]  # noqa: F821


def episode_seeds(seed: int, n: int) -> np.ndarray:
    """``n`` well-separated 32-bit seeds derived from one seed (NumPy's SeedSequence)."""
    return np.random.SeedSequence(int(seed)).generate_state(n).astype(np.int64)


class RandomPolicy:
    """Uniformly random actions in the task's bounds.

    Each episode draws from its own generator, seeded by the policy's ``seed`` and the episode
    seed (through ``reset``), so an episode's actions do not depend on which other episodes
    run beside it.  Called without ``reset`` it uses one generator seeded by ``seed``.
    """

    def __init__(self, task: str, seed: int = 0):
        self.spec = _tasks.spec(task)
        self.seed = int(seed)
        self.rng = np.random.default_rng(self.seed)
        self.plan = None   # (B, horizon, act_dim) actions drawn at reset, one row per episode
        self.t = 0

    def reset(self, seeds) -> None:
        shape = (self.spec.horizon, self.spec.act_dim)
        self.plan = np.stack([np.random.default_rng([self.seed, int(s) % 2**63])
                              .uniform(-1, 1, shape) for s in seeds])
        self.t = 0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        n = len(obs)
        if self.plan is not None and len(self.plan) == n and self.t < self.spec.horizon:
            self.t += 1
            return self.plan[:, self.t - 1]
        return self.rng.uniform(-1, 1, size=(n, self.spec.act_dim))


def as_batch_policy(policy: Policy) -> Callable[[np.ndarray], np.ndarray]:
    """Wraps a torch module as a numpy batch policy; returns other callables unchanged."""
    try:
        import torch
    except ImportError:  # pragma: no cover - torch is a dependency
        return policy
    if not isinstance(policy, torch.nn.Module):
        return policy
    module = policy
    if hasattr(module, "act_numpy"):   # a policy with its own NumPy path (nn.GaussianPolicy)
        return module.act_numpy
    call = getattr(module, "act", module)

    def numpy_policy(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            out = call(torch.as_tensor(obs, dtype=torch.float32))
        return out.detach().cpu().numpy()
    return numpy_policy


class PolicyMismatchError(ValueError):
    """A policy built for another task (other observation or action sizes)."""


def _policy_dims(policy, depth: int = 0):
    """(obs_dim, act_dim, task or None) of ``policy`` or of the network it wraps, or None.

    Reads a network's ``config()`` (GaussianPolicy), a task-bound policy's ``spec`` (random,
    planner), and looks through the wrappers the library makes (``policy``, ``net``,
    ``experts``)."""
    if depth > 4:
        return None
    spec = getattr(policy, "spec", None)
    if isinstance(spec, _tasks.TaskSpec):
        return spec.obs_dim, spec.act_dim, spec.name
    config = getattr(policy, "config", None)
    if callable(config):
        try:
            cfg = config()
        except Exception:   # another object's config(): not ours to judge
            cfg = None
        if isinstance(cfg, dict) and "obs_dim" in cfg and "act_dim" in cfg:
            return int(cfg["obs_dim"]), int(cfg["act_dim"]), None
    for inner in ("policy", "net"):
        if getattr(policy, inner, None) is not None and getattr(policy, inner) is not policy:
            dims = _policy_dims(getattr(policy, inner), depth + 1)
            if dims is not None:
                return dims
    for inner in getattr(policy, "experts", None) or ():
        dims = _policy_dims(inner, depth + 1)
        if dims is not None:
            return dims
    return None


def check_policy(task: str, policy) -> None:
    """Refuses, before any episode runs, a policy whose observation or action size is not
    ``task``'s (a policy trained on another task); a plain function passes (its actions'
    shape is checked at the first step)."""
    spec = _tasks.spec(task)
    dims = _policy_dims(policy)
    if dims is None:
        return
    obs_dim, act_dim, its_task = dims
    if its_task is not None and its_task != spec.name:
        raise PolicyMismatchError(f"the policy acts in {its_task!r}, not {task!r}: make it "
                                  f"for {task!r}")
    if (obs_dim, act_dim) != (spec.obs_dim, spec.act_dim):
        raise PolicyMismatchError(
            f"the policy is built for observations of size {obs_dim} and actions of size "
            f"{act_dim}; {task} has {spec.obs_dim} and {spec.act_dim}: use a policy trained "
            f"on {task} (see dc_lesson.tasks.spec_table() for each task's sizes)")


def trajectory_mode(task: _tasks.PortTask, mode_features: np.ndarray) -> int:
    """The mode an episode took: where it arrived and stayed (``task.episode_mode``), or
    ``tasks.NO_MODE`` (-1) when it reached none."""
    return int(task.episode_mode(mode_features))


def collect(task: str, policy: Policy, n_episodes: int, seed: int = 0, *,
            batch: int = 16, max_steps: int | None = None,
            progress: bool | None = None, venv=None, first: int = 0) -> list[Trajectory]:
    """Runs ``n_episodes`` episodes of ``policy`` on ``task``.

    Args:
        task: a task name (see ``dc_lesson.tasks.NAMES``).
        policy: a batch policy (see the module docstring).
        n_episodes: how many episodes.
        seed: decides the episodes' initial states (see :func:`episode_seeds`).
        batch: how many environments run in lockstep.
        max_steps: stop episodes early (for quick looks; the horizon by default).
        progress: show a progress bar (default: when the run is longer than a few seconds).
        venv: a :class:`~dc_lesson.tasks.VecEnv` of ``task`` to reuse (its size is the batch);
            algorithms that collect every iteration keep one instead of building it each time.
        first: skip the first ``first`` episodes of the seed's sequence (to continue an
            interrupted collection: ``first=k`` gives episodes k, k+1, ... of ``seed``).
    """
    spec = _tasks.spec(task)
    if isinstance(n_episodes, bool) or not isinstance(n_episodes, numbers.Integral) \
            or n_episodes < 1:
        raise ValueError(f"n_episodes must be a whole number of at least 1, got "
                         f"{n_episodes!r}")
    check_policy(task, policy)
    T = spec.horizon if max_steps is None else min(int(max_steps), spec.horizon)
    act = as_batch_policy(policy)
    seeds = episode_seeds(seed, first + n_episodes)[first:]
    if venv is None:
        venv = _tasks.load_vec(task, max(1, min(batch, n_episodes)))
    elif venv.spec.name != task:
        raise ValueError(f"venv runs {venv.spec.name!r}, not {task!r}")
    if progress is None:
        progress = n_episodes * T * spec.n_sub_steps > 200_000
    bar = None
    if progress:
        from dc_lesson import progress as _progress
        bar = _progress.bar(total=n_episodes * T, desc=f"{task} rollouts", unit="step", leave=False)

    if hasattr(policy, "attach"):
        policy.attach(venv)
    out: list[Trajectory] = []
    for start in range(0, n_episodes, venv.n_envs):
        chunk = seeds[start:start + venv.n_envs]
        B = len(chunk)
        obs = np.zeros((B, T + 1, spec.obs_dim), np.float32)
        acts = np.zeros((B, T, spec.act_dim), np.float32)
        rews = np.zeros((B, T), np.float64)
        feats = np.zeros((B, T + 1, spec.mode_dim), np.float32)
        if hasattr(policy, "reset"):
            policy.reset(np.asarray(chunk))
        obs[:, 0], feats[:, 0] = venv.reset(chunk)
        states = venv.get_states()
        for t in range(T):
            a = np.asarray(act(obs[:, t]), dtype=np.float64)
            if a.size != B * spec.act_dim:
                raise PolicyMismatchError(f"the policy returned actions of shape {a.shape} for "
                                          f"{B} observations; {task} needs ({B}, "
                                          f"{spec.act_dim})")
            a = a.reshape(B, spec.act_dim)
            # Round to float32 before applying, so the stored action replays exactly.
            acts[:, t] = venv.check_actions(a)
            obs[:, t + 1], rews[:, t], feats[:, t + 1], _ = venv.step(acts[:, t], checked=True)
            if bar is not None:
                bar.update(B)
        for b in range(B):
            out.append(Trajectory(task=task, observations=obs[b], actions=acts[b],
                                  rewards=rews[b], mode_features=feats[b],
                                  initial_state=states[b], seed=int(chunk[b]),
                                  mode=trajectory_mode(venv.task, feats[b])))
    if bar is not None:
        bar.close()
    return out


def returns(trajectories: list[Trajectory]) -> np.ndarray:
    return np.array([t.ret for t in trajectories])


def replay(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Replays a trajectory's actions from its initial state: (observations, rewards)."""
    env = _tasks.make(traj.task)
    env.reset(seed=traj.seed)
    obs = [env.set_state(traj.initial_state)]
    rews = []
    for a in traj.actions:
        o, r, _ = env.step(a)
        obs.append(o)
        rews.append(r)
    return np.stack(obs), np.array(rews)
