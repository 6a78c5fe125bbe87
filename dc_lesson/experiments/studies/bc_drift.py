"""BC's drift from the demonstrated states, as cells (chapter 01; ``bc_drift.json``).

Cells: on ``reacher4`` and ``halfcheetah``, for the fewest and the most of
``budget.bc_demo_counts`` and each seed of ``budget.seeds_for(task)``, BC on the first n
demonstrations, run for ``min(20, bc_eval_episodes)`` fresh episodes from ``EVAL_SEED``, and the
distance of each state to the nearest demonstrated state (:func:`metrics.distance_to_expert`;
the reference here *is* the demonstrations: compounding error is the distance from the training
data); and per task one expert cell on the same episodes (it has no training seed).
"""

from __future__ import annotations

from dc_lesson import data as _data
from dc_lesson.algorithms import bc as _bc
from dc_lesson.data import rollout as _rollout
from dc_lesson.evaluation import metrics as _metrics
from dc_lesson.experiments import aggregate as _agg
from dc_lesson.experiments import bc as _runs
from dc_lesson.experiments import cells
from dc_lesson.experiments.protocol import check_eval_seeds

NAME = "bc_drift"
TASKS = ("reacher4", "halfcheetah")


def cells_at(b):
    counts = (min(b.bc_demo_counts), max(b.bc_demo_counts))
    base = {"n_episodes": min(20, b.bc_eval_episodes), "eval_seed": _runs.EVAL_SEED}
    out = []
    for task in TASKS:
        out.append(cells.make_cell(NAME, "expert", task, 0, 0, base))
        for n in counts:
            for s in b.seeds_for(task):
                out.append(cells.make_cell(NAME, "bc", task, n, s,
                                           {**base, "max_epochs": b.bc_max_epochs}))
    return out


def run_cell(cell, needs):
    from dc_lesson.experts import load_expert
    c = cell.config
    reference = _data.load_demos(cell.task)
    check_eval_seeds(reference, c["eval_seed"], c["n_episodes"])
    if cell.learner == "expert":
        policy, _ = load_expert(cell.task)
    else:
        policy, _ = _bc.train_bc(_data.load_demos(cell.task, n_trajectories=cell.n_demos),
                                 _bc.BCConfig(epochs=c["max_epochs"], seed=cell.seed),
                                 progress=False)
    trajs = _rollout.collect(cell.task, policy, c["n_episodes"], seed=c["eval_seed"],
                             progress=False)
    d = _metrics.distance_to_expert(reference, trajs)
    return _runs.drift_summary({"curve": d})["curve"], None


def aggregate(recs, b):
    obs = [_agg.observation(r, {"late_median": r["result"]["late_median"],
                                "late_mean": r["result"]["late_mean"]}) for r in recs]
    table = _agg.table(obs, measures=("late_median", "late_mean"))
    curves = {f"{r['cell']['task']}/{r['cell']['learner']} n={r['cell']['n_demos']} "
              f"seed {r['cell']['seed']}": r["result"]["median_curve"] for r in recs}
    counts = sorted({o["n_demos"] for o in obs if o["row"] == "bc"})
    few_many = []
    for task in TASKS:
        a = [dict(o, row=f"n={o['n_demos']}", n_demos=0) for o in obs
             if o["task"] == task and o["row"] == "bc"]
        few_many += _agg.paired(a, f"n={counts[0]}", f"n={counts[-1]}",
                                measures=("late_median",))
    return {"tasks": list(TASKS), "demo_counts": counts, "table": table,
            "paired": few_many, "median_curves": curves,
            "distance": ("metrics.distance_to_expert: Euclidean distance to the nearest state of "
                         "all the task's demonstrations, in units of their std per dimension")}




STUDY = cells.Study(NAME, "BC's drift from the demonstrated states (chapter 01)",
                    cells=cells_at, run_cell=run_cell, aggregate=aggregate,
                    result_file="bc_drift_cells.json")
