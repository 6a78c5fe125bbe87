"""Our GAIL against a standard library's: ``python -m dc_lesson.perf.imitation_gail --task
hopper --steps 1000000 --seeds 0 --out FILE``.

Runs HumanCompatibleAI imitation 1.0.1's GAIL (its stable-baselines3 PPO generator) on our
task port and our demonstrations, from the warm start of our competence study
(:mod:`dc_lesson.experiments.studies.competence`), for as many environment interactions as our
learners get there, and scores the final policy with our own
:func:`~dc_lesson.evaluation.evaluate_policy` (mean action, the study's evaluation seed and
episode count).  Beside each seed's numbers it puts our GAIL's run of the same task, part and
seed from the study's result file (``competence.json``, when the sweep has made it), so one
file holds both, with the seconds of each run.

**The start.**  The competence study's BC start of the seed (BC on the task's first 4
demonstrations, to the budget's ``bc_max_epochs`` for the "keep" part, ``competence_weak_epochs``
for "learn"; trained on the fast path and one thread, as the sweep's workers train it, so it is
the very policy our learners start from: each row says whether its score is the stored
cells' start's, to the bit), with its log-std set to
``algorithms.base.START_LOG_STD`` as every learner of the study sets it.  Its mean network and
log-std are copied into SB3's ``ActorCriticPolicy`` (:data:`LAYERS`), whose observation
normaliser slot holds the start's own normaliser, frozen (:func:`sb3_classes`); SB3's value
network has no counterpart in a BC policy and starts freshly initialised (SB3's orthogonal
init from the run's seed), as our GAIL's critic does.  The policy network is ours (64-64
tanh) wherever imitation recommends another, so that both libraries start from one policy.

**The settings.**  imitation's own tuned GAIL settings for seals' MuJoCo Hopper and
HalfCheetah (:data:`RECOMMENDED`, from its repository's
``src/imitation/scripts/config/tuned_hps/gail_seals_{hopper,half_cheetah}_best_hp_eval.json``
at tag v1.0.1, built as its ``train_adversarial`` script builds them), with the changes
:func:`settings` lists, each with its reason; the result file records both.  Our competence
study's fixes for our GAIL (``competence.FIXES``) are ours and are not applied here.

imitation is not a dependency of dc_lesson: install it as :mod:`dc_lesson.perf.imitation_ref`
says (``python -m venv --system-site-packages VENV && VENV/bin/pip install imitation==1.0.1
torch==2.13.0 mujoco==3.17.0 dm-control==1.0.50``) and run this module with ``VENV/bin/python``.
"""

from __future__ import annotations

import argparse
import copy
import functools
import sys
import tempfile
import time
from pathlib import Path

import gymnasium
import numpy as np
import torch

from dc_lesson import budget as _budget
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms import bc as _bc
from dc_lesson.algorithms import envs as _envs
from dc_lesson.data import store as _store
from dc_lesson.evaluation import EVAL_SEED, CheckpointCurve, evaluate_policy
from dc_lesson.nn import fast
from dc_lesson.nn.policies import GaussianPolicy, RunningNorm
from dc_lesson.perf.imitation_ref import LAYERS, ready
from dc_lesson.storage import git_revision, read_result, write_result
from dc_lesson.tasks.gym import GymEnv

# The competence study's facts this benchmark shares.  perf does not import experiments
# (tests/test_layers.py), so they are restated here and tests/test_imitation_gail.py checks
# that they are still the study's.
N_DEMOS = 4                               # competence.N_DEMOS
KEEP_TASKS = ("cartpole", "hopper")       # competence.KEEP_TASKS
TERMINATE = {"hopper": "hopper-fall"}     # competence.TERMINATE
STUDY_EVAL_SEED = EVAL_SEED + 0           # protocol.expert_eval_seed(0), the study's eval_seed
OUR_GAIL_FIXES = {"expert_noise": "learner", "ppo.norm_adv": False}   # competence.FIXES["gail"]

