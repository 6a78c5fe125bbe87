"""Scripted experts: hand-designed controllers for ``cartpole`` and the reachers (no learning).

They follow the batch-policy protocol of :mod:`dc_lesson.data.rollout`: called with observations of
shape (B, obs_dim), they return actions of shape (B, act_dim) in [-1, 1], and a policy with a
per-episode choice defines ``reset(seeds)``, which :func:`~dc_lesson.data.rollout.collect` calls
with the batch's episode seeds before the first step.

:class:`CartpoleLQR`
    The pole starts within two degrees of upright and only has to be kept there, so the
    dynamics linearised around the upright rest state describe the whole episode well, and a
    linear-quadratic regulator is the textbook answer: it is optimal for a quadratic cost on a
    linear system and needs no tuning beyond the cost.  The linearisation is taken from MuJoCo
    itself (finite differences of one control step of the task's own model, around upright,
    at rest, zero force), and the cost is the second-order expansion of the task's reward
    (upright, centred, small pole velocity, small force), so the regulator maximises the reward
    near upright.  It is deterministic and has no memory.

:class:`ReacherExpert`
    The arm has two joints and the fingertip lives in the plane, so for a chosen target the
    joint angles that put the fingertip on it follow in closed form from the law of cosines
    (two-link inverse kinematics).  There are two solutions, elbow bent either way; the expert
    takes one the wrist's joint range allows and, of those, the one nearest to the arm's
    configuration at the start of the episode, then drives both joints there with a PD
    controller (a torque from the angle error, minus a damping term that stops the arm
    overshooting) and holds still on the target for the rest of the episode.

    Which target an episode goes to (its behaviour *mode*) is decided once, at the start:

    * ``mode_choice="coin"`` (the default): a fair K-sided coin seeded by the episode seed.  The
      choice is independent of the initial state, so no deterministic function of the
      observation can reproduce the expert's mode shares; only a learner whose policy can commit
      to a mode *stochastically* (and then stick to it) can match the expert's distribution.
    * ``mode_choice="nearest"``: the target nearest to the fingertip at the first step.  The mode
      is then a deterministic function of the initial state, so a deterministic learner can in
      principle match it, though the map has sharp boundaries between modes.

    ``expert.chosen`` holds the chosen target index of every batch row of the current episodes.

:func:`expert_for` returns the default scripted expert of a task.
"""

from __future__ import annotations

import mujoco
import numpy as np

from dc_lesson import tasks
from dc_lesson.tasks import reacher as _reacher

SCRIPTED_TASKS = ("cartpole", "reacher1", "reacher2", "reacher4")


def wrap_angle(a):
    """Angles mapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _as_batch(obs, obs_dim: int, who: str) -> np.ndarray:
    obs = np.asarray(obs, dtype=np.float64)
    if obs.ndim != 2 or obs.shape[1] != obs_dim:
        raise ValueError(f"{who} takes a batch of observations of shape (B, {obs_dim}), "
                         f"got shape {obs.shape}")
    return obs


# --------------------------------------------------------------------------------------------
# cartpole: LQR around upright
# --------------------------------------------------------------------------------------------

def _control_step(model, data, state: np.ndarray, ctrl: np.ndarray, n_sub_steps: int):
    """MuJoCo state (qpos, qvel) after one control step from ``state`` with ``ctrl`` held."""
    mujoco.mj_resetData(model, data)   # also clears warm starts, so every call is the same
    data.qpos[:] = state[:model.nq]
    data.qvel[:] = state[model.nq:]
    data.ctrl[:] = ctrl
    mujoco.mj_step(model, data, n_sub_steps)
    return np.concatenate([data.qpos, data.qvel])


def linearise(env: tasks.TaskEnv, eps: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Discrete-time ``(A, B)`` of one control step around qpos = qvel = ctrl = 0.

    The state is MuJoCo's ``(qpos, qvel)`` (cart position, pole angle, their velocities).
    Central finite differences of ``mj_step`` on the task's own model and integrator (RK4 for
    cartpole, which ``mujoco.mjd_transitionFD`` does not support).
    """
    model = env.physics.model.ptr
    if model.nq != model.nv or model.na != 0:   # pragma: no cover - true of cartpole
        raise ValueError("linearise handles models with hinge and slide joints only")
    data = mujoco.MjData(model)      # a private data, so the environment's state is untouched
    nx, nu = model.nq + model.nv, model.nu
    x0, u0 = np.zeros(nx), np.zeros(nu)   # upright, at rest, no force

    def step(x, u):
        return _control_step(model, data, x, u, env.n_sub_steps)

    A = np.stack([(step(x0 + eps * e, u0) - step(x0 - eps * e, u0)) / (2 * eps)
                  for e in np.eye(nx)], axis=1)
    B = np.stack([(step(x0, u0 + eps * e) - step(x0, u0 - eps * e)) / (2 * eps)
                  for e in np.eye(nu)], axis=1)
    return A, B


