"""A sampling-based planner on the true simulator: the expert of the hard locomotion tasks.

Predictive sampling (Howell et al., 2022, "Predictive Sampling: Real-time Behaviour Synthesis
with MuJoCo", the simplest planner of MuJoCo MPC) needs no training at all.  At every control
step it

1. keeps a *nominal plan*: actions at ``n_knots`` evenly spaced control steps from now to
   the last of the H = ``horizon`` / control timestep steps looked ahead, linearly
   interpolated between them, shifted forward one control step after each step by
   re-sampling it at the knots one step later (held at its last value past the end);
2. draws ``n_samples - 1`` candidate plans, the nominal plus Gaussian noise of std ``noise``
   on every knot (clipped to the action bounds), and keeps the unperturbed nominal as the
   last candidate, so a good plan is never lost to noise;
3. rolls every candidate out open-loop from the environment's exact current state with
   ``mujoco.rollout`` (C, optionally multi-threaded) and scores it by the sum of the task's
   own per-step reward over the horizon;
4. makes the best candidate the nominal and acts with its first action.

With ``replan_every = k > 1`` it plans only every k-th control step and follows the nominal
plan open-loop in between: k times cheaper, a little less robust.

Why it scores with the task's own reward, exactly: the planner works on a copy of the task's
model with extra frame sensors (every body's position, inertial position and orientation)
appended after the task's own sensors.  From the rollout's sensor readings it rebuilds the
MjData fields the task's ``batch_reward`` reads, and calls that very function: the reward
the planner predicts for its first step is the reward the environment pays for it (a test
checks this to 1e-9).  Sensors never change the dynamics, so the copy steps like the task
(to about 1e-12: ``mujoco.rollout`` starts the constraint solver without the environment's
warm start).  The copy cannot know state outside MuJoCo's full-physics state (mocap bodies,
applied forces) nor changes a task makes to its model at reset; no port here has either,
and a task whose reward reads a field the rollouts do not give (``geom_xpos`` of the
reachers) is refused.  A task whose own reward is a poor planning objective (humanoid falls
at once with it, see ../shared/notes/platform.md) may plan with a shaped reward instead,
named in :data:`PLANNING_REWARDS`; the expert is still *judged* on the task's reward.

Determinism: the noise of each episode comes from its own generator, seeded by the planner's
``seed`` and the episode seed (given to :meth:`reset`), and rollouts of different candidates
do not interact, so an episode's actions depend on its seed alone, not on the number of
threads or on which episodes run beside it.

A planner is a batch policy that reads the physics state, not only the observation:
:func:`dc_lesson.data.rollout.collect` hands it the running environments through ``attach(venv)``.
It acts as the expert only while attached; a learner imitates its observations and actions.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from typing import Callable

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from dc_lesson.checks import check_fields
from dc_lesson import tasks as _tasks
from dc_lesson.tasks.base import Batch

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclasses.dataclass(frozen=True)
class PlannerConfig:
    """Settings of predictive sampling (see the module docstring for each step)."""
    n_samples: int = 64          # candidate plans per control step, the nominal included
    horizon: float = 0.5         # seconds looked ahead
    n_knots: int = 4             # interpolation knots of a plan
    noise: float = 0.3           # std of the Gaussian perturbation of each knot
    replan_every: int = 1        # control steps between plans (the nominal runs in between)
    planning_reward: str | None = None   # a key of PLANNING_REWARDS; None: the task's reward
    seed: int = 0
    threads: int = 1             # threads of mujoco.rollout (results do not depend on it)

    def __post_init__(self):
        check_fields(self, positive=("n_samples", "horizon", "n_knots", "replan_every",
                                     "threads"),
                     non_negative=("noise", "seed"))

    def validate(self) -> "PlannerConfig":
        if self.replan_every < 1:
            raise ValueError(f"replan_every must be at least 1, got {self.replan_every}")
        if self.n_samples < 2:
            raise ValueError(f"n_samples must be at least 2, got {self.n_samples}")
        if self.n_knots < 2:
            raise ValueError(f"n_knots must be at least 2, got {self.n_knots}")
        if not self.horizon > 0 or not self.noise >= 0:
            raise ValueError("horizon must be positive and noise non-negative")
        if self.planning_reward not in PLANNING_REWARDS:
            raise ValueError(f"unknown planning reward {self.planning_reward!r}; the choices "
                             f"are: {', '.join(map(str, PLANNING_REWARDS))}")
        return self


def _quat_to_mat(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z), shape (..., 4), to flattened row-major rotation
    matrices, shape (..., 9): MuJoCo's xmat layout."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                     2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                     2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)


class SensedModel:
    """The task's model with frame sensors of every body appended, and the way back from
    rollout outputs to the MjData fields a task's reward reads."""

    def __init__(self, task: str):
        xml, assets = _tasks.model_and_assets(task)
        spec = mujoco.MjSpec.from_string(xml, assets)
        base = mujoco.MjModel.from_xml_string(xml, assets)
        bodies = spec.bodies       # depth-first, the order of the compiled model's bodies
        for i, body in enumerate(bodies[1:], start=1):
            if not body.name:          # a sensor names its body; unnamed ones get a name
                body.name = f"_planner_body_{i}"
        names = [b.name for b in bodies]
        self.n_own = base.nsensordata
        self.nbody = base.nbody
        for i, name in enumerate(names[1:], start=1):
            for kind, obj, tag in ((mujoco.mjtSensor.mjSENS_FRAMEPOS, mujoco.mjtObj.mjOBJ_XBODY, "xpos"),
                                   (mujoco.mjtSensor.mjSENS_FRAMEPOS, mujoco.mjtObj.mjOBJ_BODY, "xipos"),
                                   (mujoco.mjtSensor.mjSENS_FRAMEQUAT, mujoco.mjtObj.mjOBJ_XBODY, "xquat")):
                spec.add_sensor(name=f"_planner_{tag}_{i}", type=kind, objtype=obj, objname=name)
        with warnings.catch_warnings():   # dm_control's cheetah XML uses a deprecated attribute
            warnings.simplefilter("ignore", UserWarning)
            self.model = spec.compile()
        m = self.model
        if (m.nq, m.nv, m.nu, m.na) != (base.nq, base.nv, base.nu, base.na) or \
                not np.array_equal(m.sensor_adr[:base.nsensor], base.sensor_adr) or \
                not np.array_equal(m.body_parentid, base.body_parentid) or \
                not np.array_equal(m.body_mass, base.body_mass):
            raise RuntimeError(f"{task}: the planner's model copy does not match the task's")
        self.nq, self.nv = m.nq, m.nv
        # The task's own sensors of the acceleration stage (touch, force, ...): after a
        # control step the environment holds them from its last physics step's mj_step2.
        self.acc_sensors = np.zeros(self.n_own, bool)
        for i in range(base.nsensor):
            if base.sensor_needstage[i] == mujoco.mjtStage.mjSTAGE_ACC:
                adr = base.sensor_adr[i]
                self.acc_sensors[adr:adr + base.sensor_dim[i]] = True

    # The MjData fields :meth:`fields` rebuilds: all that a task's reward may read.
    FIELDS = ("qpos", "qvel", "xpos", "xipos", "xmat", "sensordata", "ctrl")

    def fields(self, states: np.ndarray, sensordata: np.ndarray, ctrl: np.ndarray) -> dict:
        """MjData fields of M simulator states: full-physics states (M, nstate), their sensor
        readings (M, nsensordata) and the controls applied (M, nu)."""
        M = len(states)
        extra = sensordata[:, self.n_own:].reshape(M, self.nbody - 1, 10)
        xpos = np.zeros((M, self.nbody, 3))
        xipos = np.zeros((M, self.nbody, 3))
        xmat = np.zeros((M, self.nbody, 9))
        xmat[:, 0] = np.eye(3).ravel()
        xpos[:, 1:], xipos[:, 1:] = extra[..., 0:3], extra[..., 3:6]
        xmat[:, 1:] = _quat_to_mat(extra[..., 6:10])
        return {"qpos": states[:, 1:1 + self.nq],
                "qvel": states[:, 1 + self.nq:1 + self.nq + self.nv],
                "xpos": xpos, "xipos": xipos, "xmat": xmat,
                "sensordata": sensordata[:, :self.n_own], "ctrl": ctrl}