TUNED = "src/imitation/scripts/config/tuned_hps/gail_seals_{}_best_hp_eval.json"
# The parts of imitation's train_adversarial that the tuned files leave at their defaults, with
# where each is set in imitation 1.0.1's repository.
_SCRIPT = {
    "num_vec": 8,            # src/imitation/scripts/ingredients/environment.py
    "parallel": True,        # same file: SubprocVecEnv
    "allow_variable_horizon": False,   # src/imitation/algorithms/adversarial/common.py
    "disc_opt": "Adam, torch's defaults (lr 1e-3)",   # same file: disc_opt_cls, disc_opt_kwargs
    "reward_net": "BasicRewardNet (state, action; 32-32 ReLU) with normalize_input_layer="
                  "RunningNorm, wrapped in NormalizedRewardNet(RunningNorm)",
    "gen_train_timesteps": "rl batch_size (n_steps x num_vec)",
}
RECOMMENDED = {   # imitation 1.0.1's tuned files (TUNED), read, not imported
    "hopper": {
        "source": TUNED.format("hopper"), "environment": "seals/Hopper-v1",
        "demo_batch_size": 128, "gen_replay_buffer_capacity": 4096,
        "n_disc_updates_per_round": 8, "rl_batch_size": 4096, "total_timesteps": 10_000_000,
        "ppo": {"batch_size": 512, "clip_range": 0.1, "ent_coef": 0.001255299425412744,
                "gae_lambda": 0.98, "gamma": 0.995, "learning_rate": 4.3984856156897565e-5,
                "max_grad_norm": 0.9, "n_epochs": 20, "vf_coef": 0.20315938606555833},
        "policy": {"pi": [64, 64], "vf": [64, 64], "activation": "ReLU",
                   "features_extractor": "NormalizeFeaturesExtractor(RunningNorm)"},
        **_SCRIPT},
    "halfcheetah": {
        "source": TUNED.format("half_cheetah"), "environment": "seals/HalfCheetah-v1",
        "demo_batch_size": 8192, "gen_replay_buffer_capacity": 512,
        "n_disc_updates_per_round": 8, "rl_batch_size": 4096, "total_timesteps": 10_000_000,
        "ppo": {"batch_size": 64, "clip_range": 0.1, "ent_coef": 3.992371122209408e-6,
                "gae_lambda": 0.95, "gamma": 0.95, "learning_rate": 0.00026250519057717037,
                "max_grad_norm": 0.8, "n_epochs": 5, "vf_coef": 0.11483689492120866},
        "policy": {"pi": [32, 32], "vf": [32, 32], "activation": "Tanh",   # FeedForward32Policy
                   "features_extractor": "NormalizeFeaturesExtractor(RunningNorm)"},
        **_SCRIPT},
}
# Our policy's observation normaliser and where SB3's policy holds it (:func:`sb3_classes`):
# the BC start's statistics, frozen in both (imitation's RunningNorm there would be updated
# by every PPO minibatch).
NORM = {"obs_norm.mean": "features_extractor.norm.mean",
        "obs_norm.var": "features_extractor.norm.var",
        "obs_norm.count": "features_extractor.norm.count"}


def _imitation():
    try:
        from imitation.algorithms.adversarial import gail
        from imitation.data import types
        from imitation.rewards import reward_nets
        from imitation.util import logger, networks
        # stable-baselines3 is imitation's pinned dependency (2.2.1), not dc_lesson's: optional
        # as imitation is (tests/test_packaging.py's OPTIONAL)
        import stable_baselines3 as sb3
        from stable_baselines3.common import torch_layers
        from stable_baselines3.common import vec_env
    except ImportError:
        raise ImportError("this benchmark needs imitation 1.0.1 in its own environment (see "
                          "`python -m dc_lesson.perf.imitation_gail --help`)") from None
    return dict(sb3=sb3, gail=gail, types=types, reward_nets=reward_nets, logger=logger,
                networks=networks, torch_layers=torch_layers, DummyVecEnv=vec_env.DummyVecEnv)


