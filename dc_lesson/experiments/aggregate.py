"""From cells to the tables the book reads: ``dc-lesson aggregate STUDY`` (and the end of a
complete sweep).

A study turns each of its records into *observations*: one per policy the cell evaluated, a
flat dict ``{"row", "task", "n_demos", "seed", measure: value, ...}`` (a GAIL cell gives two,
its BC warm start and GAIL).  Then

* :func:`table`: per (row, task, n_demos), each measure's mean over seeds, its 95% bootstrap
  interval (:func:`stats.mean_ci`), the sample std, the values per seed, and the mean mode
  shares;
* :func:`paired`: per (task, n_demos), the per-seed differences ``a - b`` of two rows that share
  their seeds (and so their warm start), mean and interval (:func:`stats.paired_diff`);
* :func:`iqm_over_tasks`: the IQM of one row's measure over tasks and seeds, with its
  stratified interval (where the paper's aggregate is across tasks).

The aggregate goes to ``data/results/STUDY.json`` with the command, budget, revision and time,
and the count, revisions and summed wall time of the cells it was made from (``wall_seconds``:
the cells' compute, one worker's worth, whatever the number of workers that ran them).  Only cells of the
study's current grid count (a record left from an older config is ignored, not mixed in).
"""

from __future__ import annotations

import datetime
import json
import pathlib

import numpy as np

from dc_lesson import budget as _budget
from dc_lesson import storage
from dc_lesson.evaluation import stats
from dc_lesson.experiments import cells as _cells

MEASURES = ("scaled_return", "return", "emd", "kl", "rkl")
KEY = ("row", "task", "n_demos")


class AggregateError(ValueError):
    """A study whose grid is not complete, or observations that cannot be paired."""


def observation(record: dict, measures: dict, row: str | None = None, **extra) -> dict:
    """One policy's measures in a cell, as a flat observation."""
    c = record["cell"]
    row = row or (c["learner"] + (f"-{c['variant']}" if c["variant"] else ""))
    return {"row": row, "task": c["task"], "n_demos": c["n_demos"], "seed": c["seed"],
            **{k: v for k, v in measures.items()}, **extra}


def _groups(obs, key=KEY) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for o in obs:
        out.setdefault(tuple(o[k] for k in key), []).append(o)
    return out


def table(obs: list[dict], measures=MEASURES, key=KEY) -> list[dict]:
    """One row per (row, task, n_demos): mean, 95% interval, std and per-seed values."""
    out = []
    for k, rows in _groups(obs, key).items():
        rows = sorted(rows, key=lambda o: o["seed"])
        entry = {**dict(zip(key, k)), "n_seeds": len(rows), "seeds": [o["seed"] for o in rows]}
        for m in measures:
            if not all(m in o and o[m] is not None for o in rows):
                continue
            v = np.array([o[m] for o in rows], np.float64)
            ci = stats.mean_ci(v)
            entry[f"{m}_mean"], entry[f"{m}_lo"], entry[f"{m}_hi"] = ci.mean, ci.lo, ci.hi
            entry[f"{m}_std"] = float(v.std(ddof=1)) if len(v) > 1 else 0.0
            entry[f"{m}_values"] = v.tolist()
        shares = [o["mode_shares"] for o in rows if o.get("mode_shares")]
        if shares:
            entry["mode_shares_mean"] = {m: float(np.mean([s[m] for s in shares]))
                                         for m in shares[0]}
            entry["mode_shares_per_seed"] = shares
        out.append(entry)
    return out


def paired(obs: list[dict], a: str, b: str, measures=MEASURES, by=("task", "n_demos")) -> list:
    """Per ``by`` group: the per-seed differences row ``a`` minus row ``b`` over the seeds both
    have, mean and 95% interval.  Skips groups where one of the rows is missing."""
    out = []
    for k, rows in _groups(obs, by).items():
        ra = {o["seed"]: o for o in rows if o["row"] == a}
        rb = {o["seed"]: o for o in rows if o["row"] == b}
        seeds = sorted(set(ra) & set(rb))
        if not seeds:
            continue
        entry = {**dict(zip(by, k)), "a": a, "b": b, "n_seeds": len(seeds), "seeds": seeds}
        for m in measures:
            if any(ra[s].get(m) is None or rb[s].get(m) is None for s in seeds):
                continue
            ci = stats.paired_diff([ra[s][m] for s in seeds], [rb[s][m] for s in seeds])
            entry[m] = ci.to_dict()
            entry[f"{m}_diffs"] = [ra[s][m] - rb[s][m] for s in seeds]
        out.append(entry)
    return out


