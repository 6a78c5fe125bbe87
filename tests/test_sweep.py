"""The sweep engine through Ray's local instance (one, module-scoped: it takes seconds to start):
a sweep killed part-way and rerun ends with the same cell records as an uninterrupted one; an
unwritable results folder fails before any compute; the dry run estimates from measured cells.

The grid is bc_demos at the smoke budget on reacher4 only: the fresh reference, BC on 2
demonstrations with 2 seeds, and the expert row's 2 samples.
"""

import dataclasses
import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest

from dc_lesson import budget, storage
from dc_lesson.experiments import cells, studies, sweep

ray = pytest.importorskip("ray")
TINY = dataclasses.replace(budget.get("smoke"), bc_demo_counts=(2,), sweep_seeds_reacher=2)
ONLY = ["task=reacher4"]
ROOT = pathlib.Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def local_ray():
    sweep.start_ray(TINY, cpus=2)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def uninterrupted(local_ray, tmp_path_factory):
    root = tmp_path_factory.mktemp("a") / "cells"
    report = sweep.run("bc_demos", TINY, only=ONLY, root=root, progress=False)
    return root, report


def _results(root) -> dict:
    out = {}
    for p in sorted(pathlib.Path(root).glob("*/*/*.json")):
        r = cells.read_record(p)
        out[str(p.relative_to(root))] = (r["cell"], r["config"], r["result"])
    return out


def test_an_uninterrupted_sweep_runs_every_cell_once(uninterrupted):
    root, report = uninterrupted
    assert (report.cells, report.ran, report.skipped, report.failed) == (5, 5, 0, [])
    assert len(_results(root)) == 5
    for p in root.glob("*/*/*.json"):
        prov = json.loads(p.read_text())["provenance"]
        assert prov["torch_threads"] == 1 and prov["budget"] == "smoke"
        assert prov["platform"]["torch_cpu_capability"]    # taken in the worker that ran it
        assert prov["wall_seconds"] > 0
    again = sweep.run("bc_demos", TINY, only=ONLY, root=root, progress=False)
    assert (again.ran, again.skipped) == (0, 5)     # nothing is ever recomputed


def test_a_sweep_stopped_part_way_and_rerun_gives_the_same_records(uninterrupted, tmp_path):
    root_a, _ = uninterrupted
    root_b = tmp_path / "cells"
    first = sweep.run("bc_demos", TINY, only=ONLY + ["seed=0"], root=root_b, progress=False)
    assert first.ran == 3 and len(_results(root_b)) == 3    # stopped after 3 of 5 cells
    # A killed sweep can also leave a temporary file behind: it is not a record.
    (root_b / "bc_demos" / "reacher4" / "bc__n2__s1__x.json.123.tmp").write_text("{")
    rest = sweep.run("bc_demos", TINY, only=ONLY, root=root_b, progress=False)
    assert (rest.ran, rest.skipped) == (2, 3)
    assert _results(root_b) == _results(root_a)


def test_the_dry_run_estimates_from_measured_cells(uninterrupted, tmp_path):
    root_a, _ = uninterrupted
    study = studies.get("bc_demos")
    p = sweep.plan(study, TINY, ONLY, root_a)
    assert p["todo"] == [] and p["cpu_seconds"] == 0
    # The reference floor it reads is counted apart from its own cells (chapter 06's lines).
    assert (p["read"], p["read_todo"]) == (1, 0)
    assert sweep.count_words(p) == "5 cells (4 its own, 1 read from other studies)"
    # Copy the finished cells but one: its estimate is the wall time of its measured twin.
    for src in root_a.glob("*/*/*"):
        dst = tmp_path / src.relative_to(root_a)
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.write_bytes(src.read_bytes())
    victim = next(tmp_path.glob("bc_demos/reacher4/bc__n2__s1__*.json"))
    twin = json.loads(next(tmp_path.glob("bc_demos/reacher4/bc__n2__s0__*.json"))
                      .read_text())["provenance"]["wall_seconds"]
    victim.unlink()
    p = sweep.plan(study, TINY, ONLY, tmp_path)
    assert [c.seed for c in p["todo"]] == [1] and p["cpu_seconds"] == pytest.approx(twin)
    assert p["read_todo"] == 0      # the missing cell is its own
    assert "to run" in sweep.format_plan(study, TINY, p, 1)


