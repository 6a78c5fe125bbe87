"""Aggregation: cells -> per-row means and intervals, paired differences over common seeds,
and a clear refusal while a grid is incomplete."""

import numpy as np
import pytest

from dc_lesson import budget
from dc_lesson.evaluation import stats
from dc_lesson.experiments import aggregate, report


def _obs():
    out = []
    for s in range(6):
        out.append({"row": "bc", "task": "t", "n_demos": 4, "seed": s, "emd": 0.1 * s,
                    "mode_shares": {"a": 0.5, "b": 0.5}})
        if s != 5:   # dc lacks seed 5: the pairing uses the 5 common seeds
            out.append({"row": "dc", "task": "t", "n_demos": 4, "seed": s,
                        "emd": 0.1 * s - 0.02, "mode_shares": {"a": 0.9, "b": 0.1}})
    return out


def test_table_gives_mean_interval_and_values_per_row():
    rows = {r["row"]: r for r in aggregate.table(_obs(), measures=("emd",))}
    bc = rows["bc"]
    assert bc["n_seeds"] == 6 and bc["emd_values"] == pytest.approx([0.1 * s for s in range(6)])
    ci = stats.mean_ci(bc["emd_values"])
    assert (bc["emd_mean"], bc["emd_lo"], bc["emd_hi"]) == (ci.mean, ci.lo, ci.hi)
    assert rows["dc"]["mode_shares_mean"] == {"a": 0.9, "b": 0.1}


def test_paired_uses_the_seeds_both_rows_have():
    (p,) = aggregate.paired(_obs(), "dc", "bc", measures=("emd",))
    assert p["seeds"] == [0, 1, 2, 3, 4]
    assert p["emd"]["mean"] == pytest.approx(-0.02)
    assert p["emd_diffs"] == pytest.approx([-0.02] * 5)


def test_iqm_over_tasks_uses_common_seeds():
    obs = [{"row": "dc", "task": t, "seed": s, "scaled_return": float(s + i)}
           for i, t in enumerate(("a", "b")) for s in range(4)]
    r = aggregate.iqm_over_tasks(obs, "dc")
    assert r["tasks"] == ["a", "b"] and r["seeds"] == [0, 1, 2, 3]
    assert r["mean"] == pytest.approx(stats.iqm(np.array([[s, s + 1] for s in range(4)])))


def test_an_incomplete_grid_is_refused_with_the_command(tmp_path):
    with pytest.raises(aggregate.AggregateError, match="dc-lesson sweep bc_demos --budget smoke"):
        aggregate.write("bc_demos", budget.get("smoke"), root=tmp_path, results=tmp_path)


def test_report_renders_from_an_aggregate():
    agg = {"summary": aggregate.table(_obs(), measures=("emd",))}
    r = report.row(agg, row="dc", task="t")
    m, lo, hi = report.t_interval(r["emd_values"])     # the verdict rule's t interval
    # printed clipped to EMD's limit (never negative); the rule decides on the unclipped one
    assert report.fmt_entry(r, "emd", 3) == f"{m:.3f} [{max(lo, 0.0):.3f}, {hi:.3f}]"
    assert report.fmt(0.5, float("nan"), float("nan")) == "0.50"
    with pytest.raises(report.ReportError, match="exactly one"):
        report.row(agg, task="t")
    (p,) = aggregate.paired(_obs(), "dc", "bc", measures=("emd",))
    assert report.fmt_entry(p, "emd", 2).startswith("-0.02")


def test_an_aggregate_whose_grid_moved_on_says_so(tmp_path):
    """A stored aggregate of the cells on record says nothing; once a setting changes (new
    config hashes) the same record is told apart from today's grid, with the count and the
    command that would bring it up to date."""
    from dc_lesson.experiments import aggregate, studies
    b = budget.get("smoke")
    grid = [c for c in studies.get("dc_lr").grid(b) if c.study == "dc_lr"]
    rec = {"benchmark": "dc_lr", "budget": "smoke", "cells": {"n": 2, "of": len(grid)}}
    for c in grid[:2]:
        c.path(tmp_path).parent.mkdir(parents=True, exist_ok=True)
        c.path(tmp_path).write_text("{}")
    assert aggregate.todays_grid(rec, tmp_path) == (2, len(grid))
    assert aggregate.freshness(rec, tmp_path) == ""
    grid[0].path(tmp_path).unlink()            # a cell of the old grid is not of today's
    said = aggregate.freshness(rec, tmp_path)
    assert f"1 of its {len(grid)} dc_lr cells" in said and "dc-lesson aggregate dc_lr" in said


def _never_read(*a, **k):
    raise AssertionError("records read before the output was checked")


def test_an_unwritable_results_folder_is_refused_before_any_record_is_read(monkeypatch):
    # issue 42: the aggregate was computed, then lost at the write
    monkeypatch.setattr(aggregate, "grid_records", _never_read)
    with pytest.raises(aggregate.AggregateError,
                       match="results folder /proc/dc-lesson-results cannot be written.*nothing "
                             "was computed.*choose another results folder"):
        aggregate.write("bc_demos", budget.get("smoke"), results="/proc/dc-lesson-results")


def test_a_read_only_data_folder_names_the_folder_and_the_variable(monkeypatch, capsys):
    from dc_lesson import cli
    monkeypatch.setattr(aggregate, "grid_records", _never_read)
    monkeypatch.setenv("DC_LESSON_DATA", "/proc")   # a folder no file can be made in, even as root
    assert cli.main(["aggregate", "bc_demos", "--budget", "smoke"]) == 2
    err = capsys.readouterr().err
    assert "results folder /proc/results cannot be written" in err
    assert "set DC_LESSON_DATA to a writable copy of the data folder" in err