# -- our task as imitation trains on it ------------------------------------------------------------

class TrainingEnv(gymnasium.Wrapper):
    """Task port ``task``'s Gymnasium face (:class:`~dc_lesson.tasks.gym.GymEnv`: episodes of
    exactly the horizon, truncated there) with the training-only termination ``terminate``
    our learners train with (``competence.TERMINATE``: a fallen hopper ends its training
    episode, ``terminated=True``, so PPO does not bootstrap past the fall).  Evaluation never
    steps this: it runs the task itself, which never ends early."""

    def __init__(self, task: str, terminate: str | None = None):
        super().__init__(GymEnv(task))
        self.terminate = terminate
        self._ended = _envs.termination(terminate)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._ended is not None:
            terminated = bool(np.asarray(self._ended(obs[None])).reshape(-1)[0])
        return obs, reward, terminated, truncated, info


# -- the weights between the libraries -------------------------------------------------------------

def sb3_state(policy: GaussianPolicy) -> dict:
    """``policy``'s mean network and log-std under SB3's ``ActorCriticPolicy`` names (its
    value network is not among them: BC has none)."""
    ours = policy.state_dict()
    return {theirs: ours[name].detach().clone() for name, theirs in LAYERS.items()}


def from_sb3(state: dict, start: GaussianPolicy) -> GaussianPolicy:
    """Our :class:`GaussianPolicy` with SB3's mean network and log-std from ``state`` and
    ``start``'s architecture and (frozen) observation normaliser."""
    if not getattr(start, "gaussian", False) or len(start.config()["hidden"]) != 2:
        raise ValueError("the weight map (LAYERS) is for a GaussianPolicy of two hidden layers")
    # a copy, not a new policy: building one would draw from torch's global generator, which
    # SB3 samples its actions from, so a checkpoint's evaluation would change the run
    policy = copy.deepcopy(start)
    weights = {name: state[theirs].detach().clone() for name, theirs in LAYERS.items()}
    weights.update({name: buf.detach().clone()
                    for name, buf in start.state_dict().items() if name in NORM})
    policy.load_state_dict(weights)   # strict: every tensor of ours is set
    return policy


@functools.cache
def sb3_classes():
    """The SB3 features extractor holding our start's observation normaliser (SB3 builds the
    extractor from a class and keyword arguments, and imitation's recommended
    ``NormalizeFeaturesExtractor`` sits in this slot): our :class:`RunningNorm`, whose
    ``forward`` never updates it, so the warm-started policy's inputs stay those BC fitted."""
    torch_layers = _imitation()["torch_layers"]

    class FrozenNorm(torch_layers.BaseFeaturesExtractor):
        def __init__(self, observation_space, stats: dict | None = None):
            dim = int(np.prod(observation_space.shape))
            super().__init__(observation_space, features_dim=dim)
            self.norm = RunningNorm(dim)
            if stats is not None:
                self.norm.load_state_dict(stats)
            else:   # a start without a normaliser: the identity
                self.norm.clip, self.norm.eps = float("inf"), 0.0

        def forward(self, observations):
            return self.norm(torch.flatten(observations, 1))

    return FrozenNorm


