"""GAIL on the multi-mode tasks, and its learning-rate robustness: ``dc-lesson bench gail`` and
``dc-lesson bench gail-lr``.

``bench gail`` (:func:`run`): for each task (``reacher4``, ``reacher2``, ``halfcheetah2``) and
each seed of the imitation protocol (``budget.il_seeds``), it

1. trains the BC warm start (:func:`dc_lesson.bc.warm_start`) on the task's first
   ``budget.il_demos`` demonstrations;
2. runs GAIL (:func:`dc_lesson.gail.train`) from it for ``budget.il_steps`` environment
   interactions, with those same demonstrations as the expert's pairs;
3. evaluates *both* policies, BC (the warm start) and GAIL, with
   :func:`dc_lesson.evaluation.evaluate_policy` (mean action, the same ``il_eval_episodes``
   fresh episodes, all the task's demonstrations as the reference), so they are judged
   exactly as BC's benchmark and DC's are.

The JSON record holds per run the measures (scaled return, return, EMD, KL, RKL), the mode
shares, the training log's learning curve (the stochastic training episodes' environment
return against environment steps) and the discriminator's accuracy, and wall times; a summary
per (task, method) in the layout of the paper's Table I (mean and sample std over seeds).
Beside it, a ``.npz`` with the same stem holds the mode features for coverage plots: for every
run and method at most ``FEATURES_PER_RUN`` steps (a seeded subsample, float32), and as many
of the expert's demonstration features per task (:func:`load_features`, no pickles).

``bench gail-lr`` (:func:`run_lr`): GAIL from the BC warm start on one locomotion task
(``halfcheetah``) for each learning rate of ``budget.lr_sweep_lrs`` (one rate for the policy,
its critic and the discriminator: :meth:`GAILConfig.with_lr`) and each seed of
``budget.lr_sweep_seeds``, ``budget.lr_sweep_steps`` interactions each; the final scaled return
of each run (and BC's, the common start) is stored: the paper's Figure 4 for GAIL.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import math
import time

import numpy as np

from dc_lesson.algorithms import bc as _bc
from dc_lesson import data as _data
from dc_lesson import evaluation as _evaluation
from dc_lesson.algorithms import gail as _gail
from dc_lesson.algorithms.gail import sized as gail_config
from dc_lesson.experiments.protocol import (BenchInputError, check_count, check_eval_seeds,
                                           default, feature_key,
                                           features_path, load_features, save_features,
                                           subsample as _subsample)

TASKS = ("reacher4", "reacher2", "halfcheetah2")
LR_TASK = "halfcheetah"
METHODS = ("BC", "GAIL")
MEASURES = _evaluation.MEASURES
FEATURES_PER_RUN = 2000
EVAL_SEED = _evaluation.EVAL_SEED
FINGER_RADIUS = 0.01   # the reacher's fingertip sphere (dm_control's reacher.xml; a test checks)


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


def summarise(runs: list[dict]) -> list[dict]:
    """Per (task, method): mean and sample std (ddof = 1; 0 with one seed) over seeds of each
    measure, and the mean mode shares."""
    out = []
    tasks = list(dict.fromkeys(r["task"] for r in runs))
    for task in tasks:
        rows = [r for r in runs if r["task"] == task]
        for method in METHODS:
            s = {"task": task, "method": method, "n_seeds": len(rows)}
            for m in MEASURES:
                v = np.array([r[method][m] for r in rows], dtype=np.float64)
                s[f"{m}_mean"] = float(v.mean())
                s[f"{m}_std"] = float(v.std(ddof=1)) if len(v) > 1 else 0.0
            if rows[0][method]["mode_shares"] is not None:
                s["mode_shares_mean"] = {k: float(np.mean([r[method]["mode_shares"][k]
                                                           for r in rows]))
                                         for k in rows[0][method]["mode_shares"]}
            out.append(s)
    return out


def format_table(summary: list[dict]) -> str:
    """The summary in the layout of the paper's Table I (plus the scaled return)."""
    head = (f"{'task':<14}{'approach':<10}{'EMD':>16}{'KL':>16}{'RKL':>16}"
            f"{'scaled return':>18}  modes")
    lines = [head, "-" * (len(head) + 30)]
    for r in summary:
        pm = lambda m, w, p: f"{r[m + '_mean']:.{p}f} ± {r[m + '_std']:.{p}f}".rjust(w)  # noqa
        modes = ", ".join(f"{k} {v:.2f}" for k, v in r.get("mode_shares_mean", {}).items())
        lines.append(f"{r['task']:<14}{r['method']:<10}{pm('emd', 16, 3)}{pm('kl', 16, 2)}"
                     f"{pm('rkl', 16, 2)}{pm('scaled_return', 18, 3)}  {modes}")
    return "\n".join(lines)


