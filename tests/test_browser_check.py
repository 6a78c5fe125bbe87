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


@pytest.mark.parametrize("text, kind", [
    ("start_log_std -0.4000000059604645", "float"),
    ("0.1 + 0.2 = 0.30000000000000004", "float"),
    ("{'softflow_toy_points': 256, 'softflow_toy_iters': 4}", "a dict"),
    ("{\n 'disc_hidden': [64, 64],\n 'disc_lr': 0.0003,\n" + " 'x': 1,\n" * 38 + "}", "a dict"),
    ('config {"lr": 0.001}', "a dict"),
    ("<dc_lesson.algorithms.bc.BCResult object at 0x7f3a2c1b9d50>", "address"),
    ("[<matplotlib.lines.Line2D at 0x7f3a2c1b9d50>]", "address"),
    ("fingertip array([0.08 , 0.123], dtype=float32)", "array"),
    ("tensor([0.1000, 0.2000])", "array"),
    ("shares {0: np.float64(0.25)}", "scalar"),
    ("Budget(name='smoke', tour_episodes=2)", "dataclass"),
    ("Text(0.5, 1.0, 'reacher4')", "matplotlib"),
])
def test_a_raw_python_repr_is_a_problem(text, kind):
    found = bc.dom_problems([output(text=text, mime="application/vnd.jupyter.stdout")])
    assert len(found) == 1 and "raw" in found[0][1] and kind in found[0][1], found
    assert "cell 3" in found[0][1]


def test_a_raw_repr_in_a_table_cell_is_a_problem():
    found = bc.dom_problems([output(text="setting\tvalue\nstart_log_std\t-0.4000000059604645",
                                    cells=["setting", "value", "start_log_std",
                                           "-0.4000000059604645"])])
    assert found and "10 or more significant digits" in found[0][1]


def test_formatted_numbers_and_ordinary_text_are_not_reprs():
    text = ("scaled return 0.912 [0.850, 0.974] over 5 seeds; EMD 1.47; 27,400 steps/s; "
            "mujoco 3.17.0, dm-control 1.0.50, torch 2.13.0; 127.0.0.1; seeds [0, 1, 2]; "
            "aggregated 2026-12-02T19:39:15+00:00; sigma 1e-05; revision 1086c01; "
            "reward in {0, 1}; Table I (reacher4); lr 0.0003; 123456.789; Fig. 3(a)")
    assert not bc.dom_problems([output(text=text, mime="application/vnd.jupyter.stdout")])


def test_a_traceback_is_one_stderr_problem_not_a_list_of_reprs():
    found = bc.dom_problems([output(text="KeyError: {'a': 1} at 0x7f3a2c1b9d50>",
                                    mime=bc.STDERR_MIME)])
    assert len(found) == 1 and "stderr" in found[0][1]