def make_generator(venv, start: GaussianPolicy, seed: int, used: dict):
    """SB3's PPO at ``used``'s settings, its policy set to ``start`` (mean net, log-std and
    normaliser); its value network stays as SB3 initialised it."""
    im = _imitation()
    cfg = start.config()
    if cfg["activation"] != "tanh":
        raise ValueError("the SB3 policy is built with tanh layers; the start has "
                         f"{cfg['activation']}")
    stats = start.obs_norm.state_dict() if start.obs_norm is not None else None
    kwargs = dict(net_arch=dict(pi=list(used["policy"]["pi"]), vf=list(used["policy"]["vf"])),
                  activation_fn=torch.nn.Tanh, features_extractor_class=sb3_classes(),
                  features_extractor_kwargs=dict(stats=stats))
    gen = im["sb3"].PPO("MlpPolicy", venv, policy_kwargs=kwargs, seed=seed, verbose=0,
                        n_steps=used["rl_batch_size"] // used["num_vec"], device="cpu",
                        **used["ppo"])
    with torch.no_grad():
        theirs = gen.policy.state_dict()
        for name, value in sb3_state(start).items():
            if theirs[name].shape != value.shape:
                raise ValueError(f"SB3's {name} is {tuple(theirs[name].shape)}, ours "
                                 f"{tuple(value.shape)}")
        loaded = gen.policy.load_state_dict(sb3_state(start), strict=False)
    # all that is left at SB3's initial values: the value network (and the extractor, which
    # was built holding the start's normaliser)
    fresh = [k for k in loaded.missing_keys if "value_net" not in k
             and "features_extractor" not in k]
    if fresh or loaded.unexpected_keys:
        raise RuntimeError(f"the start's weights do not fit SB3's policy: left {fresh}, "
                           f"unknown {loaded.unexpected_keys}")
    return gen


# -- the settings ----------------------------------------------------------------------------------

def settings(task: str, *, steps: int, n_demos: int, n_expert_pairs: int, hidden=(64, 64),
             terminate: str | None = None) -> tuple[dict, list[dict]]:
    """``(used, deviations)``: imitation's recommended settings for ``task`` as this
    benchmark runs them, and each change, ``{"setting", "recommended", "used", "why"}``."""
    if task not in RECOMMENDED:
        raise ValueError(f"imitation tunes GAIL for {', '.join(RECOMMENDED)} among our tasks; "
                         f"got {task!r}")
    rec = RECOMMENDED[task]
    used = copy.deepcopy({k: rec[k] for k in ("demo_batch_size", "gen_replay_buffer_capacity",
                                              "n_disc_updates_per_round", "rl_batch_size",
                                              "ppo", "num_vec")})
    used["policy"] = {"pi": list(hidden), "vf": list(rec["policy"]["vf"]), "activation": "Tanh",
                      "features_extractor": "the BC start's observation normaliser, frozen"}
    used.update(total_timesteps=int(steps), parallel=False,
                allow_variable_horizon=terminate is not None, terminate=terminate)
    dev = [
        {"setting": "environment", "recommended": rec["environment"], "used": f"our {task} port",
         "why": "the benchmark compares the libraries on our tasks"},
        {"setting": "demonstrations", "recommended": "imitation's PPO experts' (HuggingFace)",
         "used": f"our first {n_demos} demonstrations ({n_expert_pairs} pairs)",
         "why": "our learners' demonstrations (the competence study's 4)"},
        {"setting": "total_timesteps", "recommended": rec["total_timesteps"], "used": int(steps),
         "why": "as many interactions as our learners get in the competence study (imitation "
                "runs whole rounds of rl_batch_size: the run is rounded down to them)"},
        {"setting": "start", "recommended": "a fresh policy",
         "used": f"our competence study's BC start, log-std {_base.START_LOG_STD} "
                 "(algorithms.base.START_LOG_STD)",
         "why": "both libraries from the same start (imitation's train_adversarial takes a warm "
                "start too: agent_path); SB3's value network stays freshly initialised"},
        {"setting": "observation normaliser of the policy", "recommended":
         rec["policy"]["features_extractor"] + ", updated during training",
         "used": used["policy"]["features_extractor"],
         "why": "BC fitted the start on these inputs; a normaliser that moves changes the "
                "start's actions without a gradient step (our GAIL freezes it for that reason)"},
        {"setting": "vector environment", "recommended": "SubprocVecEnv, 8 copies",
         "used": "DummyVecEnv, 8 copies (one process)",
         "why": "the same transitions; one process and one torch thread, as our runs are timed"},
    ]
    if used["policy"]["pi"] != rec["policy"]["pi"]:
        dev.append({"setting": "policy network", "recommended": rec["policy"]["pi"],
                    "used": used["policy"]["pi"],
                    "why": "ours, so the start is our BC policy itself; the value network "
                           "(fresh either way) keeps imitation's size"})
    if rec["policy"]["activation"] != "Tanh":
        dev.append({"setting": "activation", "recommended": rec["policy"]["activation"],
                    "used": "Tanh", "why": "our start's; SB3 takes one activation for the policy "
                                           "and value networks, so both are tanh"})
    if terminate is not None:
        dev.append({"setting": "allow_variable_horizon", "recommended": False, "used": True,
                    "why": f"the training-only termination our learners train {task} with "
                           f"({terminate}: competence.TERMINATE); seals' tasks never end early"})
    if used["demo_batch_size"] > n_expert_pairs:
        used["demo_batch_size"] = int(n_expert_pairs)
        dev.append({"setting": "demo_batch_size", "recommended": rec["demo_batch_size"],
                    "used": int(n_expert_pairs),
                    "why": "more than our demonstrations hold (imitation refuses a batch larger "
                           "than its data): every discriminator step takes all the pairs"})
    return used, dev


