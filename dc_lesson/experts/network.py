"""Network experts for ``walker``, ``ant`` and ``humanoid``: SAC, then distilled into the
learners' own policy class. ``dc-lesson expert train --task walker``.

Why: these tasks' first experts were sampling planners (the best of 64-128 random plans,
replanned every step), which no Markov policy can clone (BC from 25 demonstrations scored
about 0 on the scaled axis), and the library's PPO stayed below the floors after 5M steps
(``data/experts/walker-ppo.json``, ``ant-ppo.json``). The paper's experts were Gaussian MLPs,
the learner's own class; so are these, made in two stages:

1. **SAC** (:mod:`dc_lesson.experts.sac`) on the task's own reward, with the recipe in
   ``SAC_RECIPES`` (small 64x64 networks: on one CPU thread a 256x256 update costs 4x more, and
   the small ones reached the walker's floor in 100k steps). Resumable: the run's full state,
   replay buffer included, is checkpointed every 25k steps to
   ``data/experts/checkpoints/TASK.sac`` (hundreds of MB, not committed), so a session's end
   costs at most 25k steps; ``hours`` cuts a run into chunks. The finished actor is committed
   as ``TASK-sac.pt`` (+ ``.sha256``) and its curve as ``TASK-sac.json``.
2. **Distillation by DAgger** into a :class:`~dc_lesson.nn.policies.GaussianPolicy` of BC's
   default shape (64x64 tanh, observation normaliser), so the expert is *exactly* in the class
   every learner fits: the states are visited by the student (round 0: by the SAC actor), the
   labels are the SAC actor's deterministic action tanh(mu(s)) at them (``DISTIL``). The student is
   ``TASK.pt`` (+ ``.json`` with both stages' recipes and curves).

The student is the task's expert where it meets the floor (``experts.DEFAULT_EXPERT``: all
three). The humanoid's needed a second recipe: the first run, which ended every training
episode at a fall, stayed near 0 (its record: ``humanoid-fall.json``, :data:`FIRST_HUMANOID_RUN`);
the second starts half of its training episodes at the planner's demonstrated states
(``SAC_RECIPES``' comment). The expert acts with the distilled policy's mean action.
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
from dc_lesson.experts.sac import Actor, SACConfig, json_config, train as sac_train
from dc_lesson.nn.checkpoint import ModelFileError, atomic_torch_save, load_checked
from dc_lesson.storage import atomic_write_text, git_revision

EXPERTS_DIR = _storage.DATA / "experts"
# The humanoid's first SAC run (500k steps, training episodes ended at a fall): the record of
# its distilled student, kept for its curve (chapter 00) after the second recipe replaced it.
FIRST_HUMANOID_RUN = EXPERTS_DIR / "humanoid-fall.json"
ACTOR_FORMAT, ACTOR_VERSION = "dc_lesson.sac_actor", 1

_SMALL = dict(hidden=(64, 64), log_every=5_000, checkpoint_every=25_000, eval_episodes=2)
# The expert whose demonstrations a recipe's ``demo_fraction`` and ``demo_starts`` use.
SAC_DEMOS: dict[str, str] = {"humanoid": "planner"}

SAC_RECIPES: dict[str, SACConfig] = {
    "walker": SACConfig(**_SMALL, total_steps=200_000),
    "ant": SACConfig(**_SMALL, total_steps=300_000),
    # The humanoid (measured on the planner's 25 demonstrations): dm_control starts it in a
    # random pose, and its head drops below tasks.humanoid.FALLEN_HEAD within 30 steps in 19
    # of 25 episodes (median first step 18) even under the planner, which then gets up and
    # walks (mean return 631; chapter 00 renders these). So Gym's fallen-humanoid termination
    # (the 500k-step run of round 3: evaluation returns at most 22 of 1000; its curve stays
    # in data/experts/humanoid.json) ended nearly every
    # training episode before the agent could learn to rise. No termination, then; and half
    # of the training episodes begin at a state of the planner's demonstrations
    # (``demo_starts``: reference state initialisation), so the agent meets standing and
    # walking states and tries its own actions there. Rejected by measurement (one seed each,
    # session 15): the planner's transitions as half of every minibatch (RLPD,
    # ``demo_fraction``) made the critic diverge at the demonstrated pairs, whose actions the
    # agent never tries: without LayerNorm, mean Q 2432 at 100k steps where the reward and
    # the entropy bonus then bound the soft value below about 800; with LayerNorm, 104 rising
    # to 193 by 275k (the demonstrations' discounted return-to-go: 59), TD loss 17 -> 121;
    # with the starts as well, TD loss 2.6 -> 79 by 290k. With the starts alone the TD loss
    # stayed at 0.02-0.2 (growing with the returns), and the evaluations rose from about 2 to
    # above the floor between 180k and 400k steps (the first run, below). LayerNorm critics
    # kept (RLPD's; that run had them).
    # 800k steps, about 2 hours at 110 steps/s: a run that fits in one sitting, because the
    # replay buffer (git-ignored) does not survive a fresh machine. The first run of this
    # recipe, planned for 3M steps, was lost that way at 625k (its record: humanoid-sac.json
    # at commit 93f29e2): its evaluations took off at about 190k steps and passed the floor
    # of 300 by 360k. Its rerun on another machine (another CPU's rounding, so another
    # trajectory) stayed near 2 until about 480k, then took off; planned for 700k, it was
    # extended to 800k at 500k steps (evaluation 53, training episodes 151), so that it
    # could reach the floor as far past its take-off as the first run had.
    "humanoid": SACConfig(**{**_SMALL, "hidden": (128, 128)}, total_steps=800_000,
                          demo_starts=0.5, critic_layer_norm=True),
}


@dataclasses.dataclass(frozen=True)
class DistilConfig:
    """DAgger from the SAC actor into the learners' GaussianPolicy."""
    rounds: int = 6              # round 0: the SAC actor's own states; then the student's
    episodes_per_round: int = 8  # 1000-step episodes collected each round
    epochs: int = 30             # passes over all labelled states after each round
    batch_size: int = 256
    lr: float = 1e-3
    hidden: tuple = (64, 64)     # BC's default network (BCConfig), so cloning is realizable
    activation: str = "tanh"
    eval_episodes: int = 10
    seed: int = 0