def solve_dlqr(A, B, Q, R, tol: float = 1e-12, max_iter: int = 100_000) -> np.ndarray:
    """The gain ``K`` of the infinite-horizon discrete LQR, so that ``u = -K x``."""
    try:
        from scipy.linalg import solve_discrete_are
        P = solve_discrete_are(A, B, Q, R)
    except ImportError:  # pragma: no cover - scipy comes with dm_control's dependencies
        P = Q.copy()     # iterate the Riccati equation to its fixed point
        for _ in range(max_iter):
            K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
            P_next = Q + A.T @ P @ (A - B @ K)
            if np.max(np.abs(P_next - P)) < tol * max(1.0, np.max(np.abs(P))):
                P = P_next
                break
            P = P_next
        else:
            raise RuntimeError("the Riccati iteration did not converge")
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)


# The reward is upright * centred * small_control * small_velocity; to second order around
# upright and at rest that is 1 - x^T Q x - R u^2 with these weights on (cart position, pole
# angle, cart velocity, pole velocity) and on the force:
#   upright  (cos(angle) + 1) / 2                  -> angle^2 / 4
#   centred  (1 + gaussian(x, margin 2)) / 2       -> ln(10) / 8 * x^2
#   velocity (1 + gaussian(angle', margin 5)) / 2  -> ln(10) / 50 * angle'^2
#   control  (4 + 1 - u^2) / 5                     -> u^2 / 5
# The reward ignores the cart's velocity; a tiny weight keeps Q positive definite.
CARTPOLE_Q = np.diag([np.log(10) / 8, 0.25, 1e-4, np.log(10) / 50])
CARTPOLE_R = np.array([[0.2]])


class CartpoleLQR:
    """Linear-quadratic regulator keeping the pole upright and the cart centred."""

    def __init__(self, Q=CARTPOLE_Q, R=CARTPOLE_R):
        env = tasks.make("cartpole")
        self.A, self.B = linearise(env)
        self.K = solve_dlqr(self.A, self.B, np.asarray(Q, float), np.asarray(R, float))

    @staticmethod
    def state(obs: np.ndarray) -> np.ndarray:
        """(B, 4) MuJoCo states (cart pos, pole angle, cart vel, pole vel) from observations
        (cart pos, cos angle, sin angle, cart vel, pole vel)."""
        angle = np.arctan2(obs[:, 2], obs[:, 1])
        return np.stack([obs[:, 0], angle, obs[:, 3], obs[:, 4]], axis=1)

    def __call__(self, obs) -> np.ndarray:
        x = self.state(_as_batch(obs, 5, "CartpoleLQR"))
        # The force saturates at |u| = 1; near upright the LQR asks for far less than that.
        return np.clip(-x @ self.K.T, -1.0, 1.0)


# --------------------------------------------------------------------------------------------
# reachers: inverse kinematics + PD, one target per episode
# --------------------------------------------------------------------------------------------

MODE_CHOICES = ("coin", "nearest")
_COIN_STREAM = 12345   # second seed word: the coin's stream differs from the initial state's


def arm_geometry(physics) -> tuple[float, float, float]:
    """(shoulder-to-wrist length, wrist-to-fingertip length, wrist limit in radians)."""
    body_pos = physics.named.model.body_pos
    upper = float(np.linalg.norm(body_pos["hand", :2]))     # the hand body sits at the wrist
    fore = float(np.linalg.norm(body_pos["finger", :2]))    # the finger body is the fingertip
    wrist_limit = float(physics.named.model.jnt_range["wrist", 1])
    return upper, fore, wrist_limit


def two_link_ik(xy, upper: float, fore: float) -> np.ndarray:
    """Both (shoulder, wrist) solutions putting the fingertip at ``xy``: (2, 2), one per row.

    The wrist angle follows from the law of cosines on the triangle shoulder-wrist-fingertip;
    the shoulder angle is the direction to the point minus the angle the bent forearm adds.
    """
    x, y = float(xy[0]), float(xy[1])
    cos_wrist = (x * x + y * y - upper**2 - fore**2) / (2 * upper * fore)
    if abs(cos_wrist) > 1:
        raise ValueError(f"point {xy} is out of the arm's reach")
    wrist = np.arccos(cos_wrist) * np.array([1.0, -1.0])
    shoulder = np.arctan2(y, x) - np.arctan2(fore * np.sin(wrist), upper + fore * np.cos(wrist))
    return np.stack([wrap_angle(shoulder), wrist], axis=1)