# -- one run ---------------------------------------------------------------------------------------

def expert_trajectories(demos):
    """Our demonstrations as imitation's ``Trajectory`` list (whole episodes)."""
    types = _imitation()["types"]
    out = []
    for t in demos.trajectories:
        if getattr(t, "kept", None) is not None:
            raise ValueError("a subsampled demonstration (kept pairs only) has no imitation "
                             "trajectory form; use whole episodes")
        out.append(types.Trajectory(obs=np.asarray(t.observations, np.float32),
                                    acts=np.asarray(t.actions, np.float32), infos=None,
                                    terminal=True))
    return out


def imitation_gail(task: str, demos, start: GaussianPolicy, seed: int, steps: int, *,
                   terminate: str | None = None, curve: CheckpointCurve | None = None):
    """imitation's GAIL on ``task`` from ``start`` for ``steps`` interactions with ``seed``.

    Returns ``(policy, info)``: the final policy as our :class:`GaussianPolicy`, and
    ``info`` with ``train_seconds`` (everything after the start, the checkpoint evaluations
    included, as our competence cells time it), ``curve_seconds``, ``interactions`` (whole
    rounds), ``settings`` and ``deviations``."""
    im = _imitation()
    trajs = expert_trajectories(demos)
    n_pairs = sum(len(t.acts) for t in trajs)
    used, deviations = settings(task, steps=steps, n_demos=len(trajs), n_expert_pairs=n_pairs,
                                hidden=tuple(start.config()["hidden"]), terminate=terminate)
    t0 = time.perf_counter()
    # as train_adversarial: the global generators seeded (sacred does it), the reward net
    # built, then the generator (PPO seeds them again and the copies' first episodes)
    torch.manual_seed(seed)
    np.random.seed(seed)
    venv = im["DummyVecEnv"]([functools.partial(TrainingEnv, task, terminate)
                              for _ in range(used["num_vec"])])
    reward_net = im["reward_nets"].NormalizedRewardNet(
        im["reward_nets"].BasicRewardNet(venv.observation_space, venv.action_space,
                                         normalize_input_layer=im["networks"].RunningNorm),
        im["networks"].RunningNorm)
    gen = make_generator(venv, start, seed, used)
    curve_seconds = [0.0]
    with tempfile.TemporaryDirectory(prefix="imitation-gail-") as log_dir:
        trainer = im["gail"].GAIL(
            demonstrations=trajs, demo_batch_size=used["demo_batch_size"], venv=venv,
            gen_algo=gen, reward_net=reward_net, log_dir=log_dir,
            n_disc_updates_per_round=used["n_disc_updates_per_round"],
            gen_replay_buffer_capacity=used["gen_replay_buffer_capacity"],
            allow_variable_horizon=used["allow_variable_horizon"],
            custom_logger=im["logger"].configure(log_dir, format_strs=[]))   # no tables

        def checkpoint(round_: int) -> None:
            if curve is None:
                return
            c0 = time.perf_counter()
            # the run's generators (torch's and NumPy's global ones: SB3's action noise,
            # imitation's batches) are left as they were, so a curve does not change the run
            np_state = np.random.get_state()
            with torch.random.fork_rng(devices=[]):
                curve({"env_steps": (round_ + 1) * trainer.gen_train_timesteps},
                      from_sb3(trainer.policy.state_dict(), start))
            np.random.set_state(np_state)
            curve_seconds[0] += time.perf_counter() - c0

        trainer.train(int(steps), callback=checkpoint)
        interactions = int(gen.num_timesteps)
        policy = from_sb3(trainer.policy.state_dict(), start)
    venv.close()
    return policy, {"train_seconds": time.perf_counter() - t0,
                    "curve_seconds": curve_seconds[0], "interactions": interactions,
                    "settings": used, "deviations": deviations}