def iqm_over_tasks(obs: list[dict], row: str, measure: str = "scaled_return") -> dict | None:
    """IQM of ``row``'s ``measure`` over (task, seed), with its stratified interval; uses the
    seeds every task has."""
    by_task = {}
    for o in obs:
        if o["row"] == row and o.get(measure) is not None:
            by_task.setdefault(o["task"], {})[o["seed"]] = o[measure]
    if not by_task:
        return None
    seeds = sorted(set.intersection(*(set(v) for v in by_task.values())))
    if not seeds:
        return None
    x = np.array([[by_task[t][s] for t in by_task] for s in seeds])
    return {"row": row, "measure": measure, "tasks": list(by_task), "seeds": seeds,
            **stats.iqm_ci(x).to_dict()}


def _own_cells(study: _cells.Study, b: _budget.Budget) -> list:
    """The study's own cells at a budget (not the cells of other studies it reads)."""
    return [c for c in study.grid(b) if c.study == study.name]


def grid_records(study: _cells.Study, b: _budget.Budget, root=None,
                 partial: bool = False) -> list[dict]:
    """The records of the study's current grid; fails, naming the command, if any is missing
    (with ``partial``: the records that exist, none of the missing ones invented)."""
    grid = _own_cells(study, b)
    missing = [c for c in grid if not c.path(root).exists()]
    if partial:
        if len(missing) == len(grid):
            raise AggregateError(f"none of the {len(grid)} cells of {study.name} at budget "
                                 f"{b.name} has run; run: dc-lesson sweep {study.name} "
                                 f"--budget {b.name}")
        return [_cells.read_record(c.path(root)) for c in grid if c not in missing]
    if missing:
        raise AggregateError(f"{len(missing)} of the {len(grid)} cells of {study.name} at budget "
                             f"{b.name} have not run (first: {missing[0].task}/{missing[0].name});"
                             f" run: dc-lesson sweep {study.name} --budget {b.name}")
    return [_cells.read_record(c.path(root)) for c in grid]


def todays_grid(rec: dict, root=None) -> tuple[int, int]:
    """``(done, of)``: how many cells of today's grid for a stored aggregate's study and budget
    have a record.  A changed setting gives new cells (new config hashes), so an aggregate of
    the earlier ones can outlive its grid while the new one runs."""
    from dc_lesson.experiments import studies
    study = studies.get(rec["benchmark"])
    grid = _own_cells(study, _budget.get(rec["budget"]))
    return sum(c.path(root).exists() for c in grid), len(grid)


def freshness(rec: dict, root=None) -> str:
    """"" when a stored aggregate is of today's grid; else a sentence saying how far today's
    grid has run and that the numbers shown are the stored aggregate's."""
    done, of = todays_grid(rec, root)
    if done == rec["cells"]["n"] and of == rec["cells"].get("of", of):
        return ""
    return (f"today's code has {done} of its {of} {rec['benchmark']} cells on record (a "
            f"changed setting gives new cells; they are being computed): the numbers shown "
            f"are the stored aggregate's, until `dc-lesson aggregate {rec['benchmark']}` "
            f"reruns on today's grid")


