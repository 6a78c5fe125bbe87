"""Typed, validated trajectory records (after the ``imitation`` library's ``types``).

A :class:`Trajectory` is one fixed-horizon episode of a task port.  It is immutable (its arrays
are read-only) and checked at construction: shapes agree with each other and with the task's
spec, dtypes are as documented, nothing is NaN or infinite.  It keeps the MuJoCo state the
episode started from, so its stored actions can be replayed to reproduce it exactly.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dc_lesson import tasks as _tasks


class TrajectoryError(ValueError):
    """A trajectory whose arrays are inconsistent, of the wrong type, or not finite."""


def _frozen(name: str, x, dtype, ndim: int) -> np.ndarray:
    a = np.asarray(x)
    if a.dtype != dtype:
        raise TrajectoryError(f"{name} must have dtype {np.dtype(dtype).name}, got {a.dtype}")
    if a.ndim != ndim:
        raise TrajectoryError(f"{name} must have {ndim} dimensions, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise TrajectoryError(f"{name} contains NaN or inf")
    a = a.copy()
    a.setflags(write=False)
    return a


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """One episode: T steps, T+1 observations (the last is the state after the last action).

    Attributes:
        task: the task port's name.
        observations: (T+1, obs_dim) float32.
        actions: (T, act_dim) float32, the actions applied (clipped to the bounds).
        rewards: (T,) float64, the task's reward after each action.
        mode_features: (T+1, k) float32, the task's mode feature at each observation.
        initial_state: (S,) float64, MuJoCo's integration state at the start.
        seed: the seed the episode's initial state was drawn with.
        mode: index of the behaviour mode the episode took (0 for single-mode tasks;
            ``tasks.NO_MODE`` = -1 for an episode of a multi-mode task that reached none).
    """

    task: str
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    mode_features: np.ndarray
    initial_state: np.ndarray
    seed: int
    mode: int = 0

    def __post_init__(self):
        spec = _tasks.spec(self.task)
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 - frozen dataclass
        set_("observations", _frozen("observations", self.observations, np.float32, 2))
        set_("actions", _frozen("actions", self.actions, np.float32, 2))
        set_("rewards", _frozen("rewards", self.rewards, np.float64, 1))
        set_("mode_features", _frozen("mode_features", self.mode_features, np.float32, 2))
        set_("initial_state", _frozen("initial_state", self.initial_state, np.float64, 1))
        T = len(self.actions)
        expect = {"observations": (T + 1, spec.obs_dim), "actions": (T, spec.act_dim),
                  "rewards": (T,), "mode_features": (T + 1, spec.mode_dim)}
        for name, shape in expect.items():
            got = getattr(self, name).shape
            if got != shape:
                raise TrajectoryError(
                    f"{name} of a {self.task} trajectory with {T} actions must have shape "
                    f"{shape}, got {got}")
        if T == 0:
            raise TrajectoryError("a trajectory needs at least one action")
        n_modes = max(1, len(spec.modes))
        lowest = _tasks.NO_MODE if spec.multimodal else 0   # -1: arrived at no mode
        if not lowest <= int(self.mode) < n_modes:
            raise TrajectoryError(f"mode {self.mode} out of range for {self.task} "
                                  f"({n_modes} modes, or {_tasks.NO_MODE} for none)")

    def __len__(self) -> int:
        return len(self.actions)

    @property
    def ret(self) -> float:
        """The episode's return (sum of rewards)."""
        return float(self.rewards.sum())


@dataclasses.dataclass(frozen=True)
class Demonstrations:
    """A task's expert demonstrations: validated trajectories plus their manifest entry."""

    task: str
    trajectories: tuple[Trajectory, ...]
    manifest: dict

    def __len__(self) -> int:
        return len(self.trajectories)

    @property
    def observations(self) -> np.ndarray:
        """All states the expert visited, (N * T, obs_dim): the last state of each episode,
        which no action follows, is left out so that states and actions pair up."""
        return np.concatenate([t.observations[:-1] for t in self.trajectories])

    @property
    def actions(self) -> np.ndarray:
        return np.concatenate([t.actions for t in self.trajectories])

    @property
    def mode_features(self) -> np.ndarray:
        return np.concatenate([t.mode_features[:-1] for t in self.trajectories])

    @property
    def returns(self) -> np.ndarray:
        return np.array([t.ret for t in self.trajectories])

    @property
    def modes(self) -> np.ndarray:
        return np.array([t.mode for t in self.trajectories])


__all__ = ["Demonstrations", "Trajectory", "TrajectoryError"]
