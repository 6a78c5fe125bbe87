"""The environments an RL learner steps: ``n_envs`` copies of one task in lockstep
(:class:`EnvBatch`), the stream of episode seeds they restart from (:class:`SeedStream`), and
the training-only terminations (:data:`TERMINATIONS`, the hopper's fall).

Every RL learner of the library (PPO and those built on its loop: GAIL, DRIL, PWIL, NDI, DC,
GPRIL) collects through :class:`EnvBatch`, so an episode's start, its cut at the horizon, a
training-only termination and a checkpoint's replay are written once, here.  The names stay
importable from :mod:`dc_lesson.algorithms.ppo`, where they were first written.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import torch

from dc_lesson import tasks as _tasks
from dc_lesson.data.rollout import episode_seeds


TERMINATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = _tasks.TERMINATIONS
"""Training-only terminal tests by name: ``fn(observations (N, obs_dim)) -> (N,) bool``, True
where a training episode ends in a terminal state (see the module docstring); the task ports
define them (``tasks.TERMINATIONS``: the hopper's fall)."""


def termination(name: str | None):
    if name is None:
        return None
    if name not in TERMINATIONS:
        raise ValueError(f"unknown termination {name!r}; known: {', '.join(TERMINATIONS)}")
    return TERMINATIONS[name]


class SeedStream:
    """Episode seeds one after another: the i-th is ``episode_seeds(seed, i + 1)[i]``."""

    def __init__(self, seed: int, count: int = 0):
        self.seed, self.count = int(seed), int(count)
        self._cache = np.zeros(0, np.int64)

    def __next__(self) -> int:
        if self.count >= len(self._cache):   # a longer call extends a shorter one's seeds
            self._cache = episode_seeds(self.seed, max(64, 2 * len(self._cache), self.count + 1))
        self.count += 1
        return int(self._cache[self.count - 1])


class EnvBatch:
    """``n_envs`` copies of one task stepped in lockstep (a :class:`~dc_lesson.tasks.VecEnv`).

    ``obs`` holds the observations to act on next.  All copies share the fixed horizon, so
    their episodes end together; then every copy restarts with the next seeds of the stream.
    The running episodes' seeds and actions are kept, so a checkpoint can restore the copies by
    replaying them.
    """

    def __init__(self, task: str, n_envs: int, seed: int, episode_steps: int | None = None,
                 terminate: str | None = None):
        self.task = task
        self.terminate = terminate
        self._terminal_fn = termination(terminate)
        self.last_terminal = np.zeros(n_envs, bool)   # which copies the last step ended
        self.venv = _tasks.load_vec(task, n_envs)
        self.spec = self.venv.spec
        self.episode_steps = min(episode_steps or self.spec.horizon, self.spec.horizon)
        self.seeds = SeedStream(seed)
        self.obs = self._start([next(self.seeds) for _ in range(n_envs)])

    def __len__(self) -> int:
        return self.venv.n_envs

    def _start(self, seeds) -> np.ndarray:
        self.episode_seeds = np.asarray(seeds, np.int64)
        self.episode_actions: list[np.ndarray] = []   # one (n_envs, act_dim) array per step
        self.restarts: list[tuple[int, int, int]] = []   # (step, copy, seed) of terminations
        self.restarted = np.zeros(len(seeds), bool)      # copies restarted in this episode
        self.episode_return = np.zeros(len(self))
        obs, _ = self.venv.reset(self.episode_seeds)
        return obs

    def step(self, actions: np.ndarray):
        """One action per copy, clipped to the bounds.

        Returns ``(next_obs, rewards, dones, finished)``: the observations the actions led to
        (at the episodes' end, their final observations, not the reset ones), the rewards,
        which episodes ended, and the returns of the episodes that ended.  With a training-only
        termination, a copy whose next observation is terminal ends (``dones`` and
        ``last_terminal`` True) and restarts alone with the next seed; the episode it then
        starts is cut at the shared time limit, and its return is left out of ``finished``
        (so ``finished`` holds returns of episodes that ran from a start to a fall or to the
        horizon: what the task pays, as a fallen hopper earns nothing more).
        """
        actions = self.venv.check_actions(actions)
        next_obs, rewards, _, done = self.venv.step(actions, checked=True)
        done = done or self.venv.t >= self.episode_steps
        self.episode_actions.append(actions)
        self.episode_return += rewards
        terminal = (np.zeros(len(self), bool) if self._terminal_fn is None else
                    np.asarray(self._terminal_fn(next_obs), bool).reshape(len(self)))
        self.last_terminal = terminal
        finished = []
        if done:
            # A copy restarted after a termination was cut short by the shared time limit:
            # its return is not an episode's (nor is it reported).
            finished = self.episode_return[~(self.restarted & ~terminal)].tolist()
            self.obs = self._start([next(self.seeds) for _ in range(len(self))])
        else:
            self.obs = next_obs.copy()
            for i in np.flatnonzero(terminal):
                finished.append(float(self.episode_return[i]))
                self._restart(int(i), next(self.seeds))
        return next_obs, rewards, done | terminal, finished

    def _restart(self, i: int, seed: int) -> None:
        """A terminated copy starts a new episode at once (training-only termination)."""
        self.restarts.append((len(self.episode_actions), i, seed))
        self.restarted[i] = True
        self.obs[i] = self.venv.reset_one(i, seed)
        self.episode_return[i] = 0.0

    def state_dict(self) -> dict:
        actions = np.zeros((0, len(self), self.spec.act_dim))
        if self.episode_actions:
            actions = np.stack(self.episode_actions)
        return {"seed": self.seeds.seed, "seed_count": self.seeds.count,
                "episode_seeds": torch.from_numpy(self.episode_seeds.copy()),
                "episode_actions": torch.from_numpy(actions),
                "restarts": torch.tensor(self.restarts, dtype=torch.int64).reshape(-1, 3),
                "obs": torch.from_numpy(np.array(self.obs)),
                "episode_return": torch.from_numpy(self.episode_return.copy())}

    def load_state_dict(self, state: dict) -> None:
        """Restores the copies by replaying the running episodes from their seeds.

        Replaying is exact for any task (MuJoCo is deterministic) and also restores what a
        task sets at reset outside the simulation state (a reacher's target, say).
        """
        if len(state["episode_seeds"]) != len(self):
            raise ValueError(f"the saved state has {len(state['episode_seeds'])} environments, "
                             f"this batch {len(self)}")
        self.obs = self._start(state["episode_seeds"].numpy())
        restarts = [tuple(int(x) for x in r) for r in state.get("restarts", torch.zeros(0, 3))]
        for actions in state["episode_actions"].numpy():
            obs, rewards, _, _ = self.venv.step(actions)
            self.obs = obs.copy()
            self.episode_actions.append(actions)
            self.episode_return += rewards
            for step, i, seed in restarts:
                if step == len(self.episode_actions):
                    self._restart(i, seed)
        self.seeds = SeedStream(state["seed"], state["seed_count"])
        if "episode_return" in state and not np.allclose(self.episode_return,
                                                         state["episode_return"].numpy()):
            raise RuntimeError("replaying the saved episodes did not reproduce their returns")
        if not np.array_equal(self.obs, state["obs"].numpy()):
            raise RuntimeError("replaying the saved episodes did not reproduce the saved "
                               "observations (a different MuJoCo version or task code?)")


__all__ = ["EnvBatch", "SeedStream", "TERMINATIONS", "termination"]