# -- the benchmark ---------------------------------------------------------------------------------

def _ours(task: str, part: str, seed: int, b, steps: int) -> dict:
    """Our runs of (task, part, seed) in the competence study's result file
    (``competence.json``, the aggregate of its cells at today's configurations) when it was
    made at budget ``b`` (which sets the start): the start's scaled return any learner
    recorded there (every learner starts from the same policy) and, if the study's runs are
    ``steps`` long, our GAIL's numbers."""
    out = {"gail": None, "stored_start": None, "source": "competence.json"}
    try:
        result = read_result("competence.json")
    except FileNotFoundError:
        return {**out, "source": "competence.json has not been made on this checkout"}
    if result.get("budget") != b.name:
        return {**out, "source": f"competence.json is at budget {result.get('budget')}"}
    same_length = result.get("steps", {}).get(part) == steps
    if not same_length:
        out["source"] += f" (its {part} runs are {result.get('steps', {}).get(part)} long)"
    for o in result.get("observations", []):
        if (o["task"], o["seed"], o["part"]) != (task, seed, part):
            continue
        if out["stored_start"] is None:
            out["stored_start"] = {"learner": o["row"], "scaled_return": o["start"]}
        if o["row"] == "gail" and same_length:
            out["gail"] = {k: o[k] for k in ("start", "final", "curve", "curve_steps",
                                             "train_seconds")}
    return out


def default_part(task: str) -> str:
    """The competence study's part on ``task``: "keep" where it runs it, else "learn"."""
    return "keep" if task in KEEP_TASKS else "learn"


