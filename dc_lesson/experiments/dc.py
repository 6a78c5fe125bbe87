"""DC from the BC warm start on one task and seed, both policies evaluated alike: the run
behind the hopper ablations' DC cells (``dc_ablation``, ``dc_lr``, through
:mod:`dc_lesson.experiments.studies._learners`).

:func:`run_one`:

1. trains BC's warm start (:func:`dc_lesson.algorithms.bc.warm_start`, the same start GAIL
   gets), or takes it from the caller's cache;
2. runs DC (:func:`dc_lesson.algorithms.dc.train`) from it with the budget's preset (and the
   cell's overrides: loops, iterations, learning rate, update rule);
3. evaluates the BC start and the DC policy on the same fresh episodes
   (:func:`dc_lesson.evaluation.evaluate_policy`): scaled return, EMD, KL, reverse KL against
   the reference, mode shares;
4. keeps the learning curve (mean reward, return of pi's finished episodes, parameter
   change, the pi-pi' gap, consensus ADMM's residuals), optional deterministic evaluations at
   checkpoints, and the wall times; a subsample of each policy's mode features goes to the
   caller's ``features`` dict.
"""

from __future__ import annotations

import json
import time

import numpy as np

from dc_lesson.algorithms import bc as _bc
from dc_lesson import budget as _budget
from dc_lesson import data as _data
from dc_lesson.algorithms import dc as _dc
from dc_lesson.algorithms.dc import DC_DEFAULTS, preset as dc_config
from dc_lesson import evaluation as _evaluation
# One format for the stored mode features of every imitation benchmark (keys task__method__seedN).
from dc_lesson.experiments.protocol import feature_key, subsample

FEATURES_KEPT = 2000            # mode features per (task, method, seed) in the .npz
CURVE_KEYS = ("env_steps", "reward_mean", "log_p_mean", "episode_return", "bc_nll",
              "param_change_l1", "pi_pi_prime_l1", "primal_residual", "dual_residual",
              "log_std")

def _sub(x, seed: int = 0) -> np.ndarray:
    return subsample(x, FEATURES_KEPT, seed)


def _curve(log: list[dict]) -> dict:
    rows = [r for r in log if r["kind"] == "iteration"]
    return {k: [None if (v := r.get(k)) is None or not np.isfinite(v) else round(float(v), 5)
                for r in rows] for k in CURVE_KEYS if any(k in r for r in rows)}


MEASURED = ("scaled_return", "return", "return_std", "emd", "kl", "rkl", "mode_shares")


def run_one(task: str, seed: int, budget: _budget.Budget, reference: _data.Demonstrations,
            *, config_overrides: dict | None = None, features: dict | None = None,
            bc_cache: dict | None = None, progress: bool = False,
            curve: tuple[int, int] | None = None) -> dict:
    """BC start and DC for one (task, seed); a row of the result file.

    ``bc_cache`` (a dict kept by the caller) holds the starts already trained, by (task, seed),
    with their evaluations and features: the caller must give one dict per (demonstrations,
    epochs, reference).  ``curve=(points, episodes)`` adds ``eval_curve``: the scaled return
    of ``episodes`` deterministic episodes at ``points`` evenly spaced interaction counts
    (:class:`~dc_lesson.evaluation.CheckpointCurve`; the run is unchanged by it)."""
    t0 = time.perf_counter()
    key = (task, seed)
    if bc_cache is not None and key in bc_cache:
        policy, demos, bc_row, bc_features = bc_cache[key]
        policy = _copy(policy)
        if features is not None and bc_features is not None:
            features[feature_key(task, "BC", seed)] = bc_features
    else:
        policy, demos, _ = _bc.warm_start(task, budget.il_demos, seed,
                                          max_epochs=budget.bc_max_epochs)
        ev = _evaluation.evaluate_policy(task, policy, reference,
                                         n_episodes=budget.il_eval_episodes, keep_features=True)
        bc_row = {k: ev[k] for k in MEASURED}
        bc_row["seconds"] = time.perf_counter() - t0
        bc_features = _sub(ev["features"], seed=seed)
        if features is not None:
            features[feature_key(task, "BC", seed)] = bc_features
        if bc_cache is not None:
            bc_cache[key] = (_copy(policy), demos, bc_row, bc_features)
    config = dc_config(budget, seed=seed, **(config_overrides or {}))
    checkpoints = None if curve is None else _evaluation.CheckpointCurve(
        lambda p: _evaluation.evaluate_policy(task, p, n_episodes=curve[1], divergences=False),
        config.loops * config.iterations * config.batch_size, curve[0])
    t1 = time.perf_counter()
    result = _dc.train(task, demos, config, policy=policy, progress=progress,
                       callback=checkpoints)
    pi, log = result.policy, result.log
    t2 = time.perf_counter()
    ev = _evaluation.evaluate_policy(task, pi, reference, n_episodes=budget.il_eval_episodes,
                                     keep_features=True)
    if features is not None:
        tag = "DC" if not config_overrides else "DC_" + "_".join(
            f"{k}-{v}" for k, v in sorted(config_overrides.items()))
        features[feature_key(task, tag, seed)] = _sub(ev["features"], seed=seed)
    flows = [r for r in log if r["kind"] == "flow"]
    return {"task": task, "seed": int(seed), "bc": bc_row,
            "dc": {**{k: ev[k] for k in MEASURED}, "train_seconds": t2 - t1,
                   "flow_seconds": float(sum(r["flow_seconds"] for r in flows)),
                   "env_steps": log[-1]["env_steps"]},
            "config": json.loads(config.to_json()), "flows": flows, "curve": _curve(log),
            **({} if checkpoints is None else {"eval_curve": checkpoints.points})}


def _copy(policy):
    import copy
    return copy.deepcopy(policy)


__all__ = ["CURVE_KEYS", "DC_DEFAULTS", "MEASURED", "dc_config", "run_one"]
