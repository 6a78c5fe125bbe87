"""Typed, validated trajectory records (after the ``imitation`` library's ``types``).

A :class:`Trajectory` is one fixed-horizon episode of a task port.  It is immutable (its arrays
are read-only) and checked at construction: shapes agree with each other and with the task's
spec, dtypes are as documented, nothing is NaN or infinite.  It keeps the MuJoCo state the
episode started from, so its stored actions can be replayed to reproduce it exactly.

Subsampled demonstrations (:func:`subsample`, GAIL's benchmark protocol) keep every array of
the whole episode and say in ``Trajectory.kept`` which steps' (state, action) pairs a learner
may see: the pairs (``Demonstrations.observations``/``actions``/``mode_features``,
``bc.episodes``/``bc.pairs``) are the kept ones, while the arrays of a trajectory and
:meth:`Demonstrations.whole` stay the whole episode for code that needs it (replay, returns,
modes, an evaluation's reference), which says so where it reads them.
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
        kept: None (every pair is the learner's: an ordinary demonstration) or the sorted,
            distinct step indices in [0, T) whose (state, action) pairs a learner may see
            (:func:`subsample`); the arrays above stay the whole episode either way.
    """

    task: str
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    mode_features: np.ndarray
    initial_state: np.ndarray
    seed: int
    mode: int = 0
    kept: np.ndarray | None = None

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
        if self.kept is not None:
            k = np.asarray(self.kept)
            if not np.issubdtype(k.dtype, np.integer) or k.ndim != 1 or len(k) == 0:
                raise TrajectoryError(f"kept must be a non-empty 1-D array of step indices, "
                                      f"got dtype {k.dtype} and shape {k.shape}")
            if k[0] < 0 or k[-1] >= T or np.any(np.diff(k) <= 0):
                raise TrajectoryError(f"kept must hold increasing, distinct step indices in "
                                      f"[0, {T}), got {k[:5].tolist()}...{k[-2:].tolist()}")
            set_("kept", _frozen("kept", k.astype(np.int64), np.int64, 1))

    def __len__(self) -> int:
        return len(self.actions)

    @property
    def ret(self) -> float:
        """The episode's return (sum of rewards; of the whole episode, kept or not)."""
        return float(self.rewards.sum())

    @property
    def subsampled(self) -> bool:
        """Whether a learner may see only some of the episode's pairs (``kept``)."""
        return self.kept is not None

    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """``(states, actions)`` a learner may see: every step's, or the kept steps' only.
        The last observation, which no action follows, is never among them."""
        obs, act = self.observations[:-1], self.actions
        if self.kept is None:
            return obs, act
        return obs[self.kept], act[self.kept]

    def whole(self) -> "Trajectory":
        """The same episode with every pair a learner's (``kept`` dropped)."""
        return self if self.kept is None else dataclasses.replace(self, kept=None)


@dataclasses.dataclass(frozen=True)
class Demonstrations:
    """A task's expert demonstrations: validated trajectories plus their manifest entry.

    ``observations``, ``actions`` and ``mode_features`` are those of the (state, action) pairs
    a learner may see: of subsampled demonstrations (:func:`subsample`) the kept steps only.
    :meth:`whole` gives every step, for code that needs the whole episodes."""

    task: str
    trajectories: tuple[Trajectory, ...]
    manifest: dict

    def __len__(self) -> int:
        return len(self.trajectories)

    @property
    def observations(self) -> np.ndarray:
        """All states the expert visited, (N * T, obs_dim): the last state of each episode,
        which no action follows, is left out so that states and actions pair up (of
        subsampled demonstrations, the kept steps' states only)."""
        return np.concatenate([t.pairs()[0] for t in self.trajectories])

    @property
    def actions(self) -> np.ndarray:
        return np.concatenate([t.pairs()[1] for t in self.trajectories])

    @property
    def mode_features(self) -> np.ndarray:
        return np.concatenate([_kept_rows(t, t.mode_features[:-1]) for t in self.trajectories])

    @property
    def subsampled(self) -> bool:
        """Whether any demonstration shows a learner only some of its pairs."""
        return any(t.subsampled for t in self.trajectories)

    def whole(self) -> "Demonstrations":
        """These demonstrations with every pair of every episode (``self`` if none is
        subsampled): what an evaluation's reference or a replay reads."""
        if not self.subsampled:
            return self
        manifest = {k: v for k, v in self.manifest.items() if k != "subsample"}
        return Demonstrations(self.task, tuple(t.whole() for t in self.trajectories), manifest)

    @property
    def returns(self) -> np.ndarray:
        return np.array([t.ret for t in self.trajectories])

    @property
    def modes(self) -> np.ndarray:
        return np.array([t.mode for t in self.trajectories])


def _kept_rows(t: Trajectory, rows: np.ndarray) -> np.ndarray:
    return rows if t.kept is None else rows[t.kept]


def subsample(demos: Demonstrations, every: int = 20, seed: int = 0) -> Demonstrations:
    """GAIL's benchmark protocol (Ho and Ermon 2016, section 6): each demonstration keeps
    every ``every``-th (state, action) pair, from an offset drawn at random in ``[0, every)``.

    The offsets are drawn one per demonstration, in order, from one NumPy generator seeded
    with ``seed`` (``default_rng(seed).integers(every)`` per trajectory): the same seed gives
    the same pairs, and the first k demonstrations get the same offsets whatever the number
    that follows, so nested subsets (the first n demonstrations) are subsampled alike.
    Demonstration i keeps steps ``offset_i, offset_i + every, ...`` below its length T (about
    T / every pairs; a 1,000-step episode keeps 50).

    The trajectories stay whole and carry the kept step indices (``Trajectory.kept``); what a
    learner reads as pairs (``bc.pairs``, ``bc.episodes``, ``demos.observations``) is the kept
    pairs only, and :meth:`Demonstrations.whole` undoes it.  The manifest gains
    ``"subsample": {"every": every, "seed": seed}``.  Demonstrations subsampled already are
    refused (a subsample of a subsample is not the protocol)."""
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise ValueError(f"subsample: every must be a whole number >= 1, got {every!r}")
    if demos.subsampled:
        raise ValueError(f"subsample: these {demos.task} demonstrations are subsampled already "
                         f"({demos.manifest.get('subsample')}); subsample the whole ones "
                         f"(demos.whole())")
    rng = np.random.default_rng(seed)
    out = []
    for t in demos.trajectories:
        offset = int(rng.integers(every))
        if offset >= len(t):
            raise ValueError(f"subsample: a {len(t)}-step demonstration has no step at "
                             f"offset {offset}; choose every <= {len(t)}")
        out.append(dataclasses.replace(t, kept=np.arange(offset, len(t), every)))
    return Demonstrations(demos.task, tuple(out),
                          {**demos.manifest, "subsample": {"every": int(every),
                                                           "seed": int(seed)}})


__all__ = ["Demonstrations", "Trajectory", "TrajectoryError", "subsample"]
