"""Behaviour cloning against the number of demonstrations: ``dc-lesson bench bc``.

For each task, each demonstration count n (the paper's 4, 11, 18 and 25) and each seed, it

1. trains BC (:func:`dc_lesson.bc.train_bc`) on the task's *first* n demonstrations (so the
   subsets are nested: the 11 contain the 4), with the seed deciding the trajectory split,
   the initial weights and the minibatch order;
2. runs the policy's mean action (``GaussianPolicy.act``, what :func:`rollout.collect` calls)
   for ``eval_episodes`` fresh episodes, whose initial states come from ``eval_seed``: the
   same episodes for every (n, seed), and none of them a demonstration's (checked);
3. measures the mean return, the scaled return (:func:`metrics.scaled_return`: random 0,
   expert 1, from the manifest), the EMD, KL(expert || learner) and KL(learner || expert)
   between the mode features of *all* the task's demonstrations and those of the evaluation
   episodes (:func:`metrics.compare`: one fixed reference, so the measures of different n are
   comparable), the share of episodes in each mode for multi-mode tasks, and the wall time of
   training, of evaluation and of the measures.

The result file holds one row per run and a summary per (task, n): the mean and the sample
standard deviation (ddof = 1) over seeds.  ``dc-lesson bench bc`` runs it; the sizes default to
the budget (``DC_LESSON_BUDGET``).

``dc-lesson bench bc-drift`` (:func:`run_drift`) measures compounding error instead: for BC
with the fewest and the most demonstrations and for the expert, the distance from every state
of fresh episodes to the nearest demonstrated state (:func:`metrics.distance_to_expert`).
"""

from __future__ import annotations

import json
import time

import numpy as np

from dc_lesson.algorithms import bc as _bc
from dc_lesson import data as _data
from dc_lesson import evaluation as _evaluation
from dc_lesson.evaluation import metrics as _metrics
from dc_lesson.data import rollout as _rollout
from dc_lesson import tasks as _tasks
from dc_lesson.experiments.protocol import BenchInputError, check_count, check_eval_seeds, default

# The demonstrations use seed 0 and the manifest's expert and random evaluations seeds 1 and 2;
# BC's evaluation episodes come from a seed of their own.
EVAL_SEED = _evaluation.EVAL_SEED
MEASURES = _evaluation.MEASURES


def available_tasks() -> list[str]:
    """The tasks that have demonstrations in the manifest, in the library's order."""
    have = _data.read_manifest()["tasks"]
    return [n for n in _tasks.NAMES if n in have]


def run_one(task: str, n_demos: int, seed: int, eval_episodes: int, *,
            reference: _data.Demonstrations, max_epochs: int = 200,
            eval_seed: int = EVAL_SEED, emd_n_max: int | None = 2000,
            bc_kwargs: dict | None = None) -> dict:
    """One run: BC on the first ``n_demos`` demonstrations with ``seed``, evaluated and
    measured against ``reference`` (the task's demonstrations); a row of the result file."""
    demos = _data.load_demos(task, n_trajectories=n_demos)
    config = _bc.BCConfig(**{"epochs": max_epochs, **(bc_kwargs or {}), "seed": seed})
    t0 = time.perf_counter()
    policy, log = _bc.train_bc(demos, config, progress=False)
    t1 = time.perf_counter()
    ev = _evaluation.evaluate_policy(task, policy, reference, n_episodes=eval_episodes,
                                     seed=eval_seed, emd_n_max=emd_n_max)
    best = log[policy.meta["best_epoch"] - 1]
    return {"task": task, "n_demos": int(n_demos), "seed": int(seed),
            **{k: ev[k] for k in ("scaled_return", "return", "return_std", "returns", "emd",
                                  "kl", "rkl", "mode_shares")},
            "train_episodes": len(policy.meta["train_episodes"]),
            "val_episodes": len(policy.meta["val_episodes"]),
            "best_epoch": policy.meta["best_epoch"], "epochs_run": policy.meta["epochs_run"],
            "best_val_nll": best["val_nll"], "train_nll_at_best": best["train_nll"],
            "train_seconds": t1 - t0, "eval_seconds": ev["eval_seconds"],
            "measure_seconds": ev["measure_seconds"]}


