"""What SoftFlow learns, as cells (chapter 03; ``softflow_fit_cells.json``).

Cells: the circle toy per seed of ``budget.softflow_toy_seeds`` and per sigma_max of the sweep
(0 = the plain CNF; task ``circle``, learner ``softflow``, variant ``sigma=...``), and the
expert-state flows per task, seed and sigma_max (the sweep on ``reacher4``, 0.1 on
``halfcheetah2``), each with its held-out NLL (:func:`experiments.softflow.toy_run`,
:func:`experiments.softflow.task_run`).  The aggregate gives each (task, sigma) row's held-out
NLL with its interval over seeds and the paired CNF - SoftFlow(0.1) gap on the toy.

What chapter 03 draws is in the cells too: each toy cell's density on a
``budget.softflow_grid`` square (its features ``.npz``), and per task a ``data`` cell (learner
``data``) with the split's facts, the Gaussian and KDE baselines of the same training states
and a subsample of the data's mode feature.  :func:`fit_record` rebuilds the
chapter's record from them.
"""

from __future__ import annotations

import dataclasses as _dc
import pathlib

import numpy as np

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
                                        "iterations": b.softflow_toy_iters, "sigma_max": s,
                                        "grid": b.softflow_grid},
                                       variant=f"sigma={s:g}"))
    for task in _sf.FIT_TASKS:
        out.append(cells.make_cell(NAME, "data", task, 0, 0, {"states": b.softflow_states}))
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
        row = _sf.toy_run(cell.seed, (c["sigma_max"],), c["points"], c["iterations"],
                          grid=c["grid"])[0]
        return row, {"density": row.pop("density"), "grid": row.pop("grid")}
    d = _sf.task_data(cell.task, c["states"])
    if cell.learner == "data":
        return _sf.task_context(d)
    row = _sf.task_run(d, c["sigma_max"], c["iterations"], cell.seed)
    return row, {"sample_features": row.pop("sample_features")}


def aggregate(recs, b):
    fits = [r for r in recs if r["cell"]["learner"] != "data"]
    obs = [_agg.observation(r, {f"nll {k}": v for k, v in r["result"]["heldout_nll"].items()})
           for r in fits]
    names = sorted({k for o in obs for k in o if k.startswith("nll ")})
    gap = _agg.paired([o for o in obs if o["task"] == "circle"], "softflow-sigma=0",
                      "softflow-sigma=0.1", measures=names)
    return {"table": _agg.table(obs, measures=names), "cnf_minus_softflow": gap,
            "runs": [{**r["cell"], **r["result"]} for r in fits],
            "tasks": {r["cell"]["task"]: {**r["result"],
                                          "config_hash": r["cell"]["config_hash"]}
                      for r in recs if r["cell"]["learner"] == "data"},
            "toy": {"config": _dc.asdict(_sf.toy_config(0.1, b.softflow_toy_iters)),
                    "train_points": b.softflow_toy_points, "test_points": _sf.TOY_TEST_POINTS,
                    "test_noises": list(_sf.TOY_TEST_NOISES)}}


def fit_record(record: dict, root=None) -> tuple[dict, dict]:
    """Chapter 03's record and arrays, rebuilt from the ``softflow_fit`` cells' aggregate
    (``softflow_fit_cells.json``) and their features: the structure
    :func:`experiments.softflow.softflow_fit_benchmark` returns (toy runs, per-sigma summaries with the
    population std over seeds, the CNF - SoftFlow gap per seed, task runs beside the task's
    facts), so every number the chapter reads is a cell's."""
    runs = record["runs"]
    arrays: dict[str, np.ndarray] = {}

    def feats(r):   # the features .npz of the cell a run row came from
        row = r["learner"] + (f"-{r['variant']}" if r["variant"] else "")
        return cells.read_features(
            pathlib.Path(root or cells.cells_root()) / r["study"] / r["task"]
            / f"{row}__n{r['n_demos']}__s{r['seed']}__{r['config_hash']}.json")

    toy_rows = sorted((r for r in runs if r["task"] == "circle"),
                      key=lambda r: (r["seed"], r["sigma_max"]))
    seeds = sorted({r["seed"] for r in toy_rows})
    compared = sorted({r["sigma_max"] for r in toy_rows})
    for r in toy_rows:
        if r["seed"] == seeds[0]:
            f = feats(r)
            arrays[f"toy_density_sigma_{r['sigma_max']:g}"] = f["density"]
            arrays["toy_grid"] = f["grid"]
    summary = {f"{s:g}": {nz: _sf.mean_std([r["heldout_nll"][nz] for r in toy_rows
                                         if r["sigma_max"] == s])
                          for nz in toy_rows[0]["heldout_nll"]} for s in compared}
    cnf = {r["seed"]: r for r in toy_rows if r["sigma_max"] == 0}
    soft = {r["seed"]: r for r in toy_rows if r["sigma_max"] == 0.1}
    gap = {nz: _sf.mean_std([cnf[s]["heldout_nll"][nz] - soft[s]["heldout_nll"][nz]
                          for s in seeds]) for nz in summary["0"]}
    toy = {**record["toy"], "seeds": seeds, "sigma_maxes": compared, "runs": toy_rows,
           "summary": summary, "cnf_minus_softflow": gap}
    tasks = {}
    for task, context in record["tasks"].items():
        res = {**context, "runs": []}
        for r in sorted((r for r in runs if r["task"] == task),
                        key=lambda r: (r["seed"], r["sigma_max"])):
            feat = feats(r)["sample_features"]
            arrays[f"{task}_samples_seed{r['seed']}_sigma_{r['sigma_max']:g}"] = feat
            row = {k: v for k, v in r.items() if k not in (
                "study", "learner", "variant", "task", "n_demos", "config_hash")}
            if "feature_grid" in res:
                f = feat[:, 0]
                row["feature_kde_samples"] = _sf.feature_kde(f[np.isfinite(f)],
                                                         np.asarray(res["feature_grid"]))
            res["runs"].append(row)
        data_cell = {"study": "softflow_fit", "learner": "data", "task": task, "n_demos": 0,
                     "seed": 0, "variant": "", "config_hash": context["config_hash"]}
        arrays[f"{task}_data_features"] = feats(data_cell)["data_features"]
        res.pop("config_hash")
        tasks[task] = res
    from dc_lesson import budget as _budget
    out = {k: record[k] for k in ("command", "budget", "revision", "time", "seeds")
           if k in record}
    sizes = {k: v for k, v in _dc.asdict(_budget.get(record["budget"])).items()
             if k.startswith("softflow_")}
    return {**out, "budget_sizes": sizes, "threads": 1, "wall_seconds": record["wall_seconds"],
            "toy": toy, "tasks": tasks, "cells": record["cells"]}, arrays


