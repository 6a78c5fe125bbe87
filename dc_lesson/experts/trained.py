"""Experts trained with the library's PPO: ``dc-lesson expert train --task NAME``.

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
from dc_lesson.policies import load_policy, save_policy
from dc_lesson import ppo as _ppo
from dc_lesson.ppo import PPOConfig, train
from dc_lesson.results import atomic_write_text, git_revision

EXPERTS_DIR = pathlib.Path(__file__).resolve().parent.parent.parent / "data" / "experts"

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


def hopper_fell(obs: np.ndarray) -> np.ndarray:
    """Gym's unhealthy hopper, read from the observation (torso height ``obs[0]``, angle
    ``obs[1]``): below 0.7 m or tilted more than 0.2 rad.  A *training-only* termination
    (PPO's ``terminate="hopper-fall"``): the task itself never ends an episode early, it pays
    an unhealthy step nothing.  (Gym's third test, every position and velocity within +-100,
    needs the unclipped velocities; a hopper does not get there before it falls.)"""
    from dc_lesson.tasks import hopper
    obs = np.asarray(obs)
    return (obs[..., 0] <= hopper.HEALTHY_Z) | (np.abs(obs[..., 1]) >= hopper.HEALTHY_ANGLE)


_ppo.TERMINATIONS["hopper-fall"] = hopper_fell


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
    Recipe("walker", "walker", PPOConfig(**_LOCOMOTION, total_steps=5_000_000)),
    Recipe("ant", "ant", PPOConfig(**_LOCOMOTION, total_steps=5_000_000)),
    Recipe("humanoid", "humanoid", PPOConfig(**{**_LOCOMOTION, "hidden": (256, 256)},
                                             total_steps=10_000_000)),
]}

EXPERT_UNITS = {"halfcheetah": ("halfcheetah",),
                "halfcheetah2": ("halfcheetah", "halfcheetah-backward"),
                "hopper": ("hopper",), "walker": ("walker",), "ant": ("ant",),
                "humanoid": ("humanoid",)}


class ExpertMissing(FileNotFoundError):
    """A trained expert that has not been trained (or committed) yet."""


def unit_paths(unit: str, directory=None) -> dict[str, pathlib.Path]:
    d = pathlib.Path(directory or EXPERTS_DIR)
    return {"policy": d / f"{unit}.pt", "meta": d / f"{unit}.json",
            "checkpoint": d / "checkpoints" / f"{unit}.ckpt"}


def train_unit(unit: str, total_steps: int | None = None, command: str = "",
               directory=None, progress: bool = True) -> dict:
    """Trains (or resumes training) one unit and writes its policy and metadata."""
    if unit not in RECIPES:
        raise ValueError(f"no training recipe {unit!r}; the recipes are: {', '.join(RECIPES)}")
    recipe = RECIPES[unit]
    config = recipe.config
    if total_steps is not None:
        config = dataclasses.replace(config, total_steps=int(total_steps))
    paths = unit_paths(unit, directory)
    if paths["policy"].exists() and paths["meta"].exists():
        done = json.loads(paths["meta"].read_text())
        # A knob added to PPOConfig after a unit was trained takes its default value.
        defaults = {f.name: f.default for f in dataclasses.fields(PPOConfig)}
        saved = json.loads(json.dumps({**defaults, **done.get("config", {})}))
        if done.get("steps") == config.n_updates * config.batch_size and \
                saved == json.loads(json.dumps(dataclasses.asdict(config))):
            return {k: v for k, v in done.items() if k != "learning_curve"}  # already trained
    paths["checkpoint"].parent.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)   # small networks: one thread is fastest and leaves a core free
    t0 = time.time()
    policy, _, log = train(recipe.task, config, reward_fn=REWARDS[recipe.reward],
                           progress=progress, checkpoint=paths["checkpoint"])
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
    return meta


def learning_curve(unit: str, directory=None) -> dict:
    """The stored learning curve of a trained unit, read from ``UNIT.json``: ``steps`` and
    ``episode_return`` (mean return of the training episodes that ended in each update, with
    the stochastic policy), the task and the training wall time."""
    path = unit_paths(unit, directory)["meta"]
    if not path.exists():
        raise ExpertMissing(f"no training record {path}; train the unit with "
                            f"dc_lesson.experts.trained.train_unit({unit!r})")
    meta = json.loads(path.read_text())
    curve = meta.get("learning_curve")
    if not isinstance(curve, list) or not curve:
        raise ValueError(f"{path} has no learning curve; retrain the unit with "
                         f"dc_lesson.experts.trained.train_unit({unit!r})")
    return {"unit": unit, "task": meta["task"],
            "steps": np.array([row["steps"] for row in curve]),
            "episode_return": np.array([row["episode_return"] for row in curve]),
            "training_seconds": meta["training_seconds"]}


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


def load_unit(unit: str, directory=None):
    path = unit_paths(unit, directory)["policy"]
    if not path.exists():
        task = RECIPES[unit].task if unit in RECIPES else unit
        raise ExpertMissing(f"the trained expert {path} does not exist yet; train it with: "
                            f"dc-lesson expert train --task {task}")
    return load_policy(path)


def load_trained_expert(task: str, directory=None):
    """The expert of a locomotion task as a batch policy, and its description."""
    if task not in EXPERT_UNITS:
        raise ValueError(f"no trained expert for {task!r}; trained experts exist for: "
                         f"{', '.join(EXPERT_UNITS)}")
    nets = [load_unit(u, directory) for u in EXPERT_UNITS[task]]
    info = {"kind": "trained", "name": "PPO" if len(nets) == 1 else "PPO coin-flip mixture",
            "units": [dict(net.meta, file=f"data/experts/{u}.pt")
                      for u, net in zip(EXPERT_UNITS[task], nets)],
            "acts_with": "the policy's mean action",
            "mode_choice": (None if len(nets) == 1 else
                            "coin: forward or backward runner drawn per episode from the "
                            "episode seed, independent of the initial state")}
    if len(nets) == 1:
        return DeterministicPolicy(nets[0]), info
    return CoinFlipMixture([DeterministicPolicy(n) for n in nets]), info
