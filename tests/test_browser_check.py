"""The browser checker's rules for what a reader must not see, on constructed page outputs
(the checker itself runs in CI, `.ci/run`, on every chapter)."""

import importlib.util
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
spec = importlib.util.spec_from_file_location("browser_check", ROOT / ".ci" / "browser_check.py")
bc = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bc)


def output(text="", cells=(), imgs=(), mime="text/html"):
    return {"index": 0, "cell": 2, "mime": mime, "text": text, "images": len(imgs),
            "widget": False, "progress": 0, "widgetError": False, "cells": list(cells),
            "imgs": list(imgs)}


@pytest.mark.parametrize("shown", ["NaN", "nan", "None", "<NA>"])
def test_a_missing_value_in_a_table_is_a_problem(shown):
    found = bc.dom_problems([output(cells=["dc", "0.91", shown])])
    assert len(found) == 1 and "missing values" in found[0][1] and "cell 3" in found[0][1]


def test_a_cell_cut_by_max_colwidth_is_a_problem():
    found = bc.dom_problems([output(cells=["reproduced: dc - bc +0.12 [+0.03, +0..."])])
    assert found and "ellipsis" in found[0][1]
    assert not bc.dom_problems([output(cells=["reproduced: dc - bc +0.12 [+0.03, +0.21]",
                                              "nanometre", "none"])])


def test_a_shrunken_figure_is_a_problem_and_a_fitting_one_is_not():
    wide = output(imgs=[{"drawn": 990, "natural": 2200}])
    assert "45%" in bc.dom_problems([wide])[0][1]
    assert not bc.dom_problems([output(imgs=[{"drawn": 990, "natural": 1100},
                                             {"drawn": 0, "natural": 0}])])


def test_warnings_and_stderr_stay_problems():
    assert bc.dom_problems([output(text="UserWarning: x")])
    assert bc.dom_problems([output(text="progress", mime=bc.STDERR_MIME)])
    assert not bc.dom_problems([output(text="scaled return 0.91", cells=["0.91", "dc"])])


def test_the_budget_follows_the_environment(monkeypatch):
    seen = {}
    monkeypatch.setattr(bc, "check_one", lambda nb, args: seen.setdefault("b", args.budget) and 0)
    monkeypatch.setenv("DC_LESSON_BUDGET", "lesson")
    assert bc.main(["book/00_tour.ipynb"]) == 0 and seen["b"] == "lesson"
    seen.clear()
    assert bc.main(["--budget", "smoke", "book/00_tour.ipynb"]) == 0 and seen["b"] == "smoke"


def test_all_means_every_chapter(monkeypatch):
    seen = []
    monkeypatch.setattr(bc, "check_one", lambda nb, args: seen.append(nb.name) or 0)
    assert bc.main(["all"]) == 0
    assert seen == sorted(p.name for p in (ROOT / "book").glob("[0-9][0-9]_*.ipynb"))
    assert len(seen) == 7