def as_batch(fields: dict, ids: dict) -> Batch:
    b = Batch.__new__(Batch)
    b.ids = ids
    for k, v in fields.items():
        setattr(b, k, v)
    return b


# Shaped planning objectives, for tasks whose own reward a short-horizon planner cannot
# climb.  Each maps (task object, Batch) to a per-step reward; none is used to judge.
PLANNING_REWARDS: dict[str | None, Callable | None] = {None: None}


def _humanoid_shaped(task, b: Batch) -> np.ndarray:
    """Humanoid walk plus a wider head-height term: the task's standing term falls to a
    tenth with the head at 1.05 m and to 1e-4 at 0.7 m, so a planner that stumbles sees
    almost no gradient back up; this adds up to 0.5 for head height (still a tenth of that
    at 0.5 m) times the task's own upright term (torso z axis vertical)."""
    from dm_control.utils import rewards
    head = b.xpos[:, b.ids["head"], 2]
    standing = rewards.tolerance(head, bounds=(1.4, float("inf")), margin=0.9,
                                 sigmoid="gaussian")
    upright = rewards.tolerance(b.xmat[:, b.ids["torso"], 8], bounds=(0.9, float("inf")),
                                sigmoid="linear", margin=1.9, value_at_margin=0)
    own = task.batch_reward(b)
    return 0.5 * standing * upright + own