@fast.on()   # our parts (the BC start, every evaluation) as the sweep's workers run them
def run(task: str, seeds, *, part: str | None = None, steps: int | None = None,
        b=None, curve_points: int | None = None, n_demos: int | None = None,
        eval_episodes: int | None = None) -> dict:
    """Per seed: the competence start, imitation's GAIL from it, both scored by our
    evaluation, beside our GAIL's stored cell.  Defaults are the competence study's at
    budget ``b`` (the current one): its part on ``task``, steps, demonstrations, evaluation
    and checkpoint curve (``curve_points=0``: none).  On the fast path, as the study's cells
    run: its rollouts' NumPy forward moves a mean action by float32 rounding, enough to move
    a score in the fourth digit (hopper's start, seed 0: 1.00047 there, 1.00009 on the
    reader's path), so only there is the start's score the stored cells'."""
    b = b or _budget.current()
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("give at least one seed")
    part = part or default_part(task)
    if part not in ("keep", "learn"):
        raise ValueError(f"part must be 'keep' or 'learn', got {part!r}")
    steps = int(steps or (b.competence_keep_steps if part == "keep"
                          else b.competence_learn_steps))
    start_epochs = b.bc_max_epochs if part == "keep" else b.competence_weak_epochs
    n_demos = n_demos or N_DEMOS
    eval_episodes = eval_episodes or b.competence_eval_episodes
    curve_points = b.competence_curve_points if curve_points is None else curve_points
    eval_seed = STUDY_EVAL_SEED
    terminate = TERMINATE.get(task)
    demos = _store.load_demos(task, n_trajectories=n_demos)

    def evaluate(policy, n_episodes):   # as competence.run_cell scores
        return evaluate_policy(task, policy, None, n_episodes=n_episodes, seed=eval_seed,
                               divergences=False)

    rows = []
    for seed in seeds:
        t0 = time.perf_counter()
        start = _bc.warm_start_policy(demos, seed, max_epochs=start_epochs)
        _base.set_start_noise(start, _base.START_LOG_STD)
        start_seconds = time.perf_counter() - t0
        curve = (CheckpointCurve(lambda p: evaluate(p, b.competence_curve_episodes), steps,
                                 curve_points) if curve_points else None)
        policy, info = imitation_gail(task, demos, copy.deepcopy(start), seed, steps,
                                      terminate=terminate, curve=curve)
        s, f = evaluate(start, eval_episodes), evaluate(policy, eval_episodes)
        ours = _ours(task, part, seed, b, steps)
        stored = ours["stored_start"]
        # the same start scored alike gives the same number, to the bit
        ours["same_start"] = (None if stored is None
                              else stored["scaled_return"] == s["scaled_return"])
        rows.append({
            "seed": seed, "start": s["scaled_return"], "final": f["scaled_return"],
            "start_return": s["return"], "final_return": f["return"],
            "curve": curve.points if curve else [], "interactions": info["interactions"],
            "train_seconds": info["train_seconds"], "curve_seconds": info["curve_seconds"],
            "seconds_per_10k": 1e4 * (info["train_seconds"] - info["curve_seconds"])
                               / info["interactions"],
            "start_seconds": start_seconds, "ours": ours})
        settings_used, deviations = info["settings"], info["deviations"]
    return {"task": task, "part": part, "budget": b.name, "steps": steps, "n_demos": n_demos,
            "start_epochs": start_epochs, "start_log_std": _base.START_LOG_STD,
            "eval_episodes": eval_episodes, "eval_seed": eval_seed,
            "curve_points": curve_points, "curve_episodes": b.competence_curve_episodes,
            "terminate": terminate, "recommended": RECOMMENDED[task],
            "settings": settings_used, "deviations": deviations,
            "not_applied": {"competence.FIXES['gail']": OUR_GAIL_FIXES,
                            "why": "our GAIL's fixes, not imitation's settings (imitation "
                                   "keeps SB3's advantage normalisation and shows its "
                                   "discriminator the demonstrations' actions as recorded)"},
            "rows": rows}


# What must agree for two runs' rows to share one result file (``--add``): everything that
# decides a row's numbers, not when or by which revision it ran.
_PROVENANCE = ("command", "seeds", "revision", "revisions", "time", "platform", "rows")


def merged(old: dict, new: dict, new_command: str) -> dict:
    """``old`` (a stored result) with ``new``'s rows added: a seed in both takes ``new``'s
    row.  Refused, naming the field, when any setting differs (two protocols in one file
    would pair rows that are not comparable)."""
    for key in sorted((set(old) | set(new)) - set(_PROVENANCE) - {"benchmark"}):
        if old.get(key) != new.get(key):
            raise ValueError(f"cannot add these rows: {key!r} is {new.get(key)!r} here and "
                             f"{old.get(key)!r} in the stored file; write another --out")
    rows = {r["seed"]: r for r in old["rows"]}
    rows.update({r["seed"]: r for r in new["rows"]})
    return {**new, "rows": [rows[s] for s in sorted(rows)],
            "command": f"{old['command']} ; then {new_command}",
            "seeds": sorted(rows),
            "revisions": sorted(set(_revisions(old)) | {new.get("revision")} - {None})}