def summarise(runs: list[dict]) -> list[dict]:
    """Per (task, n): the mean and sample std (ddof = 1; 0 with one seed) over seeds of each
    measure, the mean wall times and epochs, and the mean mode shares of multi-mode tasks."""
    groups: dict[tuple[str, int], list[dict]] = {}
    for r in runs:
        groups.setdefault((r["task"], r["n_demos"]), []).append(r)
    out = []
    for (task, n), rows in groups.items():
        row = {"task": task, "n_demos": n, "n_seeds": len(rows)}
        for m in MEASURES:
            v = np.array([r[m] for r in rows], dtype=np.float64)
            row[f"{m}_mean"] = float(v.mean())
            row[f"{m}_std"] = float(v.std(ddof=1)) if len(v) > 1 else 0.0
        for k in ("train_seconds", "eval_seconds", "measure_seconds", "epochs_run", "best_epoch"):
            row[f"{k}_mean"] = float(np.mean([r[k] for r in rows]))
        if rows[0]["mode_shares"] is not None:
            row["mode_shares_mean"] = {k: float(np.mean([r["mode_shares"][k] for r in rows]))
                                       for k in rows[0]["mode_shares"]}
        out.append(row)
    return out


def format_table(summary: list[dict]) -> str:
    """The summary as a plain-text table."""
    head = (f"{'task':<13}{'demos':>6}{'seeds':>6}{'scaled return':>17}{'return':>16}"
            f"{'EMD':>15}{'KL':>13}{'RKL':>13}{'epochs':>8}{'train s':>9}{'eval s':>8}")
    lines = [head, "-" * len(head)]
    for r in summary:
        pm = lambda m, w, p: f"{r[m + '_mean']:.{p}f} ± {r[m + '_std']:.{p}f}".rjust(w)  # noqa
        lines.append(f"{r['task']:<13}{r['n_demos']:>6}{r['n_seeds']:>6}"
                     f"{pm('scaled_return', 17, 3)}{pm('return', 16, 1)}{pm('emd', 15, 3)}"
                     f"{pm('kl', 13, 2)}{pm('rkl', 13, 2)}{r['epochs_run_mean']:>8.0f}"
                     f"{r['train_seconds_mean']:>9.1f}{r['eval_seconds_mean']:>8.1f}")
        if "mode_shares_mean" in r:
            lines.append(" " * 19 + "modes: " + ", ".join(
                f"{k} {v:.2f}" for k, v in r["mode_shares_mean"].items()))
    return "\n".join(lines)


