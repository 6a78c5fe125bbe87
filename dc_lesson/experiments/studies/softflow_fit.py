"""What SoftFlow learns, as cells (chapter 03; ``softflow_fit.json``).

Cells: the circle toy per seed of ``budget.softflow_toy_seeds`` and per sigma_max of the sweep
(0 = the plain CNF; task ``circle``, learner ``softflow``, variant ``sigma=...``), and the
expert-state flows per task, seed and sigma_max (the sweep on ``reacher4``, 0.1 on
``halfcheetah2``), each with its held-out NLL (:func:`experiments.softflow.toy_run`,
:func:`experiments.softflow.task_run`).  The aggregate gives each (task, sigma) row's held-out
NLL with its interval over seeds and the paired CNF - SoftFlow(0.1) gap on the toy.
"""

from __future__ import annotations

from dc_lesson.experiments import aggregate as _agg
from dc_lesson.experiments import cells
from dc_lesson.experiments import softflow as _sf

NAME = "softflow_fit"


def _levels(b):
    return tuple(sorted({0.0, 0.1} | {float(s) for s in b.softflow_sigma_maxes}))


def cells_at(b):
    out = []
    for seed in b.softflow_toy_seeds:
        for s in _levels(b):
            out.append(cells.make_cell(NAME, "softflow", "circle", 0, seed,
                                       {"points": b.softflow_toy_points,
                                        "iterations": b.softflow_toy_iters, "sigma_max": s},
                                       variant=f"sigma={s:g}"))
    for task in _sf.FIT_TASKS:
        for seed in b.softflow_task_seeds:
            for s in (_levels(b) if task == _sf.SWEEP_TASK else (0.1,)):
                out.append(cells.make_cell(NAME, "softflow", task, 0, seed,
                                           {"states": b.softflow_states,
                                            "iterations": b.softflow_iters, "sigma_max": s},
                                           variant=f"sigma={s:g}"))
    return out


def run_cell(cell, needs):
    c = cell.config
    if cell.task == "circle":
        row = _sf.toy_run(cell.seed, (c["sigma_max"],), c["points"], c["iterations"])[0]
        return row, None
    d = _sf.task_data(cell.task, c["states"])
    row = _sf.task_run(d, c["sigma_max"], c["iterations"], cell.seed)
    return row, {"sample_features": row.pop("sample_features")}


def aggregate(recs, b):
    obs = [_agg.observation(r, {f"nll {k}": v for k, v in r["result"]["heldout_nll"].items()})
           for r in recs]
    names = sorted({k for o in obs for k in o if k.startswith("nll ")})
    gap = _agg.paired([o for o in obs if o["task"] == "circle"], "softflow-sigma=0",
                      "softflow-sigma=0.1", measures=names)
    return {"table": _agg.table(obs, measures=names), "cnf_minus_softflow": gap,
            "runs": [{**r["cell"], **r["result"]} for r in recs]}


STUDY = cells.Study(NAME, "SoftFlow on the circle toy and on expert states (chapter 03)",
                    cells=cells_at, run_cell=run_cell, aggregate=aggregate,
                    result_file="softflow_fit_cells.json")