def pooled_features(features: dict, task: str, method: str) -> np.ndarray:
    """One method's features on one task, pooled over the seeds."""
    keys = sorted(k for k in features if k.startswith(feature_key(task, method) + "__seed"))
    if not keys:
        raise KeyError(f"no {method} features of {task} in the file")
    return np.concatenate([features[k] for k in keys])


def on_target(features: np.ndarray, n_targets: int) -> dict:
    """Where a reacher policy is paid: the share of steps with the fingertip inside a target
    (within target + finger radius, as the task's reward counts it), and how those steps split
    over the targets (``None`` when no step is on one).  The evaluation's mode shares name the
    *nearest* target of each episode's second half, however far away; this counts arrivals."""
    from dc_lesson.tasks import reacher
    targets = reacher.target_positions(n_targets)
    radius = reacher.TARGET_SIZE + FINGER_RADIUS
    d = np.linalg.norm(np.asarray(features)[:, None, :2] - targets[None], axis=-1)
    on = d.min(1) <= radius
    split = None
    if on.any():
        counts = np.bincount(d.argmin(1)[on], minlength=n_targets) / on.sum()
        split = dict(zip(reacher.target_colours(n_targets), counts.tolist()))
    return {"share": float(on.mean()), "split": split}


def _task_info(ref: _data.Demonstrations) -> dict:
    m = ref.manifest
    return {"expert_return": m["expert_return"]["mean"],
            "random_return": m["random_return"]["mean"], "n_reference_demos": len(ref),
            "mode_feature": m["mode_feature"], "demo_mode_shares": m["demo_mode_shares"],
            "expert_mode_shares": m["expert_mode_shares"], "expert": m["expert"]["name"]}


@contextlib.contextmanager
def _torch_threads(threads: int | None):
    """Runs the block with ``threads`` torch threads (None: unchanged), restored afterwards;
    one thread by default, which makes runs repeat exactly."""
    import torch
    old = torch.get_num_threads()
    if threads is not None:
        torch.set_num_threads(int(threads))
    try:
        yield threads if threads is not None else old
    finally:
        torch.set_num_threads(old)


