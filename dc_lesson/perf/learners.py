"""How fast the learners run: ``dc-lesson perf learners``.

Each learner (BC, PPO, GAIL, DC) runs a fixed, small amount of work on each task (a few
iterations at the lesson budget's batch sizes), twice per repeat: on the path before issue 14
(``dc_lesson.nn.fast.disabled()``: the torch modules in every rollout step, validated
distributions, the environment copies stepped one by one) and on the fast path sweep workers
run (``fast.on()``), alternating which goes first.  Every run records its
phases (:mod:`dc_lesson.timing`: ``policy`` and ``env`` in rollouts, ``value``, ``gae``,
``ppo_update``, ``bc_step``, ``disc_step``, ``flow_fit``, ``log_p``, ``refit_rollout``) and
the table gives the median seconds of each phase on both paths, environment steps per second
including the updates, and the ratio old / new.  The same seed gives the same work on both
paths, so the ratio is the speed-up; absolute times drift with the machine's load.
"""

from __future__ import annotations

import dataclasses
import platform
import time

import numpy as np
import torch

from dc_lesson import algorithms, budget as _budget, data, timing
from dc_lesson.nn import fast
from dc_lesson.storage import check_writable, write_result

TASKS = ("reacher4", "halfcheetah")
LEARNERS = ("bc", "ppo", "gail", "dc")


def _config(name: str, b: _budget.Budget, task: str):
    """The fixed work of one benchmark run (independent of the budget's run lengths)."""
    algo = algorithms.get(name)
    cfg = algo.preset(b, 0)
    if name == "bc":
        return dataclasses.replace(cfg, epochs=20, patience=10 ** 6)
    if name == "ppo":
        return dataclasses.replace(cfg, total_steps=6 * cfg.batch_size)
    if name == "gail":
        return algorithms.gail.sized(6 * cfg.ppo.batch_size, 0)
    return dataclasses.replace(cfg, loops=2, iterations=3)   # dc: fit, 3 its, refit, 3 its


def _env_steps(name: str, config, task: str) -> int:
    if name == "bc":
        return 0
    if name == "ppo":
        return config.total_steps
    if name == "gail":
        return config.ppo.n_updates * config.ppo.batch_size
    return config.env_steps(task)


def run_once(name: str, task: str, demos, start, b: _budget.Budget, old: bool) -> dict:
    """One timed run of learner ``name`` on ``task``; ``old`` selects the path before issue 14."""
    config = _config(name, b, task)
    algo = algorithms.get(name)
    policy = None if name in ("bc", "ppo") else _copy(start)
    with (fast.disabled() if old else fast.on()), timing.recording() as phases:
        t0 = time.perf_counter()
        algo.train(task, demos if algo.uses_demos else None, config, policy=policy,
                   progress=False)
        total = time.perf_counter() - t0
    steps = _env_steps(name, config, task)
    return {"total": total, "env_steps": steps, "phases": dict(phases)}


def _copy(policy):
    import copy
    return copy.deepcopy(policy)


@fast.on()   # the BC start as a sweep worker makes it
def benchmark(tasks=TASKS, learners=LEARNERS, repeats: int = 2, log=print) -> list[dict]:
    """One row per (learner, task): median seconds per phase and in all, on both paths."""
    torch.set_num_threads(1)
    b = _budget.get("lesson")
    rows = []
    for task in tasks:
        demos = data.load_demos(task, n_trajectories=b.il_demos)
        start = algorithms.bc.warm_start_policy(demos, 0, max_epochs=b.bc_max_epochs)
        for name in learners:
            runs = {"old": [], "new": []}
            for r in range(repeats):
                for path in (("old", "new") if r % 2 == 0 else ("new", "old")):
                    runs[path].append(run_once(name, task, demos, start, b, path == "old"))
            med = {p: float(np.median([x["total"] for x in rs])) for p, rs in runs.items()}
            names = sorted({k for rs in runs.values() for x in rs for k in x["phases"]})
            phases = {k: {p: float(np.median([x["phases"].get(k, 0.0) for x in rs]))
                          for p, rs in runs.items()} for k in names}
            steps = runs["new"][0]["env_steps"]
            row = {"learner": name, "task": task, "env_steps": steps,
                   "seconds_old": med["old"], "seconds_new": med["new"],
                   "ratio": float(np.median([o["total"] / n["total"] for o, n in
                                             zip(runs["old"], runs["new"])])),
                   "steps_per_s_old": steps / med["old"] if steps else None,
                   "steps_per_s_new": steps / med["new"] if steps else None,
                   "phases": phases, "repeats": repeats}
            rows.append(row)
            log(format_row(row))
    return rows


def format_row(r: dict) -> str:
    sps = (f"  env steps/s {r['steps_per_s_old']:.0f} -> {r['steps_per_s_new']:.0f}"
           if r["env_steps"] else "")
    phases = ", ".join(f"{k} {v['old']:.1f}->{v['new']:.1f}"
                       for k, v in sorted(r["phases"].items(), key=lambda kv: -kv[1]["old"]))
    return (f"{r['learner']:<5} {r['task']:<12} {r['seconds_old']:6.1f} s -> "
            f"{r['seconds_new']:6.1f} s  (x{r['ratio']:.2f}){sps}\n      phases (s): {phases}")


def main(tasks=None, learners=None, repeats: int = 2, out=None, command: str = "") -> list[dict]:
    if out:
        check_writable(out)
    rows = benchmark(tasks or TASKS, learners or LEARNERS, repeats)
    if out:
        write_result(out, {"benchmark": "learners", "rows": rows, "threads": 1,
                           "machine": platform.processor() or platform.machine()},
                     command=command, seeds=[0])
    return rows


__all__ = ["LEARNERS", "TASKS", "benchmark", "format_row", "main", "run_once"]
