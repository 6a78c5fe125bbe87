"""GAIL from the BC warm start on one task and seed, both policies evaluated alike: the run
behind the ``gail_lr`` cell study (:mod:`dc_lesson.experiments.studies._learners`).

:func:`run_one`:

1. trains the BC warm start (:func:`dc_lesson.algorithms.bc.warm_start`) on the task's first
   ``n_demos`` demonstrations;
2. runs GAIL (:func:`dc_lesson.algorithms.gail.train`) from it for ``steps`` environment
   interactions, with those same demonstrations as the expert's pairs;
3. evaluates *both* policies, BC (the warm start) and GAIL, with
   :func:`dc_lesson.evaluation.evaluate_policy` (mean action, the same fresh episodes, against
   the given reference), so they are judged exactly as every other learner is.

Its row holds per policy the measures (scaled return, return, EMD, KL, RKL) and mode shares,
the training log's learning curve (the stochastic training episodes' return against
environment steps), optionally deterministic evaluations at checkpoints, the discriminator's
accuracies over the last tenth of training, and wall times; beside it, each policy's mode
features over its evaluation episodes.
"""

from __future__ import annotations

import copy
import time

import numpy as np

from dc_lesson.algorithms import bc as _bc
from dc_lesson import data as _data
from dc_lesson import evaluation as _evaluation
from dc_lesson.algorithms import gail as _gail
from dc_lesson.algorithms.gail import sized as gail_config

MEASURES = _evaluation.MEASURES
EVAL_SEED = _evaluation.EVAL_SEED


def learning_curve(log: list[dict]) -> dict:
    """The iterations in which training episodes ended: steps and their mean return."""
    rows = [r for r in log if r["n_episodes"] > 0]
    return {"steps": [int(r["steps"]) for r in rows],
            "episode_return": [round(float(r["episode_return"]), 3) for r in rows]}


def _measures(ev: dict) -> dict:
    return {k: ev[k] for k in ("scaled_return", "return", "return_std", "emd", "kl", "rkl",
                               "mode_shares")}


def run_one(task: str, seed: int, *, n_demos: int, steps: int, eval_episodes: int,
            reference: _data.Demonstrations, bc_max_epochs: int = 200,
            config: _gail.GAILConfig | None = None, eval_seed: int = EVAL_SEED,
            progress: bool = False, bc_cache: dict | None = None,
            curve: tuple[int, int] | None = None) -> tuple[dict, dict]:
    """One seed on one task: BC warm start, GAIL from it, both evaluated.

    Returns ``(row, features)``: the row of the result file and ``{"BC": ..., "GAIL": ...}``,
    each policy's mode features over its evaluation episodes (all of them).  ``bc_cache`` (a
    dict kept by the caller, one per (demonstrations, epochs, evaluation)) holds the starts
    already trained and evaluated, by (task, seed).  ``curve=(points, episodes)`` adds
    ``eval_curve``, the scaled return of deterministic evaluations at ``points`` evenly spaced
    interaction counts (:class:`~dc_lesson.evaluation.CheckpointCurve`).
    """
    t0 = time.perf_counter()
    if bc_cache is not None and (task, seed) in bc_cache:
        policy, demos, ev_bc, bc_seconds = copy.deepcopy(bc_cache[(task, seed)])
        t1 = t0 + bc_seconds
    else:
        policy, demos, _ = _bc.warm_start(task, n_demos, seed, max_epochs=bc_max_epochs)
        t1 = time.perf_counter()
        ev_bc = _evaluation.evaluate_policy(task, policy, reference, n_episodes=eval_episodes,
                                            seed=eval_seed, keep_features=True)
        if bc_cache is not None:
            bc_cache[(task, seed)] = copy.deepcopy((policy, demos, ev_bc, t1 - t0))
    cfg = config or gail_config(steps, seed)
    checkpoints = None if curve is None else _evaluation.CheckpointCurve(
        lambda p: _evaluation.evaluate_policy(task, p, n_episodes=curve[1], seed=eval_seed,
                                              divergences=False),
        int(cfg.ppo.n_updates * cfg.ppo.batch_size), curve[0])
    t2 = time.perf_counter()
    start = copy.deepcopy(policy) if cfg.bc_warm_start else None   # None: a fresh policy
    result = _gail.train(task, demos, cfg, policy=start, progress=progress,
                         callback=checkpoints)
    policy, log = result.policy, result.log
    t3 = time.perf_counter()
    ev_gail = _evaluation.evaluate_policy(task, policy, reference, n_episodes=eval_episodes,
                                          seed=eval_seed, keep_features=True)
    last = log[-max(1, len(log) // 10):]     # the last tenth of the iterations
    row = {"task": task, "seed": int(seed), "n_demos": int(n_demos),
           "steps": int(cfg.ppo.n_updates * cfg.ppo.batch_size),
           "BC": _measures(ev_bc), "GAIL": _measures(ev_gail),
           "curve": learning_curve(log),
           **({} if checkpoints is None else {"eval_curve": checkpoints.points}),
           "disc_final": {k: float(np.mean([r[k] for r in last])) for k in
                          ("acc_expert", "acc_learner", "d_expert", "d_learner", "disc_loss",
                           "reward_mean", "reward_std")},
           "steps_per_second": float(np.mean([r["steps_per_second"] for r in log])),
           "bc_seconds": t1 - t0, "gail_seconds": t3 - t2,
           "eval_seconds": ev_bc["eval_seconds"] + ev_gail["eval_seconds"],
           "wall_seconds": time.perf_counter() - t0}
    return row, {"BC": ev_bc["features"], "GAIL": ev_gail["features"]}


__all__ = ["EVAL_SEED", "MEASURES", "gail_config", "learning_curve", "run_one"]