STUDY = cells.Study(NAME, "SoftFlow on the circle toy and on expert states (chapter 03)",
                    cells=cells_at, run_cell=run_cell, aggregate=aggregate,
                    result_file="softflow_fit_cells.json")


def _seeds_word(k: int, n: int, who: str) -> str:
    """``"{who} wins on every seed"``, ``"... on none of the N seeds"``, or ``"on k of N"``."""
    if k == n:
        return f"{who} wins on every seed"
    return f"{who} wins on none of the {n} seeds" if k == 0 else f"{who} wins on {k} of {n} seeds"


def toy_findings(fit: dict, arrays: dict, soft: str = "0.1") -> list[str]:
    """Chapter 03's statements on the circle toy, rendered from the record
    (:func:`fit_record`): per test-noise level how many seeds SoftFlow (``sigma_max`` =
    ``soft``) beats the plain CNF on, and by how much; the peaks of the seed-0 densities; and
    the squeeze in the plain CNF's held-out curves (where its NLL off the circle is lowest,
    and how far it climbs from there to the end, against SoftFlow's climb)."""
    toy = fit["toy"]
    s, gap = toy["summary"], toy["cnf_minus_softflow"]
    noises = sorted((k for k in gap if float(k) > 0), key=float)
    far = noises[-1]
    n = len(gap[far]["per_seed"])
    won = lambda k: sum(g > 0 for g in gap[k]["per_seed"])
    lines = [f"* **Off the circle** (test noise std {far}) {_seeds_word(won(far), n, 'SoftFlow')}"
             f": held-out NLL {s[soft][far]['mean']:.2f} ± {s[soft][far]['std']:.2f} nats "
             f"against the plain CNF's {s['0'][far]['mean']:.2f} ± {s['0'][far]['std']:.2f}, "
             f"the CNF minus SoftFlow per seed from {min(gap[far]['per_seed']):.1f} to "
             f"{max(gap[far]['per_seed']):.1f}."]
    for k in noises[:-1]:
        lines.append(f"* At noise {k} {_seeds_word(won(k), n, 'SoftFlow')} (CNF minus "
                     f"SoftFlow from {min(gap[k]['per_seed']):.1f} to "
                     f"{max(gap[k]['per_seed']):.1f} nats).")
    on = gap["0"]["per_seed"]
    cnf_won = _seeds_word(sum(g < 0 for g in on), n, "the plain CNF")
    lines.append(f"* **Exactly on the circle** {cnf_won} ({s['0']['0']['mean']:.2f} ± {s['0']['0']['std']:.2f} nats against "
                 f"SoftFlow's {s[soft]['0']['mean']:.2f} ± {s[soft]['0']['std']:.2f}); in the "
                 f"seed-0 images the plain CNF's density peaks at "
                 f"{float(arrays['toy_density_sigma_0'].max()):.0f}, SoftFlow's at "
                 f"{float(arrays[f'toy_density_sigma_{float(soft):g}'].max()):.0f}.")
    runs = lambda sigma: [r for r in toy["runs"] if r["sigma_max"] == sigma]
    cnf = [r["heldout_curve"] for r in runs(0.0)]
    best = [c["iteration"][int(np.argmin(c[far]))] for c in cnf]
    climb = [c[far][-1] - min(c[far]) for c in cnf]
    soft_climb = [r["heldout_curve"][far][-1] - min(r["heldout_curve"][far])
                  for r in runs(float(soft))]
    lines.append(f"* **The curves.** The plain CNF's NLL at noise {far} is lowest at step "
                 f"{min(best)} to {max(best)} of {cnf[0]['iteration'][-1]} and then climbs by "
                 f"{min(climb):.1f} to {max(climb):.1f} nats to the end; SoftFlow's climbs by "
                 f"at most {max(soft_climb):.2f}.")
    return lines