def _revisions(rec: dict) -> list[str]:
    """The revisions a stored file's rows ran at: its ``revisions`` (a list, or a mapping of
    seeds to revision as an early hand-merged file has it), else its ``revision``."""
    r = rec.get("revisions", [rec.get("revision")])
    return [x for x in (r.values() if isinstance(r, dict) else r) if x is not None]


def side_path(out, seeds) -> Path:
    """Where a run's own result goes when it cannot be added to ``out``: beside it, named by
    its seeds, so that no computed row is lost."""
    out = Path(out)
    return out.with_name(f"{out.stem}.seeds-{'-'.join(map(str, seeds))}{out.suffix}")


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(prog="python -m dc_lesson.perf.imitation_gail",
                                description=" ".join(__doc__.split("\n")[:2]),
                                epilog=__doc__[__doc__.index("imitation is not a dependency"):],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--task", default="hopper", choices=sorted(RECOMMENDED))
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--steps", type=int, default=None,
                   help="environment interactions (default: the competence study's for the part)")
    p.add_argument("--part", choices=("keep", "learn"), default=None,
                   help="the competence start: keep (BC to bc_max_epochs) or learn (the weak "
                        "start); default: the study's part on the task (hopper keep, "
                        "halfcheetah learn)")
    p.add_argument("--budget", default=None, help="the budget whose competence sizes apply "
                                                  "(default: DC_LESSON_BUDGET, lesson)")
    p.add_argument("--curve-points", type=int, default=None,
                   help="checkpoint evaluations (default: the study's; 0: none)")
    p.add_argument("--out", default=None, help="write the result JSON here")
    p.add_argument("--add", action="store_true",
                   help="add these seeds' rows to the --out file already there (its settings "
                        "must be these; a seed in both is replaced)")
    args = p.parse_args(argv)
    if args.add and not (args.out and Path(args.out).exists()):
        p.error(f"--add needs an existing --out file (got {args.out!r}): run without --add "
                "to write a new one")
    if args.add:   # before the compute: the settings the arguments decide must agree
        stored = read_result(args.out)
        asked = {"task": args.task, "part": args.part or default_part(args.task)}
        for key, value in asked.items():
            if stored.get(key) != value:
                p.error(f"--add: {key} is {value!r} here and {stored.get(key)!r} in "
                        f"{args.out}; write another --out")
    ready(args.out, _imitation)
    b = _budget.get(args.budget) if args.budget else _budget.current()
    out = run(args.task, args.seeds, part=args.part, steps=args.steps, b=b,
              curve_points=args.curve_points)
    for r in out["rows"]:
        ours = r["ours"]["gail"]
        print(f"imitation GAIL {args.task} seed {r['seed']}: scaled return {r['start']:.3f} -> "
              f"{r['final']:.3f} in {r['interactions']:,} interactions, "
              f"{r['train_seconds']:.0f} s ({r['seconds_per_10k']:.1f} s / 10k)"
              + (f"; ours {ours['start']:.3f} -> {ours['final']:.3f}" if ours else
                 "; ours: no stored GAIL cell")
              + {True: " (the same start as ours)", False: " (NOT the start of our cells)",
                 None: ""}[r["ours"]["same_start"]])
    if args.out:
        command = "python -m dc_lesson.perf.imitation_gail " + " ".join(
            argv if argv is not None else sys.argv[1:])
        payload, seeds = {"benchmark": "imitation_gail", **out}, args.seeds
        if args.add:
            stored = read_result(args.out)
            try:
                payload = merged(stored, {**payload, "revision": git_revision()}, command)
            except ValueError as e:   # keep the rows computed: they cost minutes each
                side = side_path(args.out, seeds)
                write_result(side, payload, command=command, seeds=seeds)
                p.exit(2, f"{p.prog}: {e}\nthis run's rows are in {side}\n")
            command, seeds = payload.pop("command"), payload.pop("seeds")
        write_result(args.out, payload, command=command, seeds=seeds)
    return out


if __name__ == "__main__":  # pragma: no cover
    main()