def joint_distance(q_from: np.ndarray, q_to: np.ndarray) -> np.ndarray:
    """How far apart two arm configurations are, as the larger of the two joint moves.

    Both joints move at once and have about the same top speed (full torque against the joint
    damping, 0.05 / 0.01 = 5 rad/s), so the larger move sets the time to get there.  The
    shoulder turns freely, so its move is the shorter way round.
    """
    d = np.asarray(q_to) - np.asarray(q_from)
    return np.maximum(np.abs(wrap_angle(d[..., 0])), np.abs(d[..., 1]))


def joint_goal(target_xy, q_now, upper: float, fore: float, wrist_limit: float) -> np.ndarray:
    """The IK solution for ``target_xy`` that the wrist can reach and is nearest to ``q_now``."""
    solutions = two_link_ik(target_xy, upper, fore)
    solutions = solutions[np.abs(solutions[:, 1]) <= wrist_limit]
    if len(solutions) == 0:
        raise ValueError(f"target {target_xy} needs a wrist angle beyond +-{wrist_limit} rad")
    return solutions[np.argmin(joint_distance(q_now, solutions))]


def coin_flip_targets(seeds, n_targets: int) -> np.ndarray:
    """One uniformly random target index per episode seed, a deterministic function of it."""
    return np.array([np.random.default_rng([int(s) % 2**64, _COIN_STREAM]).integers(n_targets)
                     for s in np.ravel(seeds)], dtype=np.int64)