DISTIL = DistilConfig()


def paths(task: str, directory=None) -> dict[str, pathlib.Path]:
    d = pathlib.Path(directory or EXPERTS_DIR)
    return {"checkpoint": d / "checkpoints" / f"{task}.sac", "actor": d / f"{task}-sac.pt",
            "sac_meta": d / f"{task}-sac.json", "policy": d / f"{task}.pt",
            "meta": d / f"{task}.json"}


def _write_sac_meta(task, cfg, log, done, command, directory=None):
    meta = {"task": task, "algorithm": "SAC", "config": json_config(cfg), "done": done,
            "command": command or f"dc-lesson expert train --task {task}",
            "revision": git_revision(),
            "training_seconds": log[-1]["seconds"] if log else 0.0,
            "steps": log[-1]["steps"] if log else 0, "log": log}
    atomic_write_text(paths(task, directory)["sac_meta"], json.dumps(meta, indent=1) + "\n")
    return meta


def sac_demonstrations(task: str):
    """The demonstrations the task's SAC recipe samples from (``SAC_DEMOS``), or None.

    Named by their expert, so the set stays the same when the task's default expert (and with
    it the unnamed demonstration file) changes."""
    kind, cfg = SAC_DEMOS.get(task), SAC_RECIPES[task]
    if kind is None or (cfg.demo_fraction == 0 and cfg.demo_starts == 0):
        return None
    from dc_lesson.data import load_demos
    from dc_lesson.experts import DEFAULT_EXPERT
    variant = None if DEFAULT_EXPERT.get(task) == kind else kind
    return load_demos(task, variant=variant).trajectories


def train_sac(task: str, hours: float | None = None, command: str = "", directory=None,
              progress=print) -> dict:
    """Runs (or resumes) the task's SAC recipe; returns its metadata with ``done``.

    ``hours``: stop at the first checkpoint after this much wall time (run again to go on).
    The actor is written to ``TASK-sac.pt`` when the run is done."""
    if task not in SAC_RECIPES:
        raise ValueError(f"no SAC recipe for {task!r}; the recipes are: {', '.join(SAC_RECIPES)}")
    cfg, p = SAC_RECIPES[task], paths(task, directory)
    p["checkpoint"].parent.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)

    def show(row):
        if progress:
            progress(f"{task} SAC {row['steps']:>8,} steps: eval return {row['eval_return']:7.1f}"
                     f", train {row['train_return']:7.1f}, alpha {row['alpha']:.3f}, "
                     f"{row['steps_per_second']:.0f} steps/s")

    out = sac_train(task, cfg, checkpoint=p["checkpoint"], progress=show,
                    stop_after_seconds=None if hours is None else 3600 * hours,
                    demonstrations=sac_demonstrations(task))
    meta = _write_sac_meta(task, cfg, out["log"], out["done"], command, directory)
    if out["done"]:
        atomic_torch_save({"format": ACTOR_FORMAT, "version": ACTOR_VERSION,
                           "config": json.dumps(json_config(cfg)),
                           "state_dict": out["actor"].state_dict()}, p["actor"])
    return meta