def test_an_unwritable_results_folder_fails_before_any_compute(tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    def no_compute(*a, **k):
        raise AssertionError("computed before checking the folder")
    monkeypatch.setattr(sweep, "start_ray", no_compute)
    with pytest.raises(sweep.SweepError, match="cannot be written.*nothing was computed"):
        sweep.run("bc_demos", TINY, only=ONLY, root=blocker / "cells", progress=False)
    from dc_lesson import cli
    monkeypatch.setenv(storage.DATA_ENV, str(blocker))
    assert cli.main(["sweep", "bc_demos", "--budget", "smoke"]) == 2


def test_a_killed_sweep_process_resumes_to_the_same_records(uninterrupted, tmp_path):
    """The real thing: `dc-lesson sweep` in a process of its own, killed (SIGKILL, with its Ray
    workers) once the reference is stored and BC is running, then run again to the end."""
    root_a, _ = uninterrupted
    data = tmp_path / "data"
    (data / "results").mkdir(parents=True)
    for sub in ("demos", "experts"):
        (data / sub).symlink_to(storage.DATA / sub)
    env = {**os.environ, storage.DATA_ENV: str(data), "DC_LESSON_BUDGET": "smoke",
           "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, "-m", "dc_lesson.cli", "sweep", "bc_demos", "--cpus", "1",
           "--only", "task=reacher4", "n_demos=2", "seed=0"]
    log = open(tmp_path / "killed.log", "w")
    proc = subprocess.Popen(cmd, env=env, cwd=tmp_path, start_new_session=True,
                            stdout=log, stderr=subprocess.STDOUT)
    cells_dir = data / "results" / "cells"
    deadline = time.time() + 480
    while time.time() < deadline and not list(cells_dir.glob("reference/*/*.json")):
        time.sleep(0.5)
    os.killpg(proc.pid, signal.SIGKILL)      # the process group this test started
    proc.wait()
    log.close()
    killed_with = len(list(cells_dir.glob("*/*/*.json")))
    assert proc.returncode == -signal.SIGKILL and killed_with == 1, \
        (tmp_path / "killed.log").read_text()[-3000:]
    done = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    b = _results(cells_dir)
    a = _results(root_a)
    assert len(b) == 2 and all(b[k] == a[k] for k in b)   # the reference and BC seed 0


def test_a_new_row_is_estimated_from_its_learners_cost_per_interaction():
    """A row no cell of which has run (another loop count) is estimated from the same
    learner's measured seconds per interaction on the task, times its own interactions (DC's
    from its loops and iterations, not the budget's steps it carries)."""
    from dc_lesson.experiments.studies import dc_ablation
    lesson = budget.get("lesson")
    grid = {c.variant: c for c in dc_ablation.cells_at(lesson) if c.seed == 0}
    one, four = grid["loops=1"], grid["loops=4"]
    assert sweep.interactions(four.config) == 4 * sweep.interactions(one.config)
    assert one.config["steps"] == four.config["steps"]          # what a naive estimate reads
    rates = {("dc", "hopper", "lesson"): [0.001, 0.002, 0.003]}
    costs = {("dc-loops=2", "hopper", "lesson"): [120.0]}
    assert sweep.estimate(four, costs, "lesson", rates) == pytest.approx(
        0.002 * sweep.interactions(four.config))
    assert sweep.estimate(one, costs, "lesson", rates) == pytest.approx(
        0.002 * sweep.interactions(one.config))
    costs[("dc-loops=4", "hopper", "lesson")] = [300.0]           # the row at other steps:
    assert sweep.estimate(four, costs, "lesson", rates) == pytest.approx(   # the rate wins
        0.002 * sweep.interactions(four.config))
    costs[("dc-loops=4", "hopper", "lesson", sweep.interactions(four.config))] = [300.0]
    assert sweep.estimate(four, costs, "lesson", rates) == 300.0   # measured: its own row wins
    costs[("dc-loops=4", "hopper", "lesson", sweep.interactions(four.config),
           four.study)] = [200.0]
    assert sweep.estimate(four, costs, "lesson", rates) == 200.0   # and its own study first
    variant = dataclasses.replace(one, learner="dc-mix")
    assert sweep.estimate(variant, {}, "lesson", rates) == pytest.approx(   # its learner's rate
        0.002 * sweep.interactions(variant.config))
    assert sweep.interactions({"steps": 0}) is None               # BC: no interactions


def test_the_ledger_counts_each_cell_once_and_sums_the_done_cells_wall_time(uninterrupted):
    """`dc-lesson sweep all --dry-run`: every cell of the book's studies once (a reference two
    studies read is counted in the first), the done ones with their records' wall time; the
    superseded studies are not in it."""
    root, _ = uninterrupted
    rows = {r["study"]: r for r in sweep.ledger(TINY, root, workers=2)}
    assert set(rows) == set(studies.BOOK)
    done = list(pathlib.Path(root).glob("*/*/*.json"))
    assert sum(r["done"] for r in rows.values()) == len(done) > 0
    wall = sum(json.loads(p.read_text())["provenance"]["wall_seconds"] for p in done)
    assert sum(r["cpu_done"] for r in rows.values()) == pytest.approx(wall)
    unique = {f"{c.study}/{c.task}/{c.name}" for n in studies.BOOK
              for c in studies.get(n).grid(TINY)}
    assert sum(r["cells"] for r in rows.values()) == len(unique)
    assert all(r["left"] == r["cells"] - r["done"] for r in rows.values())
    text = sweep.format_ledger(list(rows.values()), TINY, 2)
    assert "on 2 worker(s)" in text and text.count("\n") == len(rows) + 4
    # the final grid's total leaves out exactly the superseded first grids
    assert {r["study"] for r in rows.values() if r["superseded"]} == set(studies.SUPERSEDED)
    fake = [{"study": "new", "cells": 1, "done": 1, "cpu_done": 100.0, "left": 0,
             "cpu_left": 0.0, "unknown": 0, "superseded": False},
            {"study": "old", "cells": 1, "done": 1, "cpu_done": 7000.0, "left": 0,
             "cpu_left": 0.0, "unknown": 0, "superseded": True}]
    last = sweep.format_ledger(fake, TINY, 2).splitlines()[-1]
    assert "(old: kept as the record): 100 s of CPU done" in last and "100 s in all" in last


def test_with_a_deadline_only_the_cells_that_fit_start_in_order_and_the_rest_wait():
    est = {"a": 50.0, "b": 500.0, "c": 20.0, "d": None}
    # no deadline: the first free-many, in order
    assert sweep.startable(list(est), est, 2, 0.0, None) == ["a", "b"]
    # 100 s left: b would end too late and is passed over; c, cheaper and later, fits
    assert sweep.startable(list(est), est, 2, 0.0, 100.0) == ["a", "c"]
    assert sweep.startable(list(est), est, 3, 0.0, 100.0) == ["a", "c", "d"]   # never measured
    assert sweep.startable(list(est), est, 0, 0.0, None) == []                # no free worker
    assert sweep.startable(list(est), est, 2, 90.0, 100.0) == ["d"]   # late: only the unknown


def test_a_sweep_whose_deadline_has_passed_starts_nothing_and_resumes_later(uninterrupted,
                                                                             tmp_path):
    import shutil
    root_a, _ = uninterrupted
    root_b = tmp_path / "cells"
    shutil.copytree(root_a, root_b)
    gone = sorted(root_b.glob("bc_demos/reacher4/bc__*s1*.json"))
    assert gone
    for p in gone:   # one seed's BC cell(s) to run again; their row keeps a measured cost
        p.unlink()
        p.with_suffix(".npz").unlink(missing_ok=True)   # a cell without features has none
    late = sweep.run("bc_demos", TINY, only=ONLY, root=root_b, progress=False, hours=1e-7)
    assert (late.ran, late.deferred, late.failed) == (0, len(gone), [])
    assert len(_results(root_b)) == 5 - len(gone)
    rest = sweep.run("bc_demos", TINY, only=ONLY, root=root_b, progress=False, hours=1.0)
    assert (rest.ran, rest.deferred) == (len(gone), 0)
    assert _results(root_b) == _results(root_a)


def test_the_grid_repriced_by_a_window_uses_the_window_s_cells_and_falls_back(monkeypatch):
    """`--priced-since`: every cell of the grid, done or not, priced by the median of its row's
    cells finished in the window; a row with none there by every cell's median."""
    from dc_lesson.experiments.studies import table3
    lesson = budget.get("lesson")
    grid = [c for c in table3.cells_at(lesson) if c.task == "reacher1" and c.n_demos == 4
            and c.learner in ("bc", "dc")]
    study = cells.Study("t", "t", cells=lambda b: grid, run_cell=None, aggregate=None,
                        result_file="t.json")

    def record(row, seconds, when):
        return {"cell": {"learner": row, "variant": "", "task": "reacher1"}, "config": {},
                "provenance": {"budget": "lesson", "wall_seconds": seconds, "time": when}}
    old, new = "2026-12-01T10:00:00+00:00", "2026-12-03T12:00:00+00:00"
    records = [record("dc", 300.0, old), record("dc", 100.0, new), record("dc", 120.0, new),
               record("bc", 10.0, old)]          # bc has no cell in the window
    monkeypatch.setattr(sweep, "_finished", lambda root=None: iter(records))
    monkeypatch.setattr(sweep, "measured_rates", lambda root=None: {})
    r = sweep.reprice(study, lesson, "2026-12-03T11:55", workers=2)
    n_dc, n_bc = (sum(c.learner == x for c in grid) for x in ("dc", "bc"))
    assert n_dc and n_bc and r["since"] == "2026-12-03T11:55:00+00:00"
    assert r["cpu_seconds"] == pytest.approx(110.0 * n_dc + 10.0 * n_bc)   # window median
    assert r["wall_seconds"] == pytest.approx(r["cpu_seconds"] / 2)
    refs = len(study.grid(lesson)) - len(grid)       # the reference the cells read: never run
    assert refs == 1 and r["cells"] == len(grid) + refs
    assert (r["window_cells"], r["priced_from_window"], r["unknown"]) == (2, n_dc, refs)
    assert "priced by the 2 cells finished since" in sweep.format_reprice(r)
    with pytest.raises(sweep.SweepError, match="not an ISO time"):
        sweep.reprice(study, lesson, "yesterday")
    # a window with an end: a later (loaded) cell is left out of the window's median
    records.append(record("dc", 900.0, "2026-12-03T15:00:00+00:00"))
    r = sweep.reprice(study, lesson, "2026-12-03T11:55", workers=2, until="2026-12-03T14:10")
    assert r["cpu_seconds"] == pytest.approx(110.0 * n_dc + 10.0 * n_bc)
    assert "and before 2026-12-03T14:10" in sweep.format_reprice(r)
    with pytest.raises(sweep.SweepError, match="--priced-until 'soon' is not an ISO time"):
        sweep.reprice(study, lesson, "2026-12-03T11:55", until="soon")
