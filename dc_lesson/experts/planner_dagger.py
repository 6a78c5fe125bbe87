"""DAgger from the planner: a Markov network expert where SAC did not reach the floor (the
humanoid, issue 39).  ``dc-lesson expert dagger --task humanoid [--hours H]``.

Why.  The humanoid's first expert was a sampling planner (:mod:`dc_lesson.experts.planner`);
BC from its 25 demonstrations scored the random level, and SAC's first run on the task's
reward stayed near 0 after 500,000 steps (``humanoid-fall.json``; a second SAC recipe later
reached the floor and is the expert now, :mod:`dc_lesson.experts.network`).  A planner's action depends
on its nominal plan, a memory no Markov policy has, and a clone of its demonstrations drifts
into states the planner never showed.  DAgger (Ross, Gordon and Bagnell 2011) asks the
oracle for its action at the states the *student* visits, so the data cover the drift.

The labeller (:class:`Labeller`).  The planner runs beside the student's episode: at every
state the episode reaches it plans from the exact simulator state, warm-started by its own
shifted best plan of the step before, exactly as when it acts itself; its label is the first
action of its best plan (the action it would take there).  Who acts is DAgger's mixture: at every
step of round r each episode takes the planner's action with probability beta_r =
``beta`` ** r and the student's otherwise, so round 0 is the planner's own states and later
rounds drift further into the student's.  A pure student rollout (beta = 0) wastes a
humanoid round: the student falls within a few dozen steps and the rest of its labels are
of a body lying on the floor (measured: rounds 1-2 at beta = 0 returned 1.4 and 4.0 of the
planner's 210 over 400 steps).  After each round the student's mean is fitted to every label so far by mean squared
error (:func:`dc_lesson.experts.network.fit_mean`, as the SAC distillation does).

Choices, each a field of :class:`DaggerConfig`: rounds of ``episodes`` episodes of
``episode_steps`` steps (short: a fallen humanoid's states teach nothing, and a label costs a
whole plan, 0.2-0.3 s on one thread); the student is BC's default network (64 x 64 tanh,
observation normaliser fitted once on round 0's states), so the expert is in the class every
learner fits.

Resumable and integrity-checked: after every round the labels so far and the round's log go
to ``data/experts/checkpoints/TASK-dagger.pt`` (+ ``.sha256``, loaded with
``weights_only=True``; a file made with another configuration is refused, naming the fix).  A
rerun refits the student on them (the same numbers: the fit's generator is seeded by the
round) and goes on with the next round.  The student is written as the variant
``TASK-dagger.pt`` (+ ``.json`` with the rounds' returns); it becomes the task's expert only
if it meets the floor (``experts.DEFAULT_EXPERT``).
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import time

import numpy as np
import torch

from dc_lesson import storage as _storage
from dc_lesson import tasks as _tasks
from dc_lesson.checks import check_fields
from dc_lesson.nn.checkpoint import atomic_torch_save, load_checked
from dc_lesson.storage import atomic_write_text, git_revision

LABELS_FORMAT, LABELS_VERSION = "dc_lesson.planner_dagger.labels", 1
ROLLOUT_SEED = 700     # episode seeds of round r: rollout seed ROLLOUT_SEED + r
EVAL_SEED = 900        # as network.EVAL_SEED: the student's and the planner's final comparison


@dataclasses.dataclass(frozen=True)
class DaggerConfig:
    """DAgger from a task's planner into BC's GaussianPolicy."""
    rounds: int = 12             # round 0: the planner acts; then more and more the student
    beta: float = 0.5            # the planner acts at a step of round r with probability beta^r
    episodes: int = 2            # episodes per round (in lockstep)
    episode_steps: int = 400     # steps per episode (each a label)
    epochs: int = 30             # passes over all labels after each round
    batch_size: int = 256
    lr: float = 1e-3
    hidden: tuple = (64, 64)     # BC's default network, so cloning is realizable
    activation: str = "tanh"
    eval_episodes: int = 4
    seed: int = 0

    def __post_init__(self):
        check_fields(self, positive=("rounds", "episodes", "episode_steps", "epochs",
                                     "batch_size", "lr", "eval_episodes"),
                     non_negative=("seed",))
        if not 0 <= self.beta <= 1:
            raise ValueError(f"DaggerConfig.beta is a probability, got {self.beta}")

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)


RECIPES = {"humanoid": DaggerConfig()}


def paths(task: str, directory=None) -> dict[str, pathlib.Path]:
    d = pathlib.Path(directory or _storage.DATA / "experts")
    return {"labels": d / "checkpoints" / f"{task}-dagger.pt",
            "policy": d / f"{task}-dagger.pt", "meta": d / f"{task}-dagger.json"}


class Labeller:
    """A batch policy for :func:`dc_lesson.data.rollout.collect` that records, at every
    state, the observation and the planner's action there, and acts with the planner's
    action with probability ``beta`` (``rng``'s draw, per episode and step) and with
    ``actor`` (the student) otherwise; no actor: the planner always."""

    def __init__(self, planner, actor=None, beta: float = 1.0, rng=None):
        self.planner, self.actor, self.beta = planner, actor, beta
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.obs: list[np.ndarray] = []
        self.labels: list[np.ndarray] = []

    def attach(self, venv) -> None:
        self.planner.attach(venv)

    def reset(self, seeds) -> None:
        self.planner.reset(seeds)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        label = np.asarray(self.planner(obs), dtype=np.float32)   # plans from the sim state
        self.obs.append(np.asarray(obs, np.float32).copy())
        self.labels.append(label.copy())
        if self.actor is None:
            return label
        planner_acts = self.rng.random(len(obs)) < self.beta
        return np.where(planner_acts[:, None], label, self.actor(obs))


def _save(task, config, xs, ys, log, directory=None) -> None:
    atomic_torch_save({"format": LABELS_FORMAT, "version": LABELS_VERSION, "task": task,
                       "config": config.to_json(), "obs": torch.as_tensor(np.concatenate(xs)),
                       "labels": torch.as_tensor(np.concatenate(ys)),
                       "sizes": torch.as_tensor([len(x) for x in xs]),
                       "log": json.dumps(log)}, paths(task, directory)["labels"])


def _load(task, config, directory=None):
    """The stored rounds: ``(xs, ys, log)``, empty lists when none are stored."""
    p = paths(task, directory)["labels"]
    if not p.exists():
        return [], [], []
    fix = f"delete {p} (and its .sha256) to start DAgger again"
    obj = load_checked(p, LABELS_FORMAT, LABELS_VERSION, "DAgger labels", fix)
    if obj.get("task") != task or obj.get("config") != config.to_json():
        raise ValueError(f"{p} holds labels of another DAgger configuration ({obj.get('config')}"
                         f"; this run's: {config.to_json()}); {fix}")
    cuts = np.cumsum([0] + [int(n) for n in obj["sizes"]])
    x, y = obj["obs"].numpy(), obj["labels"].numpy()
    return ([x[a:b] for a, b in zip(cuts[:-1], cuts[1:])],
            [y[a:b] for a, b in zip(cuts[:-1], cuts[1:])], json.loads(obj["log"]))


def train(task: str, config: DaggerConfig | None = None, *, hours: float | None = None,
          directory=None, command: str = "", progress=print) -> dict:
    """Runs (or resumes) DAgger from ``task``'s planner; returns ``{"done", "log", ...}``.
    ``hours``: stop after the first round that ends past this much wall time."""
    from dc_lesson.data import rollout
    from dc_lesson.experts import network, planner as _planner
    from dc_lesson.nn.policies import GaussianPolicy, save_policy
    config = config or RECIPES[task]
    spec = _tasks.spec(task)
    torch.set_num_threads(1)
    xs, ys, log = _load(task, config, directory)
    teacher, _ = _planner.load_planner_expert(task)
    torch.manual_seed(config.seed)
    student = GaussianPolicy(spec.obs_dim, spec.act_dim, config.hidden, config.activation,
                             norm_obs=True)
    opt = torch.optim.Adam(student.mean_net.parameters(), lr=config.lr)

    def fit(r):   # after round r: every label of rounds 0..r, a generator of its own
        gen = torch.Generator().manual_seed(config.seed * 1000 + r)
        return network.fit_mean(student, opt, np.concatenate(xs[:r + 1]),
                                np.concatenate(ys[:r + 1]), config.epochs, config.batch_size,
                                gen)

    if xs:     # the stored rounds, refitted round by round as they were first fitted
        student.update_obs_norm(torch.as_tensor(xs[0]))
        for r in range(len(xs)):
            fit(r)
    t0 = time.time()
    for r in range(len(xs), config.rounds):
        labeller = Labeller(teacher, None if r == 0 else student.eval().act_numpy,
                            config.beta ** r, np.random.default_rng([config.seed, r]))
        eps = rollout.collect(task, labeller, config.episodes, seed=ROLLOUT_SEED + r,
                              batch=config.episodes, max_steps=config.episode_steps,
                              progress=False)
        xs.append(np.concatenate(labeller.obs))
        ys.append(np.concatenate(labeller.labels))
        if r == 0:
            student.update_obs_norm(torch.as_tensor(xs[0]))
        mse = fit(r)
        row = {"round": r, "rolled_out_by": "planner" if r == 0 else "mixture",
               "beta": 1.0 if r == 0 else config.beta ** r,
               "return": float(rollout.returns(eps).mean()), "steps": config.episode_steps,
               "labels": int(sum(len(x) for x in xs)), "mse": mse,
               "seconds": round(time.time() - t0, 1)}
        log.append(row)
        _save(task, config, xs, ys, log, directory)
        if progress:
            progress(f"{task} DAgger round {r} (the planner acts with probability "
                     f"{row['beta']:.2f}): return {row['return']:.1f}"
                     f" over {config.episode_steps} steps; {row['labels']:,} labels, MSE "
                     f"{mse:.4f}")
        if hours is not None and time.time() - t0 > 3600 * hours and r + 1 < config.rounds:
            return {"done": False, "log": log}
    n = config.eval_episodes
    student_r = rollout.returns(rollout.collect(task, student.eval(), n, seed=EVAL_SEED,
                                                batch=n, progress=False))
    meta = {"unit": f"{task}-dagger", "task": task, "algorithm": "DAgger from the planner",
            "config": dataclasses.asdict(config), "command": command, "revision": git_revision(),
            "student_return": {"mean": float(student_r.mean()), "std": float(student_r.std()),
                               "n_episodes": n, "seed": EVAL_SEED}}
    p = paths(task, directory)
    save_policy(student, p["policy"], meta=meta)
    atomic_write_text(p["meta"], json.dumps({**meta, "rounds": log}, indent=1) + "\n")
    return {"done": True, "log": log, **meta}


def record(task: str, directory=None) -> dict | None:
    """What is on record of ``task``'s DAgger: ``{"done", "rounds", "student_return",
    "config", "label_variance"}`` (the last: the labels' variance per action dimension,
    averaged, beside which a round's ``mse`` reads) from the finished run's ``.json`` (``student_return`` over full episodes),
    else from the stored labels of an unfinished run (``student_return`` None); None when
    neither exists.  For chapter 00's curve.  The humanoid's first rows were written before
    the log named the mixture (round 1 says "student" and has no ``beta``): every round after
    the first is read as what it was, the mixture at ``beta ** round``."""
    p = paths(task, directory)
    config = RECIPES[task]
    if p["meta"].exists():
        meta = _storage.read_json(p["meta"], "DAgger record")
        out = {"done": True, "rounds": meta["rounds"], "config": meta["config"],
               "student_return": meta["student_return"]}
    elif p["labels"].exists():
        _, _, log = _load(task, config, directory)
        out = {"done": False, "rounds": log, "config": dataclasses.asdict(config),
               "student_return": None}
    else:
        return None
    if p["labels"].exists():   # how much of the labels a function of the state could fit
        _, ys, _ = _load(task, RECIPES[task], directory)
        out["label_variance"] = float(np.concatenate(ys).var(axis=0).mean())
    beta = out["config"]["beta"]
    out["rounds"] = [{**r, "rolled_out_by": "planner" if r["round"] == 0 else "mixture",
                      "beta": 1.0 if r["round"] == 0 else beta ** r["round"]}
                     for r in out["rounds"]]
    return out


__all__ = ["DaggerConfig", "Labeller", "RECIPES", "paths", "record", "train"]