def run(tasks, demo_counts=(4, 11, 18, 25), seeds=(0, 1, 2), eval_episodes: int = 50, *,
        max_epochs: int = 200, eval_seed: int = EVAL_SEED, emd_n_max: int | None = 2000,
        bc_kwargs: dict | None = None, threads: int | None = 1, progress: bool = True,
        out=None, command: str = "") -> dict:
    """BC on each task with each demonstration count and seed; returns the result record
    (and writes it to ``out`` via :func:`dc_lesson.results.write_result` when given).

    ``bc_kwargs`` overrides :class:`~dc_lesson.bc.BCConfig` fields other than the seed and
    (unless given there) ``epochs``; ``threads`` sets torch's thread count for the run
    (restored afterwards; None leaves it), one by default, which makes runs repeat exactly.
    """
    import torch
    from dc_lesson import progress as _progress

    from dc_lesson.storage import write_result
    tasks, demo_counts, seeds = list(tasks), [int(n) for n in demo_counts], [int(s) for s in
                                                                             seeds]
    if not tasks or not demo_counts or not seeds:
        raise BenchInputError("bench bc needs at least one task, one demonstration count "
                              "and one seed")
    eval_episodes = check_count("eval_episodes", eval_episodes)
    max_epochs = check_count("max_epochs", max_epochs)
    for s in seeds:
        check_count("a seed", s, minimum=0)
    references, task_info = {}, {}
    for task in tasks:   # fail on a missing task or a bad count before any training
        ref = _data.load_demos(task)
        for n in demo_counts:
            if not 2 <= n <= len(ref):
                raise BenchInputError(f"{task} has {len(ref)} demonstrations; BC with a "
                                      f"validation split needs 2 to {len(ref)}, got {n}")
        check_eval_seeds(ref, eval_seed, eval_episodes)
        references[task] = ref
        entry = ref.manifest
        task_info[task] = {
            "expert_return": entry["expert_return"]["mean"],
            "random_return": entry["random_return"]["mean"],
            "n_reference_demos": len(ref), "mode_feature": entry["mode_feature"],
            "demo_mode_shares": entry["demo_mode_shares"],
            "expert_mode_shares": entry["expert_mode_shares"],
            "expert": entry["expert"]["name"]}

    old_threads = torch.get_num_threads()
    if threads is not None:
        torch.set_num_threads(int(threads))
    runs = []
    start = time.perf_counter()
    bar = _progress.bar(total=len(tasks) * len(demo_counts) * len(seeds), desc="bench bc", unit="run",
               enabled=progress)
    try:
        for task in tasks:
            for n in demo_counts:
                for seed in seeds:
                    bar.set_postfix(task=task, demos=n, seed=seed)
                    row = run_one(task, n, seed, eval_episodes, reference=references[task],
                                  max_epochs=max_epochs, eval_seed=eval_seed,
                                  emd_n_max=emd_n_max, bc_kwargs=bc_kwargs)
                    runs.append(row)
                    bar.update(1)
                    if progress:
                        bar.write(f"{task:<12} demos {n:>2} seed {seed}: scaled return "
                                  f"{row['scaled_return']:6.3f}  EMD {row['emd']:.3f}  "
                                  f"epochs {row['epochs_run']:>3}  train "
                                  f"{row['train_seconds']:.1f} s  eval {row['eval_seconds']:.1f}"
                                  f" s")
    finally:
        bar.close()
        torch.set_num_threads(old_threads)
    wall = time.perf_counter() - start
    bc_config = _bc.BCConfig(**{"epochs": max_epochs, **(bc_kwargs or {})})
    record = {
        "benchmark": "bc_demos", "tasks": tasks, "demo_counts": demo_counts,
        "eval_episodes": int(eval_episodes), "eval_seed": int(eval_seed),
        "eval_policy": "the Gaussian policy's mean action, clipped to the bounds",
        "demo_subset": "the first n demonstrations of data/demos/TASK.npz (nested subsets)",
        "measures_on": ("mode features: all the task's demonstrations (reference) against "
                        "every step of the evaluation episodes (learner); metrics.compare "
                        f"with n_max={emd_n_max} for the EMD, k=1 and jitter 1e-4 for the KLs"),
        "std": "sample standard deviation over seeds (ddof = 1)",
        "bc_config": {k: v for k, v in json.loads(bc_config.to_json()).items()
                      if k != "seed"},
        "torch_threads": threads if threads is not None else old_threads,
        "task_info": task_info, "wall_seconds": wall,
        "summary": summarise(runs), "runs": runs}
    if progress:
        print(format_table(record["summary"]))
        print(f"{len(runs)} runs in {wall:.0f} s "
              f"({wall / max(1, len(runs)):.1f} s per run)")
    if out is not None:
        path = write_result(out, record, command=command, seeds=seeds)
        if progress:
            print(f"wrote {path}")
    return record


# -- drift from the demonstrated states (compounding error) -------------------------------------

def drift(task: str, demo_counts, *, seed: int = 0, n_episodes: int = 10, max_epochs: int = 200,
          eval_seed: int = EVAL_SEED, policies: dict | None = None,
          variant: str | None = None) -> dict:
    """How far BC's states get from the demonstrated ones over an episode, against the expert.

    Trains BC with ``seed`` on the first n demonstrations for each n in ``demo_counts`` (or
    takes ``policies[n]`` when given), runs each policy and the task's expert for
    ``n_episodes`` fresh episodes from ``eval_seed`` (the same initial states for all), and
    measures :func:`metrics.distance_to_expert` against *all* the task's demonstrations
    (``variant``: another expert's demonstrations and that expert).
    Returns ``{"distances": {name: (n_episodes, T + 1)}, "trajectories": {name: [...]},
    "policies": {n: policy}}`` with the names ``"expert"`` and ``"BC, n demos"``.
    """
    from dc_lesson.experts import load_expert
    reference = _data.load_demos(task, variant=variant)
    check_eval_seeds(reference, eval_seed, n_episodes)
    expert, _ = load_expert(task, variant)
    trajs = {"expert": _rollout.collect(task, expert, n_episodes, seed=eval_seed,
                                        progress=False)}
    policies = dict(policies or {})
    for n in demo_counts:
        if n not in policies:
            policies[n], _ = _bc.train_bc(_data.load_demos(task, n_trajectories=n,
                                                           variant=variant),
                                          _bc.BCConfig(epochs=max_epochs, seed=seed),
                                          progress=False)
        trajs[f"BC, {n} demos"] = _rollout.collect(task, policies[n], n_episodes,
                                                   seed=eval_seed, progress=False)
    distances = {k: _metrics.distance_to_expert(reference, v) for k, v in trajs.items()}
    return {"distances": distances, "trajectories": trajs, "policies": policies}