PLANNING_REWARDS["humanoid-shaped"] = _humanoid_shaped


class PredictiveSampling:
    """Predictive sampling as a batch policy for :func:`dc_lesson.data.rollout.collect`."""

    kind = "planner"

    def __init__(self, task: str, config: PlannerConfig = PlannerConfig()):
        self.task_name = _tasks.check_name(task)
        self.config = config.validate()
        self.spec = _tasks.spec(task)
        self.sensed = SensedModel(task)
        self.env_task = _tasks.make(task).task    # for its reward functions and named ids
        missing = [f for f in self.env_task.fields if f not in SensedModel.FIELDS]
        if missing:
            raise ValueError(f"a planner cannot score {task!r}: its reward reads "
                             f"{', '.join(missing)}, which the rollouts do not give "
                             f"(they give {', '.join(SensedModel.FIELDS)})")
        self.ids = self.env_task.resolve(self.sensed.model)
        self.H = max(2, int(round(config.horizon / self.spec.control_timestep)))
        self.knot_t = np.linspace(0, self.H - 1, config.n_knots)
        m = self.sensed.model
        self.low, self.high = m.actuator_ctrlrange[:, 0].copy(), m.actuator_ctrlrange[:, 1].copy()
        self.datas = [mujoco.MjData(m) for _ in range(max(1, config.threads))]
        self.venv = None
        self.rngs: list[np.random.Generator] = []
        self.nominal = None        # (B, n_knots, nu)
        self.last_scores = None    # (B, n_samples) predicted returns of the candidates
        self.last_first_reward = None  # (B,) predicted reward of the chosen first step
        reward = PLANNING_REWARDS[config.planning_reward]
        self.score = (lambda b: self.env_task.batch_reward(b)) if reward is None else \
            (lambda b: reward(self.env_task, b))

    # -- the batch-policy protocol ---------------------------------------------------------
    def attach(self, venv) -> None:
        if venv.spec.name != self.task_name:
            raise ValueError(f"a planner for {self.task_name!r} cannot act in {venv.spec.name!r}")
        self.venv = venv

    def reset(self, seeds) -> None:
        self.rngs = [np.random.default_rng([self.config.seed, int(s) % 2**63]) for s in seeds]
        self.nominal = np.zeros((len(seeds), self.config.n_knots, self.spec.act_dim))
        self.t = 0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self.venv is None or self.nominal is None or len(self.nominal) != len(obs):
            raise RuntimeError("a planner acts on the simulator state: rollout.collect calls "
                               "attach(venv) and reset(seeds) before the first step")
        self.t += 1
        if (self.t - 1) % self.config.replan_every:
            # Between plans: the next action of the last plan, open loop.
            action = self.nominal[:, 0].copy()
            self.nominal = self._shift(self.nominal)
            self.last_first_reward = None
            return action
        return self.plan(self._states(len(obs)))

    # -- planning --------------------------------------------------------------------------
    def _states(self, n: int) -> np.ndarray:
        return self.venv.get_states(_FULL)[:n]

    def _controls(self, knots: np.ndarray) -> np.ndarray:
        """Per-control-step actions (..., H, nu) of plans given by knots (..., K, nu)."""
        t = np.arange(self.H)
        idx = np.clip(np.searchsorted(self.knot_t, t, side="right") - 1, 0, len(self.knot_t) - 2)
        t0, t1 = self.knot_t[idx], self.knot_t[idx + 1]
        w = ((t - t0) / (t1 - t0))[:, None]
        return knots[..., idx, :] * (1 - w) + knots[..., idx + 1, :] * w

    def _shift(self, knots: np.ndarray) -> np.ndarray:
        """The nominal plan one control step later (held at its end)."""
        t = np.clip(self.knot_t + 1, 0, self.H - 1)
        idx = np.clip(np.searchsorted(self.knot_t, t, side="right") - 1, 0, len(self.knot_t) - 2)
        t0, t1 = self.knot_t[idx], self.knot_t[idx + 1]
        w = ((t - t0) / (t1 - t0))[:, None]
        return knots[:, idx, :] * (1 - w) + knots[:, idx + 1, :] * w

    def predicted_fields(self, states: np.ndarray, controls: np.ndarray) -> dict:
        """The MjData fields the environment would hold after each control step of open-loop
        action sequences (R, H, nu) from states (R, nstate), flattened to R * H rows."""
        R, H, nu = controls.shape
        n = self.spec.n_sub_steps
        # mujoco.rollout records for physics step k the state after it (state[k]) and the
        # sensors computed during it, of the state *before* it (sensordata[k]).  After control
        # step j (physics steps up to ends[j] - 1, 0-based) the environment holds the state
        # after them with positions and sensors brought up to date by mj_step1: state[ends - 1]
        # and sensordata[ends], hence one physics step more than the horizon.  Acceleration-
        # stage sensors it holds from its last physics step's mj_step2: sensordata[ends - 1].
        per_physics = np.repeat(controls, n, axis=1)
        per_physics = np.concatenate([per_physics, per_physics[:, -1:]], axis=1)
        st, sd = mj_rollout.rollout(self.sensed.model, self.datas, states, per_physics)
        ends = np.arange(1, H + 1) * n
        sensors = sd[:, ends]
        acc = self.sensed.acc_sensors
        if acc.any():
            own = sensors[..., :self.sensed.n_own]          # a view: assigns into sensors
            own[..., acc] = sd[:, ends - 1, :self.sensed.n_own][..., acc]
        return self.sensed.fields(st[:, ends - 1].reshape(R * H, -1),
                                  sensors.reshape(R * H, -1), controls.reshape(R * H, nu))

    def predict(self, states: np.ndarray, controls: np.ndarray) -> np.ndarray:
        """Per-step rewards (R, H) of open-loop action sequences (R, H, nu) from states (R, .)
        by the planning objective."""
        R, H, _ = controls.shape
        fields = self.predicted_fields(states, controls)
        return np.asarray(self.score(as_batch(fields, self.ids))).reshape(R, H)

    def plan(self, states: np.ndarray) -> np.ndarray:
        B, N, K, nu = len(states), self.config.n_samples, self.config.n_knots, self.spec.act_dim
        cands = np.empty((B, N, K, nu))
        for i in range(B):
            noise = self.rngs[i].standard_normal((N - 1, K, nu)) * self.config.noise
            cands[i, :-1] = self.nominal[i] + noise
            cands[i, -1] = self.nominal[i]
        cands = np.clip(cands, self.low, self.high)
        rewards = self.predict(np.repeat(states, N, axis=0),
                               self._controls(cands.reshape(B * N, K, nu))).reshape(B, N, -1)
        scores = rewards.sum(-1)
        best = scores.argmax(1)
        chosen = cands[np.arange(B), best]
        self.last_scores, self.last_first_reward = scores, rewards[np.arange(B), best, 0]
        self.nominal = self._shift(chosen)
        return chosen[:, 0].copy()

    def describe(self) -> dict:
        return self.describe_config(self.task_name, self.config)

    @staticmethod
    def describe_config(task: str, config: PlannerConfig) -> dict:
        dt = _tasks.spec(task).control_timestep
        settings = dataclasses.asdict(config)
        settings.pop("threads")    # how fast, not what it does: results do not depend on it
        return {"kind": "planner", "name": "predictive sampling (MPC on the true simulator)",
                "config": settings,
                "horizon_steps": max(2, int(round(config.horizon / dt))),
                "planning_objective": config.planning_reward or "the task's own reward",
                "acts_with": f"the best of n_samples sampled plans, replanned every "
                             f"{config.replan_every} control step(s)",
                "mode_choice": None}


