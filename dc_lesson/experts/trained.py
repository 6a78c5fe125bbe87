"""Experts trained with the library's PPO (``dc-lesson expert train --task NAME``), and the
loading of every network expert (the SAC-distilled ones of :mod:`dc_lesson.experts.network`
too).

Each *unit* is one network trained by one recipe (a task, a reward, a :class:`PPOConfig`).
Most tasks' expert is one unit; ``halfcheetah2``'s expert is two, a forward runner (the
``halfcheetah`` expert) and a backward runner, with a coin flip per episode choosing which one
runs (see :class:`CoinFlipMixture`).

Files, all under ``data/experts/``:

* ``checkpoints/UNIT.ckpt``: the PPO run's full state, written atomically every few updates;
  ``expert train`` resumes from it, so a run interrupted (or cut by a session's end) loses at
  most a few updates, and the resumed run ends exactly where an uninterrupted one would.
* ``UNIT.pt``: the trained policy (a state_dict with its constructor arguments and metadata,
  loaded with ``torch.load(..., weights_only=True)``).
* ``UNIT.pt.sha256`` (and ``checkpoints/UNIT.ckpt.sha256``): the file's sha256, checked
  before it is loaded (:mod:`dc_lesson.nn.checkpoint`); a damaged policy is refused with the
  command that restores it.
* ``UNIT.json``: the recipe, command, seed, git revision, wall time and the learning curve.

The expert acts with its policy's mean action (no sampling noise), which scores higher than
the stochastic policy PPO trained.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import time

import numpy as np
import torch

from dc_lesson import tasks as _tasks
from dc_lesson.nn.checkpoint import ModelFileError, checksum_path, load_checked
from dc_lesson.nn.policies import load_policy, save_policy
from dc_lesson.algorithms.ppo import PPOConfig, train
from dc_lesson import storage as _storage
from dc_lesson.storage import atomic_write_text, git_revision
from dc_lesson.algorithms import ppo as _ppo

EXPERTS_DIR = _storage.DATA / "experts"

# Index of the torso's forward (rootx) velocity in the cheetah's observation: 8 joint
# positions (rootx itself is left out) come first, then the 9 velocities.
_CHEETAH_VX = 8


def backward_running_reward(batch) -> np.ndarray:
    """The run reward mirrored: clip(-forward velocity / 10 m/s, 0, 1) per step.

    Computed from the observation's rootx velocity, a close stand-in for the centre-of-mass
    speed the task itself uses; the expert is judged on the task's own reward.
    """
    vx = np.asarray(batch.next_obs)[..., _CHEETAH_VX]
    return np.clip(-vx / 10.0, 0.0, 1.0)


REWARDS = {None: None, "backward": backward_running_reward}


hopper_fell = _tasks.TERMINATIONS["hopper-fall"]   # PPO's training-only termination


@dataclasses.dataclass(frozen=True)
class Recipe:
    unit: str
    task: str
    config: PPOConfig
    reward: str | None = None      # a key of REWARDS; None: the task's own reward
    note: str = ""


_LOCOMOTION = dict(n_envs=16, n_steps=256, n_minibatches=32, n_epochs=10, lr=3e-4,
                   gamma=0.99, gae_lambda=0.95, hidden=(64, 64))

RECIPES: dict[str, Recipe] = {r.unit: r for r in [
    Recipe("halfcheetah", "halfcheetah", PPOConfig(**_LOCOMOTION, total_steps=3_000_000),
           note="CleanRL's MuJoCo settings with 16 environments"),
    Recipe("halfcheetah-backward", "halfcheetah2",
           PPOConfig(**_LOCOMOTION, total_steps=3_000_000, seed=1), reward="backward",
           note="the same settings, rewarded for running backwards"),
    Recipe("hopper", "hopper",
           PPOConfig(**_LOCOMOTION, total_steps=1_000_000, terminate="hopper-fall"),
           note="the locomotion settings, with Gym's termination of a fallen hopper for "
                "training only (the task never ends early); without it, falls in the first "
                "few hundred steps left most of every 1000-step episode lying still"),
    # PPO's attempts at walker, ant and humanoid (experts.network: SAC networks for the first
    # two, the planner still for the humanoid): walker's and ant's stayed below the floors
    # after 5M steps and are kept, with their curves, for chapter 00's comparison (``dc_lesson.experts.trained.train_unit("walker-ppo")`` resumes them)
    Recipe("walker-ppo", "walker", PPOConfig(**_LOCOMOTION, total_steps=5_000_000)),
    Recipe("ant-ppo", "ant", PPOConfig(**_LOCOMOTION, total_steps=5_000_000)),
    Recipe("humanoid-ppo", "humanoid", PPOConfig(**{**_LOCOMOTION, "hidden": (256, 256)},
                                                 total_steps=10_000_000)),
]}

# The network experts by task: files data/experts/UNIT.pt. walker, ant and humanoid are
# written by experts.network (SAC, distilled), the others by train_unit (PPO).
EXPERT_UNITS = {"halfcheetah": ("halfcheetah",),
                "halfcheetah2": ("halfcheetah", "halfcheetah-backward"),
                "hopper": ("hopper",), "walker": ("walker",), "ant": ("ant",),
                "humanoid": ("humanoid",)}
PPO_TASKS = ("halfcheetah", "halfcheetah2", "hopper")   # dc-lesson expert train runs PPO


class ExpertMissing(FileNotFoundError):
    """A trained expert that has not been trained (or committed) yet."""


def unit_paths(unit: str, directory=None) -> dict[str, pathlib.Path]:
    d = pathlib.Path(directory or EXPERTS_DIR)
    return {"policy": d / f"{unit}.pt", "meta": d / f"{unit}.json",
            "checkpoint": d / "checkpoints" / f"{unit}.ckpt"}


def regenerate_hint(unit: str) -> str:
    """How to make a unit's files again: the committed copy from git, or the training command
    (which, from a finished checkpoint, only rewrites the policy)."""
    task = RECIPES[unit].task if unit in RECIPES else unit
    return (f"restore the committed copy with: git checkout -- data/experts/{unit}.pt "
            f"data/experts/{unit}.pt.sha256; or rewrite it with: dc-lesson expert train "
            f"--task {task}")


def _check_resumable(unit: str, path, config: PPOConfig, total_steps) -> None:
    """Refuses, before training, a checkpoint made with another configuration, saying how to
    discard it (``--restart``) or resume it."""
    ckpt = load_checked(path, _ppo.CHECKPOINT_FORMAT, _ppo.CHECKPOINT_VERSION,
                        "PPO checkpoint", regenerate_hint(unit))
    saved, now = _ppo._saved_config(ckpt), json.loads(config.to_json())
    if saved != now:
        diff = ", ".join(f"{k} {saved.get(k)!r} there, {now.get(k)!r} now"
                         for k in sorted(saved.keys() | now.keys()) if saved.get(k) != now.get(k))
        task = RECIPES[unit].task
        steps = "" if total_steps is None else f" --steps {total_steps}"
        raise ModelFileError(f"the checkpoint {path} of the {unit} expert was made with another "
                             f"configuration ({diff}); to discard it and train from the first "
                             f"update run: dc-lesson expert train --task {task}{steps} "
                             f"--restart (or leave out --steps to resume it)")


def train_unit(unit: str, total_steps: int | None = None, command: str = "",
               directory=None, progress: bool = True, restart: bool = False) -> dict:
    """Trains (or resumes training) one unit and writes its policy and metadata.

    A finished unit whose policy file passes its checksum is not trained again.  A checkpoint
    made with another configuration is refused (``ModelFileError``) unless ``restart``, which
    discards it and trains from the first update; the result's ``"restarted"`` says whether a
    checkpoint was discarded.
    """
    if unit not in RECIPES:
        raise ValueError(f"no training recipe {unit!r}; the recipes are: {', '.join(RECIPES)}")
    if total_steps is not None and (isinstance(total_steps, bool)
                                    or not isinstance(total_steps, int) or total_steps < 1):
        raise ValueError(f"total_steps must be a positive integer, got {total_steps!r}")
    recipe = RECIPES[unit]
    config = recipe.config
    if total_steps is not None:
        config = dataclasses.replace(config, total_steps=int(total_steps))
    paths = unit_paths(unit, directory)
    if paths["policy"].exists() and paths["meta"].exists() and not restart:
        try:
            done = _storage.read_json(paths["meta"], "training record", _record_fix(unit))
        except _storage.UnreadableFileError:
            done = {}   # a damaged record is not a finished unit: the run below rewrites it
        done = done if isinstance(done, dict) else {}
        # A knob added to PPOConfig after a unit was trained takes its default value.
        defaults = {f.name: f.default for f in dataclasses.fields(PPOConfig)}
        saved = json.loads(json.dumps({**defaults, **done.get("config", {})}))
        if done.get("steps") == config.n_updates * config.batch_size and \
                saved == json.loads(json.dumps(dataclasses.asdict(config))):
            try:
                load_policy(paths["policy"], fix=regenerate_hint(unit))
                return {k: v for k, v in done.items() if k != "learning_curve"}  # trained
            except ModelFileError:
                pass   # a damaged policy: the run below rewrites it from its checkpoint
    restarted = False
    if restart:
        for p in (paths["checkpoint"], checksum_path(paths["checkpoint"])):
            if p.exists():
                p.unlink()
                restarted = True
    elif paths["checkpoint"].exists():
        _check_resumable(unit, paths["checkpoint"], config, total_steps)
    paths["checkpoint"].parent.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)   # small networks: one thread is fastest and leaves a core free
    t0 = time.time()
    result = train(recipe.task, None, config, reward_fn=REWARDS[recipe.reward],
                           progress=progress, checkpoint=paths["checkpoint"])
    policy, log = result.policy, result.log
    wall = sum(config.batch_size / row["steps_per_second"] for row in log)
    curve = [{"steps": r["steps"], "episode_return": r["episode_return"]}
             for r in log if np.isfinite(r["episode_return"])]
    meta = {"unit": unit, "task": recipe.task, "algorithm": "PPO", "reward": recipe.reward,
            "config": dataclasses.asdict(config), "note": recipe.note,
            "command": command or f"dc-lesson expert train --task {recipe.task}",
            "seed": config.seed, "revision": git_revision(),
            "training_seconds": round(wall, 1), "steps": log[-1]["steps"] if log else 0,
            "this_call_seconds": round(time.time() - t0, 1)}
    save_policy(policy, paths["policy"], meta=meta)
    atomic_write_text(paths["meta"], json.dumps({**meta, "learning_curve": curve}, indent=1)
                      + "\n")
    return {**meta, "restarted": restarted}


def learning_curve(unit: str, directory=None) -> dict:
    """The stored learning curve of a trained unit, read from ``UNIT.json``: ``steps`` and
    ``episode_return`` (mean return of the training episodes that ended in each update, with
    the stochastic policy), the task and the training wall time."""
    path = unit_paths(unit, directory)["meta"]
    if not path.exists():
        raise ExpertMissing(f"no training record {path}; train the unit with "
                            f"dc_lesson.experts.trained.train_unit({unit!r})")
    fix = _record_fix(unit)
    meta = _storage.read_json(path, "training record", fix)
    task, seconds, curve = _storage.json_fields(meta, path, "training record", fix, "task",
                                                "training_seconds", "learning_curve")
    if not isinstance(curve, list) or not curve:
        raise ValueError(f"{path} has no learning curve; {fix}")
    try:
        steps = np.array([row["steps"] for row in curve])
        returns = np.array([row["episode_return"] for row in curve])
    except (KeyError, TypeError) as e:
        raise _storage.UnreadableFileError(f"training record {path} has a learning curve row "
                                           f"without {e} ({type(e).__name__}); {fix}") from None
    return {"unit": unit, "task": task, "steps": steps, "episode_return": returns,
            "training_seconds": seconds}


def _record_fix(unit: str) -> str:
    return (f"restore it with: git checkout -- data/experts/{unit}.json; or retrain the unit "
            f"with dc_lesson.experts.trained.train_unit({unit!r})")


class DeterministicPolicy:
    """A trained network acting with its mean action, as a numpy batch policy."""

    def __init__(self, net):
        self.net = net

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return self.net.act(torch.as_tensor(obs, dtype=torch.float32)).numpy()


class CoinFlipMixture:
    """One of several experts per episode, chosen by a fair coin drawn from the episode seed.

    ``chosen[i]`` is the index of the expert running episode row ``i`` after ``reset``.  The
    coin is independent of the initial state, so which mode an episode takes is not written
    in its first observation: a learner must commit to one by itself.
    """

    SALT = 2024   # keeps the coin independent of every other use of the episode seed

    def __init__(self, experts):
        self.experts = list(experts)
        self.chosen = None

    def reset(self, seeds) -> None:
        self.chosen = np.array([np.random.default_rng([int(s) % 2**63, self.SALT])
                                .integers(len(self.experts)) for s in seeds])

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self.chosen is None or len(self.chosen) != len(obs):
            raise RuntimeError("CoinFlipMixture needs reset(seeds) for this batch first "
                               "(rollout.collect calls it)")
        out = np.zeros((len(obs), 0))
        for k, expert in enumerate(self.experts):
            rows = self.chosen == k
            if rows.any():
                a = expert(obs[rows])
                if out.shape[1] == 0:
                    out = np.zeros((len(obs), a.shape[1]))
                out[rows] = a
        return out


class StartStateSwitch:
    """One of two experts per episode, chosen by the episode's first observation: expert 0
    when ``obs[feature] >= threshold`` in it, else expert 1.

    A deterministic function of the observed start state, so one Markov policy can follow it:
    the choice is written in the state an episode starts from.  The threshold is the median
    of that feature over start states, so the two experts take about half the episodes each.
    """

    def __init__(self, experts, feature: int, threshold: float):
        self.experts, self.feature, self.threshold = list(experts), int(feature), threshold
        self.chosen = None

    def reset(self, seeds) -> None:
        self.chosen = None          # decided by the first observation of the new episodes

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self.chosen is None or len(self.chosen) != len(obs):
            self.chosen = np.where(obs[:, self.feature] >= self.threshold, 0, 1)
        return CoinFlipMixture.__call__(self, obs)


# halfcheetah2's realizable expert: forward when the back thigh's angle (observation 2) starts
# at or above its median over start states (-0.0352 rad over seeds 0..1999, measured with
# tasks.make("halfcheetah2").reset(seed=s)), else backward.
HALFCHEETAH2_SWITCH = {"feature": 2, "feature_name": "bthigh angle (observation 2)",
                       "threshold": -0.0352}


def load_unit(unit: str, directory=None):
    path = unit_paths(unit, directory)["policy"]
    if not path.exists():
        task = RECIPES[unit].task if unit in RECIPES else unit
        raise ExpertMissing(f"the trained expert {path} does not exist yet; train it with: "
                            f"dc-lesson expert train --task {task}")
    return load_policy(path, fix=regenerate_hint(unit))


def load_trained_expert(task: str, directory=None, variant: str | None = None):
    """The expert of a locomotion task as a batch policy, and its description.

    ``halfcheetah2``: the forward and the backward runner, switched by the start state
    (:class:`StartStateSwitch`); ``variant="coin"``: by a hidden coin per episode."""
    if variant is not None and (task, variant) != ("halfcheetah2", "coin"):
        raise ValueError(f"{task} has no expert variant {variant!r}"
                         + ("; its variants are: coin" if task == "halfcheetah2" else ""))
    if task not in EXPERT_UNITS:
        raise ValueError(f"no trained expert for {task!r}; trained experts exist for: "
                         f"{', '.join(EXPERT_UNITS)}")
    nets = [load_unit(u, directory) for u in EXPERT_UNITS[task]]
    coin = variant == "coin"
    algorithm = nets[0].meta.get("algorithm", "PPO")
    info = {"kind": "trained",
            "name": (algorithm if len(nets) == 1 else f"{algorithm} coin-flip mixture" if coin
                     else f"{algorithm} start-state switch"),
            "units": [dict(net.meta, file=f"data/experts/{u}.pt")
                      for u, net in zip(EXPERT_UNITS[task], nets)],
            "acts_with": "the policy's mean action", "variant": variant,
            "mode_choice": (None if len(nets) == 1 else
                            "coin: forward or backward runner drawn per episode from the "
                            "episode seed, independent of the initial state" if coin else
                            f"start state: forward when {HALFCHEETAH2_SWITCH['feature_name']} "
                            f">= {HALFCHEETAH2_SWITCH['threshold']} in the first observation, "
                            f"else backward")}
    if len(nets) == 1:
        return DeterministicPolicy(nets[0]), info
    experts = [DeterministicPolicy(n) for n in nets]
    if coin:
        return CoinFlipMixture(experts), info
    return StartStateSwitch(experts, HALFCHEETAH2_SWITCH["feature"],
                            HALFCHEETAH2_SWITCH["threshold"]), info