def run(tasks=TASKS, seeds=(0, 1, 2), *, n_demos: int = 18, steps: int = 300_000,
        eval_episodes: int = 50, bc_max_epochs: int = 200, lr: float | None = None,
        threads: int | None = 1,
        progress: bool = True, out=None, command: str = "") -> dict:
    """``bench gail``: BC and GAIL on each task and seed (module docstring); returns the record
    and writes it (and the features' ``.npz``) when ``out`` is given.  ``lr`` sets one learning
    rate for the policy, its critic and the discriminator (:meth:`GAILConfig.with_lr`)."""
    from dc_lesson.storage import write_result
    tasks, seeds = list(tasks), [int(s) for s in seeds]
    if not tasks or not seeds:
        raise BenchInputError("bench gail needs at least one task and one seed")
    if eval_episodes < 1 or steps < 1:
        raise BenchInputError("bench gail needs at least one evaluation episode and one step")
    references = {}
    for task in tasks:
        ref = _data.load_demos(task)
        if not 2 <= n_demos <= len(ref):
            raise BenchInputError(f"{task} has {len(ref)} demonstrations; the warm start "
                                  f"needs 2 to {len(ref)}, got {n_demos}")
        check_eval_seeds(ref, EVAL_SEED, eval_episodes)
        references[task] = ref
    config = gail_config(steps, lr=lr)
    runs, features = [], {}
    start = time.perf_counter()
    with _torch_threads(threads) as n_threads:
        for task in tasks:
            features[feature_key(task, "expert")] = _subsample(
                references[task].mode_features, FEATURES_PER_RUN, 0)
            for seed in seeds:
                row, feats = run_one(task, seed, n_demos=n_demos, steps=steps,
                                     eval_episodes=eval_episodes, reference=references[task],
                                     bc_max_epochs=bc_max_epochs,
                                     config=gail_config(steps, seed, lr=lr), progress=False)
                runs.append(row)
                for method, f in feats.items():
                    features[feature_key(task, method, seed)] = _subsample(
                        f, FEATURES_PER_RUN, seed)
                if progress:
                    print(f"{task:<13} seed {seed}: BC {row['BC']['scaled_return']:.3f} "
                          f"(EMD {row['BC']['emd']:.3f}) -> GAIL "
                          f"{row['GAIL']['scaled_return']:.3f} (EMD {row['GAIL']['emd']:.3f})"
                          f"; modes {row['GAIL']['mode_shares']}; "
                          f"{row['wall_seconds']:.0f} s", flush=True)
    wall = time.perf_counter() - start
    record = {
        "benchmark": "gail_modes", "tasks": tasks, "n_demos": int(n_demos),
        "steps": int(steps), "eval_episodes": int(eval_episodes), "eval_seed": EVAL_SEED,
        "bc_max_epochs": int(bc_max_epochs),
        "warm_start": "bc.warm_start: BC on the first n_demos demonstrations, log-std reset "
                      "to -0.5; GAIL's expert pairs are the same n_demos demonstrations",
        "eval_policy": "the Gaussian policy's mean action, clipped to the bounds "
                       "(evaluation.evaluate_policy)",
        "measures_on": "mode features of all the task's demonstrations against every step of "
                       "the evaluation episodes (evaluation.evaluate_policy)",
        "curve": "mean environment return of the stochastic training episodes that ended in "
                 "each iteration, against environment steps",
        "std": "sample standard deviation over seeds (ddof = 1)",
        "gail_config": {k: v for k, v in config.to_dict().items() if k != "seed"},
        "features_file": features_path(out).name if out is not None else None,
        "features_per_run": FEATURES_PER_RUN,
        "torch_threads": n_threads,
        "task_info": {t: _task_info(references[t]) for t in tasks},
        "wall_seconds": wall, "summary": summarise(runs), "runs": runs}
    if progress:
        print(format_table(record["summary"]))
        print(f"{len(runs)} runs in {wall / 60:.1f} min")
    if out is not None:
        save_features(features_path(out), features)
        path = write_result(out, record, command=command, seeds=seeds)
        if progress:
            print(f"wrote {path} and {features_path(out).name}")
    return record