def load_sac_actor(task: str, directory=None) -> Actor:
    p = paths(task, directory)["actor"]
    fix = f"train it with: dc-lesson expert train --task {task}"
    if not p.exists():
        raise FileNotFoundError(f"no SAC actor {p}; {fix}")
    obj = load_checked(p, ACTOR_FORMAT, ACTOR_VERSION, "SAC actor", fix)
    spec = _tasks.SPECS[task]
    try:   # a file that passed its checksum but holds no usable configuration
        cfg = json.loads(obj["config"])
        actor = Actor(spec.obs_dim, spec.act_dim, tuple(cfg["hidden"]), cfg["log_std_min"],
                      cfg["log_std_max"])
    except (KeyError, TypeError, ValueError) as e:
        raise ModelFileError(f"SAC actor {p} holds no usable configuration "
                             f"({type(e).__name__}: {e}); {fix}") from None
    try:
        actor.load_state_dict(obj["state_dict"])
    except (KeyError, RuntimeError) as e:
        raise ModelFileError(f"SAC actor {p} does not fit its recipe ({e}); {fix}") from None
    return actor.eval()


def fit_mean(student, opt, x, y, epochs: int, batch_size: int, gen: torch.Generator) -> float:
    """``epochs`` passes of minibatch MSE of the student's mean on labels ``y`` at states
    ``x`` (a Gaussian's NLL at fixed spread), in the order ``gen`` draws; the final MSE."""
    x, y = torch.as_tensor(x), torch.as_tensor(y)
    z = student.normalise(x)
    for _ in range(epochs):
        perm = torch.randperm(len(x), generator=gen)
        for i in range(0, len(x), batch_size):
            idx = perm[i:i + batch_size]
            loss = ((student.mean_net(z[idx]) - y[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    with torch.no_grad():
        return float(((student.mean_net(z) - y) ** 2).mean())


DISTIL_SEED = 500     # episode seeds of DAgger round r: rollout seed DISTIL_SEED + r
EVAL_SEED = 900       # the final comparison of teacher and student


def distil(task: str, teacher: Actor, config: DistilConfig = DISTIL, progress=print):
    """DAgger (Ross et al. 2011) from ``teacher``'s deterministic action into a fresh
    GaussianPolicy; returns ``(student, log)``.

    Round 0 rolls out the teacher; round r >= 1 the current student, whose visited states are
    labelled by the teacher and added to one growing dataset (the states a clone drifts into
    are the ones it must learn to leave). After each round the student's mean is fitted to
    all labels by mean squared error (a Gaussian's NLL at fixed spread). The observation
    normaliser is fitted once, on the teacher's states."""
    from dc_lesson.data import rollout
    from dc_lesson.nn.policies import GaussianPolicy
    spec = _tasks.SPECS[task]
    torch.manual_seed(config.seed)
    gen = torch.Generator().manual_seed(config.seed)
    student = GaussianPolicy(spec.obs_dim, spec.act_dim, config.hidden, config.activation,
                             norm_obs=True)
    opt = torch.optim.Adam(student.mean_net.parameters(), lr=config.lr)
    xs, ys, log = [], [], []
    for r in range(config.rounds):
        runner = teacher.act_numpy if r == 0 else student
        eps = rollout.collect(task, runner, config.episodes_per_round, seed=DISTIL_SEED + r,
                              batch=config.episodes_per_round, progress=False)
        obs = np.concatenate([t.observations[:-1] for t in eps])
        if r == 0:
            student.update_obs_norm(torch.as_tensor(obs))
        xs.append(obs)
        ys.append(teacher.act_numpy(obs))
        mse = fit_mean(student, opt, np.concatenate(xs), np.concatenate(ys), config.epochs,
                       config.batch_size, gen)
        row = {"round": r, "rolled_out_by": "teacher" if r == 0 else "student",
               "return": float(rollout.returns(eps).mean()),
               "states": int(sum(len(x) for x in xs)), "mse": mse}
        log.append(row)
        if progress:
            progress(f"{task} DAgger round {r}: {row['rolled_out_by']} return "
                     f"{row['return']:.1f}; {row['states']:,} labelled states, MSE {mse:.4f}")
    return student.eval(), log


def distil_expert(task: str, config: DistilConfig = DISTIL, command: str = "",
                  directory=None, progress=print) -> dict:
    """Distils the finished SAC actor of ``task`` and writes the expert ``TASK.pt`` and
    ``TASK.json`` (both stages' recipes, SAC's curve, DAgger's rounds, and teacher and
    student returns over the same ``eval_episodes`` episodes)."""
    from dc_lesson.data import rollout
    from dc_lesson.nn.policies import save_policy
    p = paths(task, directory)
    teacher = load_sac_actor(task, directory)
    fix = f"rerun: dc-lesson expert train --task {task}"
    sac_meta = _storage.read_json(p["sac_meta"], "SAC record", fix)
    _storage.json_fields(sac_meta, p["sac_meta"], "SAC record", fix, "config",
                         "training_seconds", "steps", "log")   # before hours of distillation
    torch.set_num_threads(1)
    t0 = time.time()
    student, log = distil(task, teacher, config, progress)
    n = config.eval_episodes
    teacher_r = rollout.returns(rollout.collect(task, teacher.act_numpy, n, seed=EVAL_SEED,
                                                batch=n, progress=False))
    student_r = rollout.returns(rollout.collect(task, student, n, seed=EVAL_SEED, batch=n,
                                                progress=False))
    meta = {"unit": task, "task": task, "algorithm": "SAC, distilled by DAgger",
            "sac_config": sac_meta["config"], "distil_config": dataclasses.asdict(config),
            "command": command or f"dc-lesson expert train --task {task}",
            "revision": git_revision(), "seed": sac_meta["config"]["seed"],
            "sac_training_seconds": sac_meta["training_seconds"],
            "distil_seconds": round(time.time() - t0, 1), "steps": sac_meta["steps"],
            "training_seconds": round(sac_meta["training_seconds"] + time.time() - t0, 1),
            "teacher_return": {"mean": float(teacher_r.mean()), "std": float(teacher_r.std()),
                               "n_episodes": n, "seed": EVAL_SEED},
            "student_return": {"mean": float(student_r.mean()), "std": float(student_r.std()),
                               "n_episodes": n, "seed": EVAL_SEED}}
    save_policy(student, p["policy"], meta=meta)
    curve = [{"steps": row["steps"], "episode_return": row["eval_return"]}
             for row in sac_meta["log"]]
    atomic_write_text(p["meta"], json.dumps({**meta, "learning_curve": curve,
                                             "dagger": log}, indent=1) + "\n")
    if progress:
        progress(f"{task}: SAC actor {teacher_r.mean():.1f}, distilled GaussianPolicy "
                 f"{student_r.mean():.1f} over {n} episodes (seed {EVAL_SEED})")
    return meta


def sac_curve(task: str, directory=None) -> dict:
    """The stored SAC run of ``task`` (``TASK-sac.json``): ``steps``, ``eval_return`` (the mean
    action's return over the recipe's evaluation episodes at each log row), the wall time,
    and whether the run reached its recipe's steps (``done``)."""
    path = paths(task, directory)["sac_meta"]
    if not path.exists():
        raise FileNotFoundError(f"no SAC record {path}; train it with: dc-lesson expert "
                                f"train --task {task}")
    fix = f"rerun: dc-lesson expert train --task {task}"
    meta = _storage.read_json(path, "SAC record", fix)
    log, seconds, done, config = _storage.json_fields(meta, path, "SAC record", fix, "log",
                                                      "training_seconds", "done", "config")
    try:
        return {"task": task, "steps": np.array([r["steps"] for r in log]),
                "eval_return": np.array([r["eval_return"] for r in log]),
                "training_seconds": seconds, "done": done,
                "total_steps": config["total_steps"]}
    except (KeyError, TypeError) as e:
        raise _storage.UnreadableFileError(f"SAC record {path} lacks {e} in its log or config "
                                           f"({type(e).__name__}); {fix}") from None
