"""DC against its BC start on the multi-mode tasks, and DC's ablations: ``dc-lesson bench dc*``.

``dc-lesson bench dc --out data/results/dc_modes.json`` (:func:`run`): for each task and seed of
the imitation protocol (``budget.il_*``: the first ``il_demos`` demonstrations, ``il_steps``
environment interactions, ``il_eval_episodes`` evaluation episodes), it

1. trains BC's warm start (:func:`dc_lesson.bc.warm_start`, the same start GAIL gets);
2. runs DC (:func:`dc_lesson.dc.train`) from it with ``DC_DEFAULTS`` and as many iterations
   per loop as the interaction budget allows;
3. evaluates the BC start and the DC policy on the same fresh episodes
   (:func:`dc_lesson.evaluation.evaluate_policy`): scaled return, EMD, KL, reverse KL against
   all the task's demonstrations, mode shares;
4. keeps the learning curve (mean reward, return of pi''s finished episodes, parameter change)
   and the wall times; a subsample of each policy's mode features goes to an ``.npz`` beside
   the JSON file, for the coverage plots, in ``bench gail``'s format (methods ``BC``, ``DC``
   and ``expert``; :func:`load_features`).

``dc-lesson bench dc-ablation --out data/results/dc_ablation.json`` (:func:`run_ablation`), on
one task: the loop-number ablation (the paper's Figure 3: L = 1..4 loops of a fixed number of
iterations, and one loop with as many iterations as the longest), and the paper's averaging
against consensus ADMM over the seeds.

``dc-lesson bench dc-lr --out data/results/dc_lr.json`` (:func:`run_lr`): final scaled return
for each learning rate of the sweep (the paper's Figure 4), on the locomotion task of GAIL's
sweep.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time

import numpy as np
import torch

from dc_lesson.algorithms import bc as _bc
from dc_lesson import budget as _budget
from dc_lesson import data as _data
from dc_lesson.algorithms import dc as _dc
from dc_lesson.algorithms.dc import DC_DEFAULTS, preset as dc_config
from dc_lesson import evaluation as _evaluation
# One format for the stored mode features of every imitation benchmark (keys task__method__seedN).
from dc_lesson.experiments.protocol import (BenchInputError, check_count, feature_key,
                                           features_path, load_features, save_features,
                                           subsample)
from dc_lesson.storage import write_result

TASKS = ("reacher4", "reacher2", "halfcheetah2")
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


def summarise(runs: list[dict], methods=("bc", "dc")) -> list[dict]:
    """Per task and method: mean and sample std (ddof = 1; 0 with one seed) over seeds."""
    out = []
    for task in dict.fromkeys(r["task"] for r in runs):
        rows = [r for r in runs if r["task"] == task]
        for m in methods:
            entry = {"task": task, "method": m, "n_seeds": len(rows)}
            for k in ("scaled_return", "return", "emd", "kl", "rkl"):
                v = np.array([r[m][k] for r in rows], np.float64)
                entry[f"{k}_mean"] = float(v.mean())
                entry[f"{k}_std"] = float(v.std(ddof=1)) if len(v) > 1 else 0.0
            shares = [r[m]["mode_shares"] for r in rows if r[m]["mode_shares"]]
            if shares:
                entry["mode_shares_mean"] = {k: float(np.mean([s[k] for s in shares]))
                                             for k in shares[0]}
            out.append(entry)
    return out


def format_table(summary: list[dict]) -> str:
    lines = [f"{'task':<13}{'method':<8}{'scaled return':>17}{'EMD':>17}{'KL':>17}{'RKL':>17}"]
    for s in summary:
        cells = "".join(f"{s[k + '_mean']:>9.3f} ± {s[k + '_std']:<5.3f}"
                        for k in ("scaled_return", "emd", "kl", "rkl"))
        lines.append(f"{s['task']:<13}{s['method']:<8}{cells}")
    return "\n".join(lines)


def _reference_features(tasks, features: dict) -> dict:
    refs = {}
    for task in tasks:
        refs[task] = _data.load_demos(task)
        features[feature_key(task, "expert")] = _sub(refs[task].mode_features)
    return refs


def _write(out, record: dict, features: dict, command: str, seeds) -> None:
    if features:   # first, so a result file never points at missing features
        save_features(features_path(out), features)
    path = write_result(out, record, command=command, seeds=list(seeds))
    print(f"wrote {path}")


def _progress(runs, label):
    r = runs[-1]
    print(f"{label} {r['task']:<13} seed {r['seed']}: BC {r['bc']['scaled_return']:.3f} / EMD "
          f"{r['bc']['emd']:.3f}  ->  DC {r['dc']['scaled_return']:.3f} / EMD "
          f"{r['dc']['emd']:.3f}  ({r['dc']['train_seconds']:.0f} s)", flush=True)


def run(tasks=TASKS, budget: _budget.Budget | None = None, *, out=None, command: str = "",
        threads: int = 1) -> dict:
    """The main benchmark (module docstring)."""
    budget = budget or _budget.current()
    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    features: dict = {}
    start = time.perf_counter()
    try:
        refs = _reference_features(tasks, features)
        runs = []
        for task in tasks:
            for seed in budget.il_seeds:
                runs.append(run_one(task, seed, budget, refs[task], features=features))
                _progress(runs, "bench dc")
    finally:
        torch.set_num_threads(old)
    summary = summarise(runs)
    record = {"benchmark": "dc_modes", "tasks": list(tasks),
              "protocol": {"demos": budget.il_demos, "seeds": list(budget.il_seeds),
                           "env_steps": budget.il_steps,
                           "eval_episodes": budget.il_eval_episodes,
                           "bc_max_epochs": budget.bc_max_epochs,
                           "eval_seed": _evaluation.EVAL_SEED},
              "dc_config": json.loads(dc_config(budget).to_json()),
              "std": "sample standard deviation over seeds (ddof = 1)",
              "torch_threads": threads, "wall_seconds": time.perf_counter() - start,
              "summary": summary, "runs": runs}
    print(format_table(summary))
    if out is not None:
        _write(out, record, features, command, budget.il_seeds)
    return record


def run_ablation(task: str = "reacher4", budget: _budget.Budget | None = None, *,
                 loop_counts=(1, 2, 3, 4), out=None, command: str = "",
                 threads: int = 1) -> dict:
    """Figure 3 (loops) and consensus ADMM, on ``task``.

    Each of L loops runs ``il_steps / 4`` interactions' worth of iterations, so L = 4 spends
    the protocol's budget; "1 loop, long" runs as many iterations as L = 4 in one loop.  The
    loop ablation uses the first seed.  The ADMM runs use every protocol seed with the main
    benchmark's settings except ``update="admm"``: their averaging counterparts are the
    ``task`` runs of ``bench dc`` (same seeds and configuration), not run again here."""
    budget = budget or _budget.current()
    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    features: dict = {}
    start = time.perf_counter()
    bc_cache: dict = {}
    try:
        ref = _reference_features([task], features)[task]
        per_loop = dc_config(budget, loops=4).iterations
        seed = budget.il_seeds[0]
        loops = []
        for L in loop_counts:
            row = run_one(task, seed, budget, ref, bc_cache=bc_cache,
                          config_overrides={"loops": L, "iterations": per_loop})
            row["label"] = f"L = {L}"
            loops.append(row)
            _progress(loops, f"loops {L}")
        row = run_one(task, seed, budget, ref, bc_cache=bc_cache,
                      config_overrides={"loops": 1, "iterations": per_loop * max(loop_counts)})
        row["label"] = f"1 loop, {per_loop * max(loop_counts)} iterations"
        loops.append(row)
        _progress(loops, "1 loop long")
        admm = []
        for s in budget.il_seeds:
            row = run_one(task, s, budget, ref, bc_cache=bc_cache, features=features,
                          config_overrides={"update": "admm"})
            admm.append(row)
            _progress(admm, "admm")
    finally:
        torch.set_num_threads(old)
    record = {"benchmark": "dc_ablation", "task": task, "iterations_per_loop": per_loop,
              "loops": loops, "admm": admm,
              "admm_note": ("update='admm' (rho as in dc_config), otherwise the settings of "
                            "bench dc; compare with the same task's runs in dc_modes.json"),
              "admm_summary": summarise(admm, ("dc",))[0],
              "wall_seconds": time.perf_counter() - start, "torch_threads": threads}
    if out is not None:
        _write(out, record, features, command, budget.il_seeds)
    return record


LR_TASK = "halfcheetah"   # GAIL's sweep's task (bench_gail.LR_TASK)


def run_lr(task: str = LR_TASK, lrs=None, budget: _budget.Budget | None = None, *,
           seeds=None, steps: int | None = None, out=None, command: str = "",
           threads: int = 1) -> dict:
    """Figure 4 for DC: final scaled return for each learning rate (both copies' AdamW), with
    the sweep's sizes from the budget (``lr_sweep_*``, shared with GAIL's sweep)."""
    budget = budget or _budget.current()
    lrs = tuple(lrs if lrs is not None else budget.lr_sweep_lrs)
    seeds = tuple(seeds if seeds is not None else budget.lr_sweep_seeds)
    steps = check_count("steps", budget.lr_sweep_steps if steps is None else steps)
    if not seeds or not lrs or not all(lr > 0 and math.isfinite(lr) for lr in lrs):
        raise BenchInputError(f"bench dc-lr needs a seed and positive learning rates, got "
                              f"seeds {seeds}, rates {lrs}")
    for s in seeds:
        check_count("a seed", s, minimum=0)
    sweep_budget = dataclasses.replace(budget, il_steps=steps)
    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    start = time.perf_counter()
    bc_cache: dict = {}
    rows = []
    try:
        ref = _data.load_demos(task)
        for lr in lrs:
            for s in seeds:
                row = run_one(task, s, sweep_budget, ref, bc_cache=bc_cache,
                              config_overrides={"lr": float(lr)})
                row["lr"] = float(lr)
                rows.append(row)
                _progress(rows, f"lr {lr:g}")
    finally:
        torch.set_num_threads(old)
    summary = [{"lr": float(lr),
                **{f"scaled_return_{k}": f(np.array([r["dc"]["scaled_return"] for r in rows
                                                     if r["lr"] == lr]))
                   for k, f in (("mean", np.mean), ("min", np.min), ("max", np.max))}}
               for lr in lrs]
    record = {"benchmark": "dc_lr", "task": task, "lrs": [float(x) for x in lrs],
              "seeds": list(seeds), "env_steps": steps, "summary": summary, "runs": rows,
              "bc_scaled_return": {str(s): bc_cache[(task, s)][2]["scaled_return"]
                                   for s in seeds},
              "wall_seconds": time.perf_counter() - start, "torch_threads": threads}
    for s in summary:
        print(f"lr {s['lr']:g}: scaled return {s['scaled_return_mean']:.3f} "
              f"[{s['scaled_return_min']:.3f}, {s['scaled_return_max']:.3f}]")
    if out is not None:
        _write(out, record, {}, command, seeds)
    return record


__all__ = ["DC_DEFAULTS", "load_features", "LR_TASK", "TASKS", "dc_config", "format_table", "run", "run_ablation",
           "run_lr", "run_one", "summarise"]