# The tasks whose expert is this planner, with its settings, chosen by short trials on this
# machine (one seed each: a guide, not a measurement).  Humanoid, 300-step trials: 64 samples
# over 0.5 s scored 74, 96 over 0.4 s 87, 128 over 0.3 s 24 in 200 steps, all falling;
# 128 over 0.5 s walked, and scored 577 over its first whole demonstration.  Replanning only
# every second step kept falling and getting up (157 per episode).  The cost: about 0.5 s of
# CPU per control step, so 50 episodes take hours; ``dc-lesson demos`` resumes if stopped.
# Walker: 64 samples over 0.5 s with the task's own reward walked at once, 866 and 986 over
# two whole episodes (seed 100), where PPO had reached 354 after 5M steps; about 0.07 s of CPU
# per control step.
# Ant, 300-step trials from seed 100 with its own reward: over 0.5 s it stalled (about 0.1
# per step); over 1.0 s, 32 samples scored 83, 64 scored 269 and 128 scored 272, so 64 (about
# 0.12 s of CPU per control step).  PPO had plateaued near 160 per episode after 5M steps.
# The hopper's expert is PPO's (on Gym's hopper model since issue 18).  On the earlier port
# (dm_control's suite hopper model, torso 0.6 m above the foot to stand) the planner made it fall
# within 50 steps over 0.5 s; over 1.0 s with 8 knots, "hopper-shaped" kept it standing at
# about 0.08 m/s, and objectives paying more for speed moved it at 0.3-0.5 m/s but let the
# torso drop below the standing height for much of each episode, or fall (300-step trials).
PLANNERS: dict[str, PlannerConfig] = {
    "humanoid": PlannerConfig(n_samples=128, horizon=0.5, n_knots=4, noise=0.3,
                              replan_every=1, planning_reward="humanoid-shaped"),
    "walker": PlannerConfig(n_samples=64, horizon=0.5, n_knots=4, noise=0.3, replan_every=1),
    "ant": PlannerConfig(n_samples=64, horizon=1.0, n_knots=4, noise=0.3, replan_every=1),
}


