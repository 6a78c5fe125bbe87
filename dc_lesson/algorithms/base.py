"""What every learner shares: the result it returns, its input checks and its checkpoints.

Every learner of :data:`dc_lesson.algorithms.ALGORITHMS` is called the same way::

    result = algo.train(task, demos, config, policy=None, progress=True,
                        checkpoint=None, callback=None)

and returns a :class:`TrainResult`: the trained policy, one log row per iteration, and the
other models it trained (``value``, ``discriminator``, ``flow``, ...).  Its config is a frozen
dataclass with ``preset(budget, seed)`` beside it.

A resumable run saves everything it needs to go on exactly as if it had not stopped (networks,
optimisers, random generators, the environments' episode state, the log) with
:func:`save_run`, and :func:`load_run` restores it after checking that the file was made for
the same task, configuration and network shapes.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np
import torch

from dc_lesson import tasks as _tasks
from dc_lesson.density.softflow import SoftFlowConfig
from dc_lesson.nn.checkpoint import PolicyFileError, atomic_torch_save, load_checked


@dataclasses.dataclass
class TrainResult:
    """What a learner's ``train`` returns.

    Attributes:
        policy: the trained :class:`~dc_lesson.nn.policies.GaussianPolicy`.
        log: one dict per iteration (per epoch for BC); the keys are each learner's own.
        models: the other models the learner trained, by name (``value``, ``discriminator``,
            ``flow``, ...); empty for BC.
        algorithm: the registry name of the learner.
    """

    policy: Any
    log: list
    models: dict = dataclasses.field(default_factory=dict)
    algorithm: str = ""


# The one exploration rule of every RL learner's warm start (issue 38): the start's log-std is
# set to this before training. Measured (issue 38's probe, December 2026: cartpole from a
# perfect BC start, 20,000 interactions, 3 seeds): at the BC warm start's default -0.5
# (std 0.61), GPRIL lost its start on 3 of 3 seeds and NDI on 1 of 3; at -2 (std 0.14,
# GAIL's tuned value since round 2) GAIL, DRIL, PWIL, NDI, GPRIL and DC kept it on 3 of 3
# and PPO ended at 0.92 / 0.92 / 1.00. The competence study judges the rule at full length.
START_LOG_STD = -2.0


def seed_streams(seed: int, *names: str) -> tuple[int, ...]:
    """One run's seed split into independent streams, one per name, in the order named (the
    names document the split; each learner lists its own, e.g. ``"init", "sample", "env"``).

    The streams are the words of NumPy's ``SeedSequence(seed)``: statistically independent,
    and the first k words do not depend on how many are drawn, so a learner that adds a
    stream at the end changes none of the earlier ones (``tests/test_algorithms.py``)."""
    if len(set(names)) != len(names) or not names:
        raise ValueError(f"seed_streams needs distinct stream names, got {names}")
    return tuple(int(s) for s in np.random.SeedSequence(seed).generate_state(len(names)))


def set_start_noise(policy, log_std: float | None) -> None:
    """Sets a given start policy's exploration noise (its log-std) to ``log_std`` in place;
    nothing for None (the start's own noise is kept), no policy, or a mixture (which has its
    own spreads). Every RL learner's ``start_log_std`` field goes through here."""
    if policy is None or log_std is None or not getattr(policy, "gaussian", False):
        return
    with torch.no_grad():
        policy.log_std.fill_(float(log_std))


def unset_dropped(d: dict, names=("start_log_std", "value_warmup")) -> dict:
    """``d`` without the fields in ``names`` whose value is None: a knob added after a study's
    cells were listed names them only when set, so the stored cells keep their identity."""
    return {k: v for k, v in d.items() if not (k in names and v is None)}


def check_flow(config) -> None:
    """A learner config's nested flow settings (``config.flow``): SoftFlow's config, with no
    seed of its own (the fit takes a stream of the learner's ``seed``: refused, not ignored)."""
    name = type(config).__name__
    if not isinstance(config.flow, SoftFlowConfig):
        raise TypeError(f"{name}.flow must be a softflow.SoftFlowConfig, got {type(config.flow)}")
    if config.flow.seed != 0:
        raise ValueError(f"{name}.flow.seed is not read: the flow's fit takes a stream of "
                         f"{name}.seed; set that instead")


def stored_flow(flow: dict, names: dict[str, str], default) -> dict:
    """A learner's nested flow settings (``dataclasses.asdict`` of a SoftFlowConfig) in the
    flat form its stored cells were listed with: each field of ``names`` (stored name -> field)
    under its stored name, and under ``"flow"`` only the fields that differ from ``default``
    (never the seed, which the learner's own seed decides).  A default flow therefore stores
    exactly the flat names, and the cells listed before the nesting keep their identity; a
    change of any other flow setting still makes a new cell."""
    flow = json.loads(json.dumps(flow))   # tuples as lists, as the stored JSON has them
    out = {stored: flow[field] for stored, field in names.items()}
    kept = set(names.values()) | {"seed"}
    base = json.loads(json.dumps(dataclasses.asdict(default)))
    rest = {k: v for k, v in flow.items() if k not in kept and v != base[k]}
    if rest:
        out["flow"] = rest
    return out