def drift_summary(distances: dict) -> dict:
    """JSON-able figures of :func:`drift`'s distances, per name: the median over episodes at
    every step (``median_curve``), and the median and mean over episodes and the second half
    of the episode (``late_median``, ``late_mean``: where a policy ends up)."""
    out = {}
    for name, d in distances.items():
        late = d[:, d.shape[1] // 2:]
        out[name] = {"n_episodes": int(d.shape[0]),
                     "late_median": float(np.median(late)), "late_mean": float(late.mean()),
                     "median_curve": [round(float(x), 5) for x in np.median(d, axis=0)]}
    return out


def run_drift(tasks, demo_counts=(4, 25), seeds=(0, 1, 2), n_episodes: int = 20, *,
              max_epochs: int = 200, eval_seed: int = EVAL_SEED, threads: int | None = 1,
              progress: bool = True, out=None, command: str = "") -> dict:
    """:func:`drift` for each task and seed; the record (written to ``out`` when given) holds
    :func:`drift_summary` per (task, seed) and the seeds' mean of ``late_median`` per name."""
    import torch
    from dc_lesson import progress as _progress

    from dc_lesson.storage import write_result
    tasks, demo_counts, seeds = list(tasks), [int(n) for n in demo_counts], [int(s) for s in
                                                                             seeds]
    if not tasks or not demo_counts or not seeds:
        raise BenchInputError("bench bc-drift needs a task, a demonstration count and a seed")
    n_episodes = check_count("n_episodes", n_episodes)
    max_epochs = check_count("max_epochs", max_epochs)
    for s in seeds:
        check_count("a seed", s, minimum=0)
    for task in tasks:
        n_have = len(_data.load_demos(task))
        if not all(2 <= n <= n_have for n in demo_counts):
            raise BenchInputError(f"{task} has {n_have} demonstrations; BC with a validation "
                                  f"split needs 2 to {n_have}, got {demo_counts}")
    old_threads = torch.get_num_threads()
    if threads is not None:
        torch.set_num_threads(int(threads))
    start = time.perf_counter()
    per_seed, summary = [], []
    try:
        for task, seed in _progress.bar([(t, s) for t in tasks for s in seeds], desc="bench bc-drift",
                               unit="run", enabled=progress):
            d = drift(task, demo_counts, seed=seed, n_episodes=n_episodes,
                      max_epochs=max_epochs, eval_seed=eval_seed)
            per_seed.append({"task": task, "seed": seed,
                             "curves": drift_summary(d["distances"])})
    finally:
        torch.set_num_threads(old_threads)
    for task in tasks:
        rows = [r for r in per_seed if r["task"] == task]
        for name in rows[0]["curves"]:
            v = np.array([r["curves"][name]["late_median"] for r in rows])
            summary.append({"task": task, "policy": name, "n_seeds": len(v),
                            "late_median_mean": float(v.mean()),
                            "late_median_min": float(v.min()),
                            "late_median_max": float(v.max())})
    record = {"benchmark": "bc_drift", "tasks": tasks, "demo_counts": demo_counts,
              "n_episodes": int(n_episodes), "eval_seed": int(eval_seed),
              "bc_config": {"epochs": int(max_epochs)},
              "distance": ("metrics.distance_to_expert: Euclidean distance to the nearest state "
                           "of all the task's demonstrations, each observation dimension in "
                           "units of the demonstrations' std; the expert's seeds are the same "
                           "for every seed (it does not depend on the BC seed)"),
              "wall_seconds": time.perf_counter() - start,
              "summary": summary, "per_seed": per_seed}
    if progress:
        for r in summary:
            print(f"{r['task']:<12} {r['policy']:<14} median distance over the second half "
                  f"{r['late_median_mean']:.4f} (seeds {r['late_median_min']:.4f} .. "
                  f"{r['late_median_max']:.4f})")
    if out is not None:
        path = write_result(out, record, command=command, seeds=seeds)
        if progress:
            print(f"wrote {path}")
    return record


def main(tasks=None, demo_counts=None, seeds=None, eval_episodes=None, max_epochs=None,
         out=None, command: str = "") -> dict:
    """:func:`run` with the sizes of the current budget where not given, on every task with
    demonstrations when ``tasks`` is empty."""
    from dc_lesson import budget
    b = budget.current()
    tasks = list(tasks or available_tasks())
    eval_episodes = check_count("eval_episodes", default(eval_episodes, b.bc_eval_episodes))
    max_epochs = check_count("max_epochs", default(max_epochs, b.bc_max_epochs))
    print(f"budget: {b.name}; tasks: {', '.join(tasks)}")
    return run(tasks, default(demo_counts, b.bc_demo_counts), default(seeds, b.bc_seeds),
               eval_episodes, max_epochs=max_epochs, out=out, command=command)