def check_output(study_name: str, results=None) -> pathlib.Path:
    """The file :func:`write` will write for ``study_name``, checked writable before any
    record is read or any interval computed; :class:`AggregateError` names the folder and
    the fix.  Returns the path."""
    from dc_lesson.experiments import studies
    study = studies.get(study_name)
    path = pathlib.Path(results or storage.RESULTS) / (study.result_file or f"{study.name}.json")
    try:
        storage.check_writable(path)
    except storage.OutputPathError as e:
        fix = ("choose another results folder" if results is not None else
               f"set {storage.DATA_ENV} to a writable copy of the data folder (cp -r "
               f"{storage.data_root()}/. COPY; then {storage.DATA_ENV}=COPY)")
        why = str(e).removesuffix("; choose another path")
        raise AggregateError(f"the results folder {path.parent} cannot be written, so the "
                             f"aggregate of {study.name} would be lost ({why}); nothing was "
                             f"computed. Fix the folder's permissions, or {fix}") from None
    return path


def write(study_name: str, b: _budget.Budget | None = None, *, root=None, results=None,
          command: str = "", partial: bool = False) -> pathlib.Path:
    """Aggregates a complete study and writes ``RESULTS/STUDY.json``; returns the path.

    ``partial``: aggregate the cells that have run so far (a grid still accumulating); the
    record's ``cells`` says how many of how many, and ``complete`` is False."""
    from dc_lesson.experiments import studies
    b = b or _budget.current()
    study = studies.get(study_name)
    if study.aggregate is None:
        raise AggregateError(f"study {study.name} has no aggregate (it is read by others)")
    path = check_output(study.name, results)   # a read-only data folder fails here, not after
    recs = grid_records(study, b, root, partial=partial)
    n_grid = len(_own_cells(study, b))
    payload = study.aggregate(recs, b)
    record = {"command": command or f"dc-lesson aggregate {study.name} --budget {b.name}",
              "benchmark": study.name, "budget": b.name, "revision": storage.git_revision(),
              "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "seeds": sorted({r["cell"]["seed"] for r in recs}),
              "complete": len(recs) == n_grid,
              "cells": {"n": len(recs), "of": n_grid,
                        "revisions": sorted({r["provenance"]["revision"] for r in recs}),
                        "wall_seconds": float(sum(r["provenance"]["wall_seconds"]
                                                  for r in recs)),
                        "folder": f"results/cells/{study.name}"},
              "wall_seconds": float(sum(r["provenance"]["wall_seconds"] for r in recs)),
              **payload}
    storage.atomic_write_text(path, json.dumps(_no_nan(record), indent=1, default=float,
                                               allow_nan=False) + "\n")
    return path


def _no_nan(x):
    """JSON has no NaN: an interval that does not exist (one seed) is written as null."""
    if isinstance(x, float) and not np.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _no_nan(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_no_nan(v) for v in x]
    return x


def costs(study: str, budget_name: str, since: str | None = None,
          until: str | None = None) -> list[dict]:
    """Per (task, row) of ``study``'s cells at ``budget_name`` that have run: their mean wall
    time in minutes (one worker, one torch thread; the whole cell: start, run and
    evaluations), how many cells that is, and, for the learners that interact, the median
    training seconds per 100,000 interactions (``train_per_100k``: the run alone; a median,
    robust to a cell that shared its core).

    ``since`` and ``until`` (ISO times, e.g. ``"2026-12-02T05:00"``) keep only the cells
    written between them: cells written on different machines must not be averaged into one
    cost."""
    from dc_lesson.experiments import studies
    walls: dict = {}
    for c in studies.get(study).grid(_budget.get(budget_name)):
        if c.study != study or not c.path().exists():
            continue
        r = _cells.read_record(c.path())
        when = r["provenance"]["time"]
        if (since is not None and when < since) or (until is not None and when >= until):
            continue
        steps, train = r["config"].get("steps"), r["timing"].get("train_seconds")
        walls.setdefault((c.task, c.row), []).append(
            (r["provenance"]["wall_seconds"],
             train / steps * 1e5 if steps and train is not None else None))
    out = []
    for (t, row), w in walls.items():
        per = [x for _, x in w if x is not None]
        out.append({"task": t, "row": row, "minutes": sum(x for x, _ in w) / len(w) / 60,
                    "cells": len(w), "train_per_100k": float(np.median(per)) if per else None})
    return out


__all__ = ["AggregateError", "KEY", "MEASURES", "check_output", "costs", "freshness",
           "grid_records", "iqm_over_tasks", "observation", "paired", "table", "todays_grid", "write"]
