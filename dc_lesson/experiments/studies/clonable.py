"""Can BC clone each single-mode expert? BC from 25 demonstrations, as cells
(``dc-lesson sweep clonable``; ``clonable.json``; chapter 00's floor table).

An expert that meets its floor need not be imitable: the sampling planners of walker, ant and
humanoid met theirs, and BC from all 25 of their demonstrations scored about 0 (the random
level). An expert is *clonable* here when BC from its 25 demonstrations reaches a mean scaled
return of at least ``floors.CLONE_FLOOR`` = 0.5 over ``budget.clonable_seeds`` seeds (3 at
lesson), each scored on ``budget.clonable_eval_episodes`` = 50 fresh episodes with the mean
action. BC is the book's default (``BCConfig``, ``budget.bc_max_epochs``), on the task's
default demonstrations; the planner variant's are measured beside them on walker (one seed,
the comparison that says why the experts changed).

Cells: per task of :data:`TASKS` and seed, one BC run; no expert reference (returns only:
the divergences are Table III's business), so a cell costs BC's training and 50 episodes.
"""

from __future__ import annotations

import numpy as np

from dc_lesson import data as _data
from dc_lesson.algorithms import bc as _bc
from dc_lesson.evaluation import evaluate as _evaluate
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies.bc_demos import _bc_config   # the same BC, listed alike

NAME = "clonable"
TASKS = ("cartpole", "reacher1", "hopper", "walker", "halfcheetah", "ant", "humanoid")
N_DEMOS = 25
EVAL_SEED = 3000      # away from the manifest's (1, 2) and the learners' (1000) episode seeds
PLANNER_ROWS = ("walker",)   # the planner variant's demonstrations, seed 0, for comparison


def cells_at(budget) -> list[cells.Cell]:
    out = []
    for task in TASKS:
        for seed in range(budget.clonable_seeds):
            out.append(cells.make_cell(
                NAME, "bc", task, N_DEMOS, seed,
                {"eval_episodes": budget.clonable_eval_episodes, "eval_seed": EVAL_SEED,
                 "bc": _bc_config(budget.bc_max_epochs)}))
    for task in PLANNER_ROWS:
        out.append(cells.make_cell(
            NAME, "bc", task, N_DEMOS, 0,
            {"eval_episodes": budget.clonable_eval_episodes, "eval_seed": EVAL_SEED,
             "bc": _bc_config(budget.bc_max_epochs), "demo_variant": "planner"},
            variant="planner"))
    return out


def run_cell(cell, needs):
    cfg = cell.config
    if _bc_config(cfg["bc"]["epochs"]) != cfg["bc"]:
        raise cells.CellError(f"{cell.name}: BCConfig's defaults changed since the cell was "
                              f"listed; list the study again")
    variant = cell.variant or None
    # the evaluation starts from no demonstration's initial state
    protocol.check_disjoint(cell.task, {"evaluation": (cfg["eval_seed"], cfg["eval_episodes"])})
    demos = _data.load_demos(cell.task, n_trajectories=cell.n_demos, variant=variant)
    config = _bc.BCConfig(**{**cfg["bc"], "seed": cell.seed})
    policy, _ = _bc.train_bc(demos, config, progress=False)
    ev = _evaluate.evaluate_policy(cell.task, policy, None, n_episodes=cfg["eval_episodes"],
                                   seed=cfg["eval_seed"], divergences=False, variant=variant)
    entry = _data.manifest_entry(cell.task, variant=variant)
    return {"scaled_return": ev["scaled_return"], "return": ev["return"],
            "returns": ev["returns"], "expert_return": entry["expert_return"]["mean"],
            "random_return": entry["random_return"]["mean"],
            "best_epoch": policy.meta["best_epoch"]}, None


def aggregate(records, budget) -> dict:
    from dc_lesson.experts import floors
    rows = []
    groups: dict = {}
    for r in records:
        c = r["cell"]
        groups.setdefault((c["task"], c.get("variant") or ""), []).append(r["result"])
    for (task, variant), res in sorted(groups.items(),
                                       key=lambda kv: (TASKS.index(kv[0][0]), kv[0][1])):
        v = np.array([x["scaled_return"] for x in res])
        rows.append({"task": task, "demonstrations": f"{task}-{variant}" if variant else task,
                     "expert": _data.manifest_entry(task, variant=variant or None)
                     ["expert"]["name"], "seeds": len(v),
                     "scaled_return_mean": float(v.mean()),
                     "scaled_return_min": float(v.min()),
                     "per_seed": [float(x) for x in v],
                     "clonable": bool(v.mean() >= floors.CLONE_FLOOR)})
    return {"n_demos": N_DEMOS, "eval_episodes": budget.clonable_eval_episodes,
            "eval_seed": EVAL_SEED, "clone_floor": floors.CLONE_FLOOR,
            "bc_config": _bc_config(budget.bc_max_epochs),
            "rule": "clonable: BC's mean scaled return over seeds >= clone_floor",
            "table": rows}


STUDY = cells.Study(NAME, "BC from 25 demonstrations of each single-mode expert (chapter 00)",
                    cells=cells_at, run_cell=run_cell, aggregate=aggregate,
                    result_file="clonable.json")
