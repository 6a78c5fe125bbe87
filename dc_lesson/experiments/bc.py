"""Behaviour cloning against the number of demonstrations, and its drift from the
demonstrated states: the runs behind the ``bc_demos`` and ``bc_drift`` cell studies
(:mod:`dc_lesson.experiments.studies`; chapter 01).

:func:`run_one`, one run of ``bc_demos``:

1. trains BC (:func:`dc_lesson.algorithms.bc.train_bc`) on the task's *first* n
   demonstrations (so the subsets are nested: the 11 contain the 4), with the seed deciding
   the trajectory split, the initial weights and the minibatch order;
2. runs the policy's mean action for ``eval_episodes`` fresh episodes, whose initial states
   come from ``eval_seed``: the same episodes for every (n, seed), and none of them a
   demonstration's (checked);
3. measures the mean return, the scaled return (random 0, expert 1, from the manifest), the
   EMD, KL(expert || learner) and KL(learner || expert) between the mode features of the
   reference and those of the evaluation episodes, the share of episodes in each mode for
   multi-mode tasks, and the wall time of training, of evaluation and of the measures.

:func:`summarise` gives the mean and the sample standard deviation over seeds per (task, n).

:func:`drift` measures compounding error instead: for BC with given demonstration counts and
for the expert, the distance from every state of fresh episodes to the nearest demonstrated
state (:func:`metrics.distance_to_expert`); :func:`drift_summary` makes it JSON.
"""

from __future__ import annotations

import time

import numpy as np

from dc_lesson.algorithms import bc as _bc
from dc_lesson import data as _data
from dc_lesson import evaluation as _evaluation
from dc_lesson.evaluation import metrics as _metrics
from dc_lesson.data import rollout as _rollout
from dc_lesson.experiments.protocol import check_eval_seeds

# The demonstrations use seed 0 and the manifest's expert and random evaluations seeds 1 and 2;
# BC's evaluation episodes come from a seed of their own.
EVAL_SEED = _evaluation.EVAL_SEED
MEASURES = _evaluation.MEASURES


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