def run_lr(task: str = LR_TASK, lrs=(1e-4, 3e-4, 1e-3, 3e-3), seeds=(0, 1), *,
           n_demos: int = 18, steps: int = 150_000, eval_episodes: int = 50,
           bc_max_epochs: int = 200, threads: int | None = 1, progress: bool = True,
           out=None, command: str = "") -> dict:
    """``bench gail-lr``: GAIL's final scaled return for each learning rate and seed, from the
    seed's BC warm start (module docstring)."""
    from dc_lesson.storage import write_result
    lrs, seeds = [float(x) for x in lrs], [int(s) for s in seeds]
    if not lrs or not seeds or any(not x > 0 for x in lrs):
        raise BenchInputError("bench gail-lr needs positive learning rates and a seed")
    ref = _data.load_demos(task)
    if not 2 <= n_demos <= len(ref):
        raise BenchInputError(f"{task} has {len(ref)} demonstrations; got {n_demos}")
    check_eval_seeds(ref, EVAL_SEED, eval_episodes)
    runs, bc_runs = [], []
    start = time.perf_counter()
    with _torch_threads(threads):
        for seed in seeds:
            t0 = time.perf_counter()
            warm, demos, _ = _bc.warm_start(task, n_demos, seed, max_epochs=bc_max_epochs)
            ev = _evaluation.evaluate_policy(task, warm, ref, n_episodes=eval_episodes,
                                             seed=EVAL_SEED)
            bc_runs.append({"seed": seed, "scaled_return": ev["scaled_return"],
                            "return": ev["return"], "seconds": time.perf_counter() - t0})
            for lr in lrs:
                t0 = time.perf_counter()
                cfg = gail_config(steps, seed, lr=lr)
                result = _gail.train(task, demos, cfg, policy=copy.deepcopy(warm),
                                     progress=False)
                policy, log = result.policy, result.log
                ev = _evaluation.evaluate_policy(task, policy, ref, n_episodes=eval_episodes,
                                                 seed=EVAL_SEED)
                last = log[-max(1, len(log) // 10):]
                runs.append({"lr": lr, "seed": seed,
                             "scaled_return": ev["scaled_return"], "return": ev["return"],
                             "return_std": ev["return_std"], "curve": learning_curve(log),
                             "acc_learner_final": float(np.mean([r["acc_learner"]
                                                                 for r in last])),
                             "acc_expert_final": float(np.mean([r["acc_expert"]
                                                                for r in last])),
                             "seconds": time.perf_counter() - t0})
                if progress:
                    print(f"{task} lr {lr:g} seed {seed}: scaled return "
                          f"{ev['scaled_return']:.3f} (BC start "
                          f"{bc_runs[-1]['scaled_return']:.3f}); "
                          f"{runs[-1]['seconds']:.0f} s", flush=True)
    summary = []
    for lr in lrs:
        v = np.array([r["scaled_return"] for r in runs if r["lr"] == lr])
        summary.append({"lr": lr, "n_seeds": len(v), "scaled_return_mean": float(v.mean()),
                        "scaled_return_std": float(v.std(ddof=1)) if len(v) > 1 else 0.0,
                        "scaled_return_min": float(v.min())})
    bc_v = np.array([r["scaled_return"] for r in bc_runs])
    record = {
        "benchmark": "gail_lr", "task": task, "lrs": lrs, "n_demos": int(n_demos),
        "steps": int(steps), "eval_episodes": int(eval_episodes), "eval_seed": EVAL_SEED,
        "lr_applies_to": "the policy and its critic (PPO's AdamW) and the discriminator (Adam)",
        "gail_config": {k: v for k, v in gail_config(steps).to_dict().items()
                        if k not in ("seed", "disc_lr")},
        "bc": {"scaled_return_mean": float(bc_v.mean()), "runs": bc_runs},
        "std": "sample standard deviation over seeds (ddof = 1)",
        "wall_seconds": time.perf_counter() - start, "summary": summary, "runs": runs}
    if progress:
        for s in summary:
            print(f"lr {s['lr']:g}: scaled return {s['scaled_return_mean']:.3f} ± "
                  f"{s['scaled_return_std']:.3f} over {s['n_seeds']} seeds")
        print(f"BC start: {bc_v.mean():.3f}; {record['wall_seconds'] / 60:.1f} min")
    if out is not None:
        path = write_result(out, record, command=command, seeds=seeds)
        if progress:
            print(f"wrote {path}")
    return record


def main(what: str = "gail", tasks=None, seeds=None, steps=None, lr=None, out=None,
         command: str = "") -> dict:
    """:func:`run` or :func:`run_lr` with the current budget's sizes where not given."""
    from dc_lesson import budget
    b = budget.current()
    print(f"budget: {b.name}")
    if steps is not None:
        check_count("steps", steps)
    if lr is not None and not (isinstance(lr, (int, float)) and not isinstance(lr, bool)
                               and math.isfinite(lr) and lr > 0):
        raise BenchInputError(f"the learning rate must be a positive finite number, got {lr!r}")
    if what == "gail":
        return run(tasks or TASKS, default(seeds, b.il_seeds), n_demos=b.il_demos,
                   steps=default(steps, b.il_steps), eval_episodes=b.il_eval_episodes,
                   bc_max_epochs=b.bc_max_epochs, lr=lr, out=out, command=command)
    if what == "gail-lr":
        if lr is not None:
            raise BenchInputError("bench gail-lr sweeps the budget's learning rates; --lr is "
                                  "for bench gail")
        task = (tasks or [LR_TASK])[0]
        return run_lr(task, b.lr_sweep_lrs, default(seeds, b.lr_sweep_seeds),
                      n_demos=b.il_demos, steps=default(steps, b.lr_sweep_steps),
                      eval_episodes=b.il_eval_episodes,
                      bc_max_epochs=b.bc_max_epochs, out=out, command=command)
    raise ValueError(f"unknown benchmark {what!r}")


__all__ = ["FEATURES_PER_RUN", "LR_TASK", "METHODS", "TASKS", "feature_key", "features_path",
           "format_table", "gail_config", "learning_curve", "load_features", "main", "on_target",
           "pooled_features", "run", "run_lr", "run_one", "save_features", "summarise"]