def nearest_targets(fingertips: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Index of the target nearest to each fingertip position."""
    dist = np.linalg.norm(fingertips[:, None, :] - targets[None, :, :], axis=-1)
    return np.argmin(dist, axis=1)


def pd_action(q, qdot, goal, kp, kd) -> np.ndarray:
    """PD torque commands (B, 2) in [-1, 1] driving joint angles ``q`` to ``goal``."""
    err = np.asarray(goal) - np.asarray(q)
    err[:, 0] = wrap_angle(err[:, 0])   # the shoulder turns freely: go the shorter way round
    return np.clip(kp * err - kd * np.asarray(qdot), -1.0, 1.0)


class ReacherExpert:
    """Reach one of the K targets of ``reacher{K}`` and hold still on it.

    Args:
        n_targets: K, the task's number of targets (1, 2 or 4).
        mode_choice: ``"coin"`` (target drawn uniformly per episode from the episode seed) or
            ``"nearest"`` (target nearest to the fingertip at the first step).
        kp, kd: PD gains per joint (shoulder, wrist), in action units per radian and per rad/s.

    Attributes:
        targets: (K, 2) target positions.
        chosen: (B,) target index of each batch row of the current episodes, or ``None`` before
            it is decided (after ``reset`` with ``"nearest"``, until the first call).
        goal_q: (B, 2) the joint angles each row is driven to, or ``None`` before the first call.
    """

    # The arm is damping-dominated (full torque against the joint damping gives 5 rad/s within
    # a fraction of a second), so a stiff P term saturates the torque for errors above
    # 1 / kp rad, giving a near-constant-speed approach, and then closes the last part
    # exponentially; a little D term damps the shoulder, whose inertia is larger.
    KP = (4.0, 4.0)
    KD = (0.4, 0.1)

    def __init__(self, n_targets: int, mode_choice: str = "coin", kp=KP, kd=KD):
        if n_targets not in _reacher.ANGLES:
            raise ValueError(f"n_targets must be one of {sorted(_reacher.ANGLES)}, "
                             f"got {n_targets!r}")
        if mode_choice not in MODE_CHOICES:
            raise ValueError(f"mode_choice must be one of {MODE_CHOICES}, got {mode_choice!r}")
        self.n_targets = n_targets
        self.mode_choice = mode_choice
        self.kp = np.asarray(kp, dtype=np.float64)
        self.kd = np.asarray(kd, dtype=np.float64)
        self.targets = _reacher.target_positions(n_targets)
        env = tasks.make(f"reacher{n_targets}")
        self.upper, self.fore, self.wrist_limit = arm_geometry(env.physics)
        self.chosen: np.ndarray | None = None
        self.goal_q: np.ndarray | None = None
        self._reset_called = False

    def reset(self, seeds) -> None:
        """Starts a batch of episodes; ``seeds`` are their episode seeds (one per row)."""
        seeds = np.asarray(seeds, dtype=np.int64).ravel()
        self._reset_called = True
        self.goal_q = None
        self.chosen = (coin_flip_targets(seeds, self.n_targets) if self.mode_choice == "coin"
                       else None)

    @staticmethod
    def split(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint angles (B, 2), fingertip positions (B, 2), joint velocities (B, 2)."""
        q = np.stack([np.arctan2(obs[:, 1], obs[:, 0]), np.arctan2(obs[:, 3], obs[:, 2])], 1)
        return q, obs[:, 4:6], obs[:, 6:8]

    def __call__(self, obs) -> np.ndarray:
        q, fingertip, qdot = self.split(_as_batch(obs, 8, "ReacherExpert"))
        if self.goal_q is None:
            self._commit(q, fingertip)
        elif len(self.goal_q) != len(q):
            raise ValueError(f"batch of {len(q)} observations, but the current episodes have "
                             f"{len(self.goal_q)} rows: call reset(seeds) for a new batch")
        return pd_action(q, qdot, self.goal_q, self.kp, self.kd)

    def _commit(self, q: np.ndarray, fingertip: np.ndarray) -> None:
        """First step of the episodes: fix each row's target and joint goal for the episode."""
        if self.mode_choice == "nearest":
            self.chosen = nearest_targets(fingertip, self.targets)
        elif not self._reset_called or self.chosen is None:
            raise RuntimeError("ReacherExpert(mode_choice='coin') needs reset(seeds) before the "
                               "first step: the coin is seeded by the episode seeds")
        if len(self.chosen) != len(q):
            raise ValueError(f"reset got {len(self.chosen)} seeds but the batch has "
                             f"{len(q)} observations")
        # The goal is fixed once, rather than re-solved every step, so the elbow never flips
        # between the two IK solutions on the way.
        self.goal_q = np.stack([
            joint_goal(self.targets[c], q[b], self.upper, self.fore, self.wrist_limit)
            for b, c in enumerate(self.chosen)])


def expert_for(task: str, variant: str | None = None):
    """The scripted expert of ``task``.  Reachers: the target nearest to the fingertip at the
    start (a deterministic function of the first observation, so a Markov policy can follow
    it); ``variant="coin"``: a hidden coin flip per episode picks the target."""
    if variant not in (None, "coin") or (variant == "coin" and task not in ("reacher2",
                                                                          "reacher4")):
        raise ValueError(f"{task} has no expert variant {variant!r}; the variants are: "
                         f"{', '.join(VARIANTS.get(task, ())) or 'none'}")
    if task == "cartpole":
        return CartpoleLQR()
    if task in ("reacher1", "reacher2", "reacher4"):
        return ReacherExpert(int(task[len("reacher"):]),
                             mode_choice="coin" if variant == "coin" else "nearest")
    raise ValueError(f"no scripted expert for task {task!r}; scripted experts exist for: "
                     f"{', '.join(SCRIPTED_TASKS)}")


VARIANTS = {"reacher2": ("coin",), "reacher4": ("coin",)}


def describe(task: str, variant: str | None = None) -> dict:
    """What the scripted expert of ``task`` is, for the demonstrations' manifest."""
    if task == "cartpole":
        return {"kind": "scripted", "name": "CartpoleLQR",
                "method": "discrete LQR on a finite-difference linearisation about upright; "
                          "cost weights from the second-order expansion of the task's reward",
                "mode_choice": None}
    if task in ("reacher1", "reacher2", "reacher4"):
        return {"kind": "scripted", "name": "ReacherExpert",
                "method": "two-link inverse kinematics to the chosen target, PD control on "
                          "the joint angles", "gains": {"kp": list(map(float, ReacherExpert.KP)),
                                                        "kd": list(map(float, ReacherExpert.KD))},
                "variant": variant,
                "mode_choice": None if task == "reacher1" else
                               "coin: the target is drawn uniformly per episode from the "
                               "episode seed, independent of the initial state"
                               if variant == "coin" else
                               "nearest: the target nearest to the fingertip in the first "
                               "observation (a deterministic function of the start state)"}
    raise ValueError(f"no scripted expert for task {task!r}")


__all__ = ["SCRIPTED_TASKS", "VARIANTS", "describe", "MODE_CHOICES", "CartpoleLQR", "ReacherExpert", "expert_for",
           "linearise", "solve_dlqr", "two_link_ik", "joint_goal", "coin_flip_targets",
           "nearest_targets", "pd_action", "arm_geometry", "wrap_angle"]