class LearnerInputError(ValueError):
    """Inputs a learner cannot train with (a policy or demonstrations of another task, ...)."""


def check_inputs(task: str, demos=None, policy=None) -> None:
    """Refuses demonstrations or a starting policy whose task or sizes do not fit ``task``."""
    spec = _tasks.spec(task)
    demo_task = getattr(demos, "task", None)
    if demo_task is not None and demo_task != task:
        raise LearnerInputError(f"the demonstrations are of {demo_task!r}, not {task!r}: load "
                                f"them with data.load_demos({task!r})")
    if policy is not None:
        cfg = policy.config()
        if (cfg["obs_dim"], cfg["act_dim"]) != (spec.obs_dim, spec.act_dim):
            raise LearnerInputError(
                f"the policy is built for (obs, act) dims ({cfg['obs_dim']}, {cfg['act_dim']}); "
                f"{task} has ({spec.obs_dim}, {spec.act_dim}): start from a policy of {task}")


def checkpoint_fix(path) -> str:
    """What to do about a checkpoint that cannot be resumed: start the run again."""
    return (f"delete {path} to start the run from the beginning (for an expert: dc-lesson "
            f"expert train --task NAME --restart)")


def check_checkpoint(path, ckpt: dict, task: str, saved: dict, now: dict,
                     networks: dict | None = None, what: str = "checkpoint") -> None:
    """The checks every resumable run makes before loading: the task, the configuration
    (``saved`` against ``now``, both JSON-able dicts) and the shape of each network
    (``networks`` maps a name whose ``NAME_args`` the checkpoint holds to the network)."""
    if ckpt["task"] != task:
        raise PolicyFileError(f"{what} {path} is of task {ckpt['task']!r}, not {task!r}; "
                              f"{checkpoint_fix(path)}")
    if saved != now:
        diff = {k: (saved.get(k), now.get(k)) for k in saved.keys() | now.keys()
                if saved.get(k) != now.get(k)}
        raise PolicyFileError(f"{what} {path} was made with another configuration "
                              f"(saved, now): {diff}; use the saved configuration, or "
                              f"{checkpoint_fix(path)}")
    for name, net in (networks or {}).items():
        if json.loads(ckpt[f"{name}_args"]) != net.config():
            raise PolicyFileError(f"{what} {path} holds a {name} network built as "
                                  f"{ckpt[f'{name}_args']}, not {json.dumps(net.config())}")


def save_run(path, fmt: str, version: int, *, task: str, config_json: str, update: int,
             networks: dict, optimizers: dict, generators: dict[str, torch.Generator],
             envs, log: list, **extra) -> None:
    """Writes a resumable run atomically: per network ``NAME_args`` and ``NAME`` (its
    state_dict), per optimiser and generator its state under its name, the environments' state,
    the log as JSON, and any ``extra`` entries as they are."""
    obj = {"format": fmt, "version": version, "task": task, "config": config_json,
           "update": update, "envs": envs.state_dict(), "log": json.dumps(log), **extra}
    for name, net in networks.items():
        obj[f"{name}_args"] = json.dumps(net.config())
        obj[name] = net.state_dict()
    for name, opt in optimizers.items():
        obj[name] = opt.state_dict()
    for name, gen in generators.items():
        obj[name] = gen.get_state()
    atomic_torch_save(obj, path)


def load_run(path, fmt: str, version: int, what: str, *, task: str, saved_config, now_config,
             networks: dict, optimizers: dict, generators: dict, envs) -> tuple[int, list, dict]:
    """Restores a run written by :func:`save_run` in place; returns (update, log, the file's
    dict).  ``saved_config(ckpt)`` turns the stored config into the dict compared with
    ``now_config``."""
    ckpt = load_checked(path, fmt, version, what, checkpoint_fix(path))
    check_checkpoint(path, ckpt, task, saved_config(ckpt), now_config, networks, what)
    for name, net in networks.items():
        net.load_state_dict(ckpt[name])
    for name, opt in optimizers.items():
        opt.load_state_dict(ckpt[name])
    for name, gen in generators.items():
        gen.set_state(ckpt[name])
    envs.load_state_dict(ckpt["envs"])
    return int(ckpt["update"]), json.loads(ckpt["log"]), ckpt


__all__ = ["LearnerInputError", "TrainResult", "check_checkpoint", "check_inputs", "checkpoint_fix", "load_run",
           "save_run"]
