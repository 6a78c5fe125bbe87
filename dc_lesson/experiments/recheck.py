"""Rerunning finished cells against their records: ``dc-lesson sweep STUDY --recheck N``.

A sweep never recomputes a finished cell; this does, on purpose, to ask whether the numbers
on record are the numbers today's code gives on this machine.  It reruns up to ``N`` finished
cells of a study (those ``--only`` matches, learners before the reference cells) one at a
time in a fresh process with a sweep worker's environment (one thread for torch, OpenMP and
MKL; the budget), compares every number of the new result and every array of its mode
features with the record (wall-clock entries aside), and writes nothing.  Each row says
whether the cell came out identical and, if not, how many numbers differ, the first of them
and the one that differs most relative to its size.

How to read a difference: a record keeps the ``platform`` it was computed on (CPU, vector
unit, library versions; records older than 2026-12-03 have none).  On the same platform a
difference means the code changed the cell's numbers (``dc-lesson`` then exits with status
1).  On another platform it is expected: NumPy's and PyTorch's kernels are chosen for the
CPU at run time, so float rounding differs in the last bits, and a learner turns that into
another trajectory.  The cell is then another sample of the same experiment, which the
verdicts, built on the spread over seeds, allow for.
"""

from __future__ import annotations

import concurrent.futures
import math
import multiprocessing
import os

import numpy as np

from dc_lesson import budget as _budget, storage
from dc_lesson.experiments import cells as _cells, studies, sweep as _sweep

# what "the same platform" compares: the machine and the numerical libraries
PLATFORM_KEYS = ("cpu", "torch_cpu_capability", "numpy", "torch", "mujoco")


def differences(stored, new, path: str = "") -> list[tuple[str, object, object]]:
    """Every ``(path, stored, new)`` where two results differ (NaN equals NaN)."""
    if isinstance(stored, dict) and isinstance(new, dict):
        out = []
        for k in sorted(set(stored) | set(new)):
            if k not in stored or k not in new:
                out.append((f"{path}/{k}", stored.get(k, "absent"), new.get(k, "absent")))
            else:
                out += differences(stored[k], new[k], f"{path}/{k}")
        return out
    if isinstance(stored, list) and isinstance(new, list):
        if len(stored) != len(new):
            return [(f"{path} (length)", len(stored), len(new))]
        return [d for i, (a, b) in enumerate(zip(stored, new))
                for d in differences(a, b, f"{path}[{i}]")]
    if isinstance(stored, float) and isinstance(new, float) and math.isnan(stored) \
            and math.isnan(new):
        return []
    return [] if stored == new else [(path, stored, new)]


def _largest(diffs) -> tuple[str, float, float, float] | None:
    """The numeric difference largest relative to its size: ``(path, stored, new, relative)``
    (numbers of every scale sit side by side in a result: returns, scaled returns, KLs)."""
    best = None
    for path, a, b in diffs:
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                   for x in (a, b)):
            continue
        rel = abs(a - b) / max(abs(a), abs(b))
        if best is None or rel > best[3]:
            best = (path, a, b, rel)
    return best


def _feature_differences(stored: dict, new: dict | None) -> list:
    new = {k: np.asarray(v, np.float32) for k, v in (new or {}).items()}   # as recorded
    return [(f"features/{k}", "array", "array") for k in sorted(set(stored) | set(new))
            if k not in stored or k not in new or not np.array_equal(stored[k], new[k])]


def _in_a_worker(cell, needs, b: _budget.Budget) -> dict:
    """:func:`sweep.execute` in a fresh process with a sweep worker's environment."""
    saved = dict(os.environ)
    os.environ.update(_sweep._ray_env(b))
    try:
        with concurrent.futures.ProcessPoolExecutor(
                1, mp_context=multiprocessing.get_context("spawn")) as pool:
            return pool.submit(_sweep.execute, cell, needs).result()
    finally:
        os.environ.clear()
        os.environ.update(saved)


def recheck(study_name: str, b: _budget.Budget, only=(), limit: int = 3, root=None,
            log=print) -> list[dict]:
    """Reruns up to ``limit`` finished cells of ``study_name`` that ``only`` matches and
    compares them with their records: one row per cell."""
    study = studies.get(study_name)
    chosen = _sweep.select(study.grid(b), only, with_needs=False)
    done = sorted((c for c in chosen if _cells.is_done(c, root)),
                  key=lambda c: c.stage == 0)      # learners first, references last
    if not done:
        raise _sweep.SweepError(f"no finished cell of {study_name} matches; --recheck reruns "
                                "cells a sweep has finished (see --dry-run)")
    here = storage.platform_info()
    rows = []
    for cell in done[:limit]:
        missing = [n.name for n in cell.needs if not _cells.is_done(n, root)]
        if missing:
            raise _sweep.SweepError(f"{cell.name} reads {', '.join(missing)}, which has no "
                                    f"record; run dc-lesson sweep {study_name} first")
        record, features = _cells.load(cell, root)
        out = _in_a_worker(cell, [_cells.load(n, root) for n in cell.needs], b)
        new, _ = _cells.record_form(out["result"])
        diffs = (differences(record["result"], new)
                 + _feature_differences(features, out["features"]))
        then = record["provenance"].get("platform")
        row = {"cell": f"{cell.study}/{cell.task}/{cell.name}", "identical": not diffs,
               "numbers_differing": len(diffs), "largest": _largest(diffs),
               "first": None if not diffs else f"{diffs[0][0]}: {diffs[0][1]} -> {diffs[0][2]}",
               "recorded_on": (then or {}).get("torch_cpu_capability", "not recorded"),
               "same_platform": None if then is None else
               all(then.get(k) == here.get(k) for k in PLATFORM_KEYS),
               "seconds": out["wall_seconds"]}
        rows.append(row)
        log(format_row(row))
    return rows


def format_row(row: dict) -> str:
    if row["identical"]:
        verdict = "identical"
    elif row["largest"] is not None:
        path, a, b, rel = row["largest"]
        verdict = (f"{row['numbers_differing']} numbers differ, most at {path}: {a:.6g} -> "
                   f"{b:.6g} ({100 * rel:.2g}% of it)")
    else:
        verdict = f"{row['numbers_differing']} entries differ (first {row['first']})"
    where = {True: "same platform", False: f"another platform ({row['recorded_on']})",
             None: "platform not recorded"}[row["same_platform"]]
    return f"{row['cell']}: {verdict} [{where}; {row['seconds']:.0f} s]"


__all__ = ["PLATFORM_KEYS", "differences", "format_row", "recheck"]
