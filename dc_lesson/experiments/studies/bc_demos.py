"""BC against the number of demonstrations, as cells (chapter 01; ``bc_demos.json``).

Cells: per task of :data:`TASKS`, demonstration count of ``budget.bc_demo_counts`` and seed of
``budget.seeds_for(task)``, one BC run (:func:`experiments.bc.run_one`: the first n
demonstrations, the seed deciding split, weights and minibatch order), evaluated on
``budget.bc_eval_episodes`` fresh episodes from ``EVAL_SEED`` against the task's fresh expert
reference (:func:`protocol.reference_cell`, not the demonstrations); and the expert row, the
expert scored the same way on as many disjoint samples as there are seeds.

The aggregate keeps the layout chapter 01 reads (``summary`` rows with ``{measure}_mean`` and
``_std``, ``runs``, ``task_info``) and adds each measure's 95% interval (``_lo``, ``_hi``), the
expert row (``expert``) and the paired difference of the most minus the fewest demonstrations
(``paired``; BC runs of one seed share their initial weights and minibatch order).
"""

from __future__ import annotations

import json

from dc_lesson import data as _data
from dc_lesson.algorithms import bc as _bc
from dc_lesson.experiments import aggregate as _agg
from dc_lesson.experiments import bc as _runs
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies import _common

NAME = "bc_demos"
TASKS = ("reacher1", "reacher4", "halfcheetah")   # chapter 01's tasks
EMD_N_MAX = 2000


def _bc_config(max_epochs: int) -> dict:
    return {k: v for k, v in json.loads(_bc.BCConfig(epochs=max_epochs).to_json()).items()
            if k != "seed"}


def cells_at(budget) -> list[cells.Cell]:
    out = []
    for task in TASKS:
        ref = protocol.reference_cell(task)
        for n in budget.bc_demo_counts:
            for seed in budget.seeds_for(task):
                out.append(cells.make_cell(
                    NAME, "bc", task, n, seed,
                    {"eval_episodes": budget.bc_eval_episodes, "eval_seed": _runs.EVAL_SEED,
                     "emd_n_max": EMD_N_MAX, "bc": _bc_config(budget.bc_max_epochs)},
                    needs=(ref,)))
    return out + _common.expert_rows(NAME, TASKS, budget, budget.bc_eval_episodes)


def _run_bc(cell, needs):
    cfg = cell.config
    if _bc_config(cfg["bc"]["epochs"]) != cfg["bc"]:
        raise cells.CellError(f"{cell.name}: BCConfig's defaults changed since the cell was "
                              f"listed; list the study again")
    ref = _common.reference(needs)
    protocol.check_disjoint(cell.task, {"reference": (ref.seed, ref.n_episodes),
                                        "evaluation": (cfg["eval_seed"], cfg["eval_episodes"])})
    row = _runs.run_one(cell.task, cell.n_demos, cell.seed, cfg["eval_episodes"],
                         reference=ref, max_epochs=cfg["bc"]["epochs"],
                         eval_seed=cfg["eval_seed"], emd_n_max=cfg["emd_n_max"])
    return {"measures": {k: row[k] for k in protocol.MEASURED},
            **{k: v for k, v in row.items() if k not in protocol.MEASURED}}, None


def run_cell(cell, needs):
    return _common.run_expert_or(cell, needs, _run_bc)


def aggregate(records, budget) -> dict:
    obs = [_agg.observation(r, r["result"]["measures"]) for r in records]
    bc_obs = [o for o in obs if o["row"] == "bc"]
    full = [cells.full_result(r) for r in records if r["cell"]["learner"] == "bc"]
    runs = [{**{k: x[k] for k in x if k != "measures"}, **x["measures"]} for x in full]
    summary = _agg.table(bc_obs)
    timing = _runs.summarise(runs)   # the wall times and epochs chapter 01 prints
    for s in summary:
        t = next(x for x in timing if (x["task"], x["n_demos"]) == (s["task"], s["n_demos"]))
        s.update({k: t[k] for k in t if k.endswith("seconds_mean") or k.startswith("epochs")
                  or k.startswith("best_epoch")})
    lo, hi = min(budget.bc_demo_counts), max(budget.bc_demo_counts)
    most_fewest = []
    for task in TASKS:
        a = [dict(o, row=f"bc n={o['n_demos']}", n_demos=0) for o in bc_obs
             if o["task"] == task and o["n_demos"] in (lo, hi)]
        most_fewest += _agg.paired(a, f"bc n={hi}", f"bc n={lo}")
    task_info = {}
    for task in TASKS:
        entry = _data.manifest_entry(task)
        ref = next(r for r in records if r["cell"]["task"] == task)["config"]
        task_info[task] = {"expert_return": entry["expert_return"]["mean"],
                           "random_return": entry["random_return"]["mean"],
                           "mode_feature": entry["mode_feature"],
                           "demo_mode_shares": entry["demo_mode_shares"],
                           "expert_mode_shares": entry["expert_mode_shares"],
                           "expert": entry["expert"]["name"], "reference": ref["needs"][0]}
    return {"tasks": list(TASKS), "demo_counts": list(budget.bc_demo_counts),
            "eval_episodes": budget.bc_eval_episodes, "eval_seed": _runs.EVAL_SEED,
            "eval_policy": "the Gaussian policy's mean action, clipped to the bounds",
            "demo_subset": "the first n demonstrations of data/demos/TASK.npz (nested subsets)",
            "measures_on": (f"mode features: {protocol.REFERENCE_EPISODES} fresh expert "
                            f"episodes from seed {protocol.REFERENCE_SEED} (the reference cell), "
                            "against every step of the evaluation episodes"),
            "interval": "95% bootstrap (BCa) over seeds: stats.mean_ci",
            "std": "sample standard deviation over seeds (ddof = 1)",
            "bc_config": _bc_config(budget.bc_max_epochs), "task_info": task_info,
            "summary": summary, "expert": _agg.table([o for o in obs if o["row"] == "expert"]),
            "paired": most_fewest, "runs": runs}


STUDY = cells.Study(NAME, "BC against the number of demonstrations (chapter 01)",
                    cells=cells_at, run_cell=run_cell, aggregate=aggregate,
                    result_file="bc_demos.json")