def settings_path(task: str, directory=None):
    from dc_lesson.experts.trained import EXPERTS_DIR
    import pathlib
    return pathlib.Path(directory or EXPERTS_DIR) / f"{task}-planner.json"


def write_settings(task: str, command: str = "", directory=None) -> dict:
    """``dc-lesson expert train`` for a planner task: nothing to learn; writes the planner's
    settings to ``data/experts/TASK-planner.json`` (what ``load_expert`` runs)."""
    import json
    from dc_lesson.storage import atomic_write_text, git_revision
    if task not in PLANNERS:
        raise ValueError(f"{task!r} has no planner expert; planner experts exist for: "
                         f"{', '.join(PLANNERS)}")
    info = {**PredictiveSampling.describe_config(task, PLANNERS[task]),
            "command": command or f"dc-lesson expert train --task {task}",
            "revision": git_revision()}
    path = settings_path(task, directory)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(info, indent=1) + "\n")
    return info


def load_planner_expert(task: str):
    """The planner expert of ``task`` and its description (the settings in PLANNERS)."""
    threads = max(1, min(4, os.cpu_count() or 1))   # mujoco.rollout's threads
    policy = PredictiveSampling(task, dataclasses.replace(PLANNERS[task], threads=threads))
    return policy, policy.describe()
