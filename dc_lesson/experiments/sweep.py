"""The sweep engine: ``dc-lesson sweep STUDY [--budget B] [--only k=v ...] [--dry-run]
[--address ADDR] [--cpus N] [--hours H]``.

1. The study is expanded into its cells at the budget (:meth:`cells.Study.grid`: the cells a
   cell reads, such as the fresh expert reference, come with it); ``--only`` keeps the cells
   whose fields match (``task=reacher4``, ``seed=0,1``, ``learner=bc``, ``n_demos=4``).
2. The results folder is checked writable before any compute (a clear error otherwise).
3. Finished cells (a record with the same config hash) are skipped; ``--dry-run`` stops here and
   prints the cells left and their estimated cost, from the wall times of finished cells of
   the same row, task and budget (:func:`measured_costs`), else from the same learner's
   seconds per interaction on the task times the cell's own interactions
   (:func:`measured_rates`).
4. The rest run as Ray tasks, stage by stage (references first): a local Ray instance
   (``ray.init(num_cpus=N, include_dashboard=False)``, N = the machine's cores by default),
   one CPU and one torch thread per task; ``--address`` joins an existing Ray cluster instead.
   Cells start one per free worker, in the grid's order; with ``--hours H`` only those whose
   estimated cost (step 3) ends within H hours of the start (:func:`startable`), so a sweep
   given a session's length stops with every started cell written, never killed part way.
   Workers only compute; the driver writes each record atomically the moment its task ends, so
   a sweep killed at any moment keeps every finished cell, and a rerun computes exactly the
   missing ones.  A cell's numbers depend on nothing but the cell (its config and seed), so a
   resumed sweep ends with the same records as an uninterrupted one.
5. A progress bar shows cells done / running / left and an ETA from the finished cells' wall
   times; a failed cell is reported and left for the next run (the exit code says so).
6. When the grid is complete, the study is aggregated (:mod:`dc_lesson.experiments.aggregate`).
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import socket
import statistics
import tempfile
import time

from dc_lesson import budget as _budget, storage
from dc_lesson.experiments import cells as _cells

ONLY_KEYS = ("learner", "variant", "row", "task", "n_demos", "seed", "stage")


class SweepError(ValueError):
    """A sweep that cannot start (unknown study, bad ``--only``, unwritable folder)."""


def select(grid: list[_cells.Cell], only=(), with_needs: bool = True) -> list[_cells.Cell]:
    """The cells matching every ``k=v`` of ``only`` (``v`` may list values: ``seed=0,1``),
    with the cells they need (unless ``with_needs`` is False)."""
    wanted: dict[str, set[str]] = {}
    for item in only or ():
        key, sep, value = item.partition("=")
        if not sep or key not in ONLY_KEYS or not value:
            raise SweepError(f"--only takes KEY=VALUE with KEY one of {', '.join(ONLY_KEYS)}; "
                             f"got {item!r}")
        wanted.setdefault(key, set()).update(value.split(","))
    if not wanted:
        return list(grid)
    keep = [c for c in grid
            if all(str(getattr(c, k)) in v for k, v in wanted.items())]
    if not with_needs and keep:
        return keep
    out: dict[str, _cells.Cell] = {}
    for c in keep:
        for n in c.needs:
            out.setdefault(f"{n.study}/{n.task}/{n.name}", n)
        out.setdefault(f"{c.study}/{c.task}/{c.name}", c)
    if not keep:
        raise SweepError(f"--only {' '.join(only)} matches none of the study's {len(grid)} "
                         f"cells")
    return sorted(out.values(), key=lambda c: c.stage)


def check_writable(root) -> pathlib.Path:
    """Creates ``root`` and writes a file in it, or fails with what to do."""
    root = pathlib.Path(root)
    try:
        root.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=root, prefix=".write-check-"):
            pass
    except OSError as e:
        raise SweepError(f"the results folder {root} cannot be written ({e.strerror or e}); "
                         f"nothing was computed. Fix its permissions, or set DC_LESSON_DATA to "
                         f"a writable copy of the data folder") from None
    return root


def _finished(root=None):
    """Every readable cell record on disk (an unreadable one is skipped: it will rerun)."""
    for p in sorted(pathlib.Path(root or _cells.cells_root()).glob("*/*/*.json")):
        try:
            yield _cells.read_record(p)
        except _cells.CellError:
            continue


def measured_costs(root=None, since: str | None = None,
                   until: str | None = None) -> dict[tuple, list[float]]:
    """Wall seconds of every finished cell on disk, by (learner row, task, budget), for the
    cells that interact also by (learner row, task, budget, interactions), and by (learner
    row, task, budget, interactions or 0, study): a study's own cells first, since the same
    row of another study can differ in what it does (``modes``' ``bc-full`` trains for 40 s,
    ``table1``'s took minutes); with
    ``since`` / ``until`` (ISO times, UTC), of the cells finished in [since, until) only."""
    out: dict[tuple, list[float]] = {}
    for r in _finished(root):
        t = r["provenance"]["time"]
        if (since is not None and t < since) or (until is not None and t >= until):
            continue
        c = r["cell"]
        row = c["learner"] + (f"-{c['variant']}" if c["variant"] else "")
        key = (row, c["task"], r["provenance"]["budget"])
        out.setdefault(key, []).append(r["provenance"]["wall_seconds"])
        n = interactions(r["config"])
        if n:
            out.setdefault(key + (n,), []).append(r["provenance"]["wall_seconds"])
        out.setdefault(key + (n or 0, c.get("study")), []).append(r["provenance"]["wall_seconds"])
    return out


def interactions(config: dict) -> int | None:
    """The environment interactions a cell's run spends, from its config: DC's loops x
    iterations x batch (its ``steps`` is the budget's, whatever the loop overrides), else the
    cell's ``steps``; None for cells that interact with no environment budget (BC, flows)."""
    dc = config.get("dc")
    if isinstance(dc, dict) and {"loops", "iterations"} <= set(dc) and "ppo" in dc:
        return int(dc["loops"] * dc["iterations"] * dc["ppo"]["n_envs"] * dc["ppo"]["n_steps"])
    steps = config.get("steps")
    return int(steps) if isinstance(steps, (int, float)) and steps > 0 else None


def measured_rates(root=None) -> dict[tuple, list[float]]:
    """Wall seconds per interaction of every finished cell that interacts, by (learner, task,
    budget): the estimate of a new row (another loop count, another rate) from its
    learner's other rows on the task, scaled by its own interactions."""
    out: dict[tuple, list[float]] = {}
    for r in _finished(root):
        n = interactions(r["config"])
        if n:
            out.setdefault((r["cell"]["learner"], r["cell"]["task"],
                            r["provenance"]["budget"]), []).append(
                r["provenance"]["wall_seconds"] / n)
    return out


def estimate(cell: _cells.Cell, costs: dict, budget_name: str,
             rates: dict | None = None) -> float | None:
    """The median measured wall time of this study's cells like this one (same row, task,
    budget and interactions); else of any study's (a cell that interacts: the same
    interactions, since a row of another study that ran 100,000 says little of one that runs
    1.8M); else, with ``rates``, the median seconds per
    interaction of the same learner on the task times this cell's interactions; else the
    same learner's and task's median wall time; or None when none has run."""
    n = interactions(cell.config)
    v = (costs.get((cell.row, cell.task, budget_name, n or 0, cell.study))
         or costs.get((cell.row, cell.task, budget_name) + ((n,) if n else ())))
    # a variant row of a learner (competence's ``dc-mix``) is priced by its learner's cells
    per = ((rates or {}).get((cell.learner, cell.task, budget_name))
           or (rates or {}).get((cell.learner.split("-")[0], cell.task, budget_name)))
    if not v and per and n:
        return statistics.median(per) * n
    if not v:
        v = [s for (row, task, b, *_), w in costs.items() if not _ for s in w
             if b == budget_name and task == cell.task
             and row.split("-")[0] == cell.learner.split("-")[0]]
    return statistics.median(v) if v else None


def _fmt_s(s: float | None) -> str:
    if s is None:
        return "?"
    return f"{s:.0f} s" if s < 120 else (f"{s / 60:.1f} min" if s < 7200 else f"{s / 3600:.1f} h")


def plan(study: _cells.Study, b: _budget.Budget, only=(), root=None, workers: int = 1) -> dict:
    """What a sweep would do: every cell, done or not, the estimated cost of the rest."""
    grid = select(study.grid(b), only)
    costs = measured_costs(root)
    todo = [c for c in grid if not _cells.is_done(c, root)]
    rates = measured_rates(root)
    est = [estimate(c, costs, b.name, rates) for c in todo]
    known = [e for e in est if e is not None]
    return {"grid": grid, "todo": todo, "estimates": est,
            "cpu_seconds": sum(known), "unknown": len(est) - len(known),
            "wall_seconds": sum(known) / max(1, workers),
            # the cells of other studies it reads (the reference floor), counted apart so
            # that a plan's count and an aggregate's "N of its M cells" can be told apart
            "read": sum(c.study != study.name for c in grid),
            "read_todo": sum(c.study != study.name for c in todo)}


def count_words(p: dict) -> str:
    """A plan's cells in words: "252 cells (245 its own, 7 read from other studies)"."""
    n, read = len(p["grid"]), p["read"]
    return f"{n} cells" + (f" ({n - read} its own, {read} read from other studies)"
                           if read else "")


def _iso(since: str, flag: str = "--priced-since") -> str:
    import datetime
    try:
        t = datetime.datetime.fromisoformat(since)
    except ValueError:
        raise SweepError(f"{flag} {since!r} is not an ISO time; give e.g. "
                         f"2026-12-03T11:55 (UTC, as the cell records' provenance 'time')")
    if t.tzinfo is None:
        t = t.replace(tzinfo=datetime.timezone.utc)
    return t.astimezone(datetime.timezone.utc).isoformat(timespec="seconds")


def reprice(study: _cells.Study, b: _budget.Budget, since: str, only=(), root=None,
            workers: int = 2, until: str | None = None) -> dict:
    """The whole grid (done cells too) priced by the cells finished since ``since`` (and
    before ``until``): per cell the median wall time of its (row, task) among those, else of
    all cells (:func:`estimate`). What the grid costs on the machine, and under the load, of
    that window (a session with the machine given to the sweep alone measures an idle
    machine; the done cells' own wall times mix every load they ran under)."""
    since = _iso(since)
    until = None if until is None else _iso(until, "--priced-until")
    grid = select(study.grid(b), only)
    window, every = measured_costs(root, since, until), measured_costs(root)
    rates = measured_rates(root)
    priced = [(estimate(c, window, b.name), estimate(c, every, b.name, rates)) for c in grid]
    known = [w if w is not None else e for w, e in priced if (w or e) is not None]
    n_window = sum(len(v) for (_, _, bn, *n), v in window.items() if bn == b.name and not n)
    return {"since": since, "until": until, "cells": len(grid), "window_cells": n_window,
            "priced_from_window": sum(w is not None for w, _ in priced),
            "unknown": len(grid) - len(known), "cpu_seconds": sum(known),
            "wall_seconds": sum(known) / max(1, workers), "workers": workers}


def format_reprice(r: dict) -> str:
    return (f"the whole grid, {r['cells']} cells, priced by the {r['window_cells']} cells "
            f"finished since {r['since']}"
            + (f" and before {r['until']}" if r.get("until") else "")
            + f" ({r['priced_from_window']} cells priced from those, "
            f"the rest from every finished cell, {r['unknown']} unknown): "
            f"{_fmt_s(r['cpu_seconds'])} of CPU, {_fmt_s(r['wall_seconds'])} of wall time "
            f"on {r['workers']} worker(s)")


def format_plan(study: _cells.Study, b: _budget.Budget, p: dict, workers: int) -> str:
    groups: dict[tuple, list] = {}
    todo = {id(c): e for c, e in zip(p["todo"], p["estimates"])}
    for c in p["grid"]:
        groups.setdefault((c.study, c.row, c.task), []).append(c)
    lines = [f"sweep {study.name} at budget {b.name}: {len(p['grid'])} cells, "
             f"{len(p['grid']) - len(p['todo'])} done, {len(p['todo'])} to run",
             f"{'study':<13}{'row':<22}{'task':<14}{'cells':>6}{'to run':>7}{'per cell':>10}"
             f"{'total':>10}"]
    for (st, row, task), cs in groups.items():
        left = [todo[id(c)] for c in cs if id(c) in todo]
        per = next((e for e in left if e is not None), None)
        tot = sum(e for e in left if e is not None) if per is not None else None
        lines.append(f"{st:<13}{row:<22}{task:<14}{len(cs):>6}{len(left):>7}"
                     f"{_fmt_s(per) if left else '-':>10}{_fmt_s(tot) if left else '-':>10}")
    unknown = f" (+ {p['unknown']} cells never measured)" if p["unknown"] else ""
    lines.append(f"estimated cost: {_fmt_s(p['cpu_seconds'])} of CPU{unknown}; about "
                 f"{_fmt_s(p['wall_seconds'])} of wall time on {workers} worker(s)")
    lines.append("to run it: " + b.sweep_command.replace("STUDY", study.name))
    return "\n".join(lines)


def ledger(b: _budget.Budget, root=None, workers: int = 2) -> list[dict]:
    """The whole grid at budget ``b``, study by study (:data:`studies.BOOK`): its cells, how
    many are done, the CPU seconds the done ones took (their records' wall times: one worker,
    one torch thread each, on whichever machine ran them) and the estimated CPU seconds of the
    rest (:func:`plan`).  A cell two studies share (the fresh expert reference) is counted in
    the first.  ``workers`` divides the CPU seconds into wall time."""
    from dc_lesson.experiments import studies
    costs, rates = measured_costs(root), measured_rates(root)
    seen: set[str] = set()
    out = []
    for name in studies.BOOK:
        grid = [c for c in studies.get(name).grid(b)
                if f"{c.study}/{c.task}/{c.name}" not in seen]
        seen.update(f"{c.study}/{c.task}/{c.name}" for c in grid)
        done = [c for c in grid if _cells.is_done(c, root)]
        cpu_done = sum(_cells.read_record(c.path(root))["provenance"]["wall_seconds"]
                       for c in done)
        est = [estimate(c, costs, b.name, rates) for c in grid if not _cells.is_done(c, root)]
        out.append({"study": name, "cells": len(grid), "done": len(done),
                    "superseded": name in studies.SUPERSEDED,
                    "cpu_done": cpu_done, "left": len(est),
                    "cpu_left": sum(e for e in est if e is not None),
                    "unknown": sum(e is None for e in est)})
    return out


def format_ledger(rows: list[dict], b: _budget.Budget, workers: int) -> str:
    lines = [f"the book's whole grid at budget {b.name} (CPU time: one worker, one torch thread "
             f"per cell)",
             f"{'study':<14}{'cells':>7}{'done':>7}{'CPU done':>11}{'left':>7}{'CPU left':>11}"]
    for r in rows:
        unknown = f" + {r['unknown']} unmeasured" if r["unknown"] else ""
        lines.append(f"{r['study']:<14}{r['cells']:>7}{r['done']:>7}{_fmt_s(r['cpu_done']):>11}"
                     f"{r['left']:>7}{_fmt_s(r['cpu_left']):>11}{unknown}")
    done, left = sum(r["cpu_done"] for r in rows), sum(r["cpu_left"] for r in rows)
    lines.append(f"{'all':<14}{sum(r['cells'] for r in rows):>7}"
                 f"{sum(r['done'] for r in rows):>7}{_fmt_s(done):>11}"
                 f"{sum(r['left'] for r in rows):>7}{_fmt_s(left):>11}")
    lines.append(f"on {workers} worker(s): {_fmt_s(done / workers)} of wall time spent, about "
                 f"{_fmt_s(left / workers)} left, {_fmt_s((done + left) / workers)} in all")
    final = [r for r in rows if not r.get("superseded")]
    if len(final) < len(rows):
        f_done = sum(r["cpu_done"] for r in final)
        f_left = sum(r["cpu_left"] for r in final)
        old = [r["study"] for r in rows if r.get("superseded")]
        lines.append(f"the final grid, without the first grids it superseded ({', '.join(old)}: "
                     f"kept as the record): {_fmt_s(f_done)} of CPU done, about "
                     f"{_fmt_s(f_left)} left, {_fmt_s(f_done + f_left)} in all")
    return "\n".join(lines)


# -- running -------------------------------------------------------------------------------------

def execute(cell: _cells.Cell, needs) -> dict:
    """Runs one cell in this process (what a Ray task does), on one torch thread, on the
    fast path (``dc_lesson.nn.fast``: every stored cell was computed on it)."""
    import torch

    from dc_lesson.experiments import studies
    from dc_lesson.nn import fast
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    with fast.on():
        result, features = studies.get(cell.study).run_cell(cell, needs)
    return {"result": result, "features": features, "wall_seconds": time.perf_counter() - t0,
            "threads": torch.get_num_threads(), "host": socket.gethostname(),
            "platform": storage.platform_info()}


def _ray_env(b: _budget.Budget) -> dict:
    env = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "DC_LESSON_BUDGET": b.name}
    for k in ("MUJOCO_GL", "PYTHONPATH", "DC_LESSON_DATA"):
        if k in os.environ:
            env[k] = os.environ[k]
    return env


def check_cpus(cpus) -> None:
    """``cpus`` is None (every core) or a whole number of workers from 1: 0 would be read as
    "not given" and silently mean every core, as the CLI's ``--cpus 0`` once did."""
    if cpus is not None and (isinstance(cpus, bool) or not isinstance(cpus, int) or cpus < 1):
        raise SweepError(f"cpus must be a positive whole number of workers, got {cpus!r}; "
                         "leave it out for every core")


def start_ray(b: _budget.Budget, *, address: str | None = None, cpus: int | None = None):
    """A local Ray instance (``cpus`` workers, default all cores) or, with ``address``, the
    cluster there; a no-op when Ray is already running in this process.  Returns whether this
    call started it (then the sweep shuts it down)."""
    check_cpus(cpus)
    try:
        import ray
    except ImportError:
        raise SweepError("the sweep runs on Ray, which is not installed: "
                         "pip install -e '.[sweep]'") from None
    if ray.is_initialized():
        return False
    kwargs = dict(include_dashboard=False, runtime_env={"env_vars": _ray_env(b)},
                  logging_level="ERROR", configure_logging=True)
    if address:
        ray.init(address=address, **kwargs)
    else:
        ray.init(num_cpus=int(cpus or os.cpu_count() or 1), **kwargs)
    return True


@dataclasses.dataclass
class SweepReport:
    study: str
    budget: str
    cells: int
    skipped: int
    ran: int
    failed: list
    wall_seconds: float
    aggregate: pathlib.Path | None = None
    deferred: int = 0     # cells not started because they would have ended after the deadline


def startable(queue: list, estimates: dict, free: int, now: float,
              deadline: float | None) -> list:
    """Which queued cells to start now, in queue order: at most ``free`` of them, and with a
    ``deadline`` (a ``time.time()``) only those whose estimated cost (``estimates[cell]``,
    seconds; a cell never measured counts as free) would end before it.  A cell that would
    not fit is passed over, so a cheaper one later in the queue can still use the time."""
    out = []
    for c in queue:
        if len(out) >= free:
            break
        if deadline is None or now + (estimates.get(c) or 0.0) <= deadline:
            out.append(c)
    return out


def run(study_name: str, b: _budget.Budget | None = None, *, only=(), address=None, cpus=None,
        root=None, results=None, command: str = "", progress: bool = True,
        aggregate: bool = True, hours: float | None = None) -> SweepReport:
    """The sweep (module docstring).  ``root`` is the cells folder (default
    ``DATA/results/cells``), ``results`` where the aggregate goes (default ``DATA/results``).

    ``hours``: a deadline that many hours from now.  Cells are started one per free worker
    (:func:`startable`), only those whose estimated cost ends before the deadline; cells
    running at the deadline finish, so a session of fixed length stops with every started
    cell written instead of killing cells part way (``SweepReport.deferred`` counts the rest,
    which the next run picks up)."""
    check_cpus(cpus)   # before anything is touched, as on the command line
    from dc_lesson import progress as _progress
    from dc_lesson.experiments import studies
    b = b or _budget.current()
    study = studies.get(study_name)
    root = pathlib.Path(root or _cells.cells_root())
    check_writable(root)
    if aggregate and study.aggregate is not None:
        from dc_lesson.experiments import aggregate as _aggregate
        _aggregate.check_output(study.name, results)   # a complete sweep ends by writing it
    import ray
    p = plan(study, b, only, root)
    grid, todo = p["grid"], p["todo"]
    costs = measured_costs(root)
    estimates = dict(zip(map(id, todo), p["estimates"]))
    deadline = None if hours is None else time.time() + 3600.0 * hours
    t0 = time.perf_counter()
    failed, ran, deferred = [], 0, 0
    if todo:
        started = start_ray(b, address=address, cpus=cpus)
        workers = int(ray.cluster_resources().get("CPU", 1))
        remote = ray.remote(num_cpus=1, max_retries=0)(execute)
        walls: dict[tuple, list[float]] = {}
        remaining = list(todo)
        bar = _progress.bar(total=len(todo), desc=f"sweep {study.name}", unit="cell",
                            enabled=progress)
        try:
            for stage in sorted({c.stage for c in todo}):
                queue = [c for c in todo if c.stage == stage]
                pending = {}

                def submit():   # fill the free workers with the cells that fit
                    go = set(startable([id(c) for c in queue], estimates,
                                       workers - len(pending), time.time(), deadline))
                    for c in [c for c in queue if id(c) in go]:
                        queue.remove(c)
                        needs = [_cells.load(n, root) for n in c.needs]
                        pending[remote.remote(c, needs)] = c

                submit()
                while pending:
                    running = min(len(pending), workers)
                    until = ("" if deadline is None else ", deadline "
                             + time.strftime("%H:%M", time.localtime(deadline)))
                    bar.set_postfix_str(f"running {running}, left {len(remaining) - running}, "
                                        f"ETA {_fmt_s(_eta(remaining, walls, costs, b, workers))}"
                                        + until)
                    ready, _ = ray.wait(list(pending), num_returns=1)
                    cell = pending.pop(ready[0])
                    remaining.remove(cell)
                    try:
                        out = ray.get(ready[0])
                    except Exception as e:   # a failed cell: reported, left for the next run
                        failed.append((cell.name, str(e).splitlines()[-1][:300]))
                        bar.write(f"FAILED {cell.study}/{cell.task}/{cell.name}: {failed[-1][1]}")
                        bar.update(1)
                        submit()
                        continue
                    prov = _cells.provenance(command=command, budget=b.name,
                                             threads=out["threads"],
                                             wall_seconds=out["wall_seconds"], host=out["host"],
                                             platform=out.get("platform"))
                    _cells.write_record(cell, out["result"], out["features"], prov, root)
                    walls.setdefault((cell.row, cell.task), []).append(out["wall_seconds"])
                    ran += 1
                    bar.update(1)
                    submit()
                deferred += len(queue)
                if queue:   # past the deadline: later stages would not fit either
                    deferred += sum(c.stage > stage for c in todo)
                    bar.write(f"deadline: {deferred} cells left for the next run")
                    break
        finally:
            bar.close()
            if started:
                ray.shutdown()
    report = SweepReport(study.name, b.name, len(grid), len(grid) - len(todo), ran, failed,
                         time.perf_counter() - t0, deferred=deferred)
    complete = all(_cells.is_done(c, root) for c in study.grid(b))
    if aggregate and complete and study.aggregate is not None:
        from dc_lesson.experiments import aggregate as _aggregate
        report.aggregate = _aggregate.write(study.name, b, root=root, results=results,
                                            command=command)
    return report


def _eta(left, walls, costs, b, workers) -> float | None:
    done = [w for v in walls.values() for w in v]
    total = 0.0
    for c in left:
        mine = walls.get((c.row, c.task))
        e = statistics.mean(mine) if mine else estimate(c, costs, b.name)
        if e is None and done:
            e = statistics.mean(done)
        if e is None:
            return None
        total += e
    return total / max(1, workers)


__all__ = ["ONLY_KEYS", "SweepError", "SweepReport", "check_cpus", "check_writable", "estimate",
           "execute",
           "format_plan", "interactions", "ledger", "format_ledger", "measured_costs",
           "measured_rates",
           "plan", "run", "select", "start_ray", "startable"]
