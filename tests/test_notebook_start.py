"""What every chapter prints first: its budget, how to change it, and at smoke what it means."""

from __future__ import annotations

import ast
import pathlib

import pytest

from dc_lesson import budget, notebook

ROOT = pathlib.Path(__file__).resolve().parent.parent
CHAPTERS = sorted((ROOT / "book").glob("[0-9][0-9]_*.py"))


@pytest.mark.parametrize("name", ["smoke", "lesson", "paper"])
def test_start_names_the_budget_and_how_to_change_it_at_every_budget(name, monkeypatch,
                                                                      capsys):
    monkeypatch.setenv(budget.ENV_VAR, name)
    assert notebook.start("NOTE").name == name
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0] == f"budget: {name} (one of smoke, lesson, paper)"
    assert lines[1].startswith("to change it:")
    assert f"%env {budget.ENV_VAR}=lesson" in out and "jupyter lab book/" in out
    assert ("smoke budget: NOTE" in lines) == (name == "smoke")
    assert max(map(len, lines)) <= 88   # the Lab would break longer lines mid-word


def test_the_change_note_works_from_inside_a_kernel(monkeypatch, capsys):
    """What the note tells a reader to do (set the variable in the running kernel, then run
    the chapter from the top) does change the budget."""
    monkeypatch.delenv(budget.ENV_VAR, raising=False)
    assert notebook.start("x").name == budget.DEFAULT
    monkeypatch.setenv(budget.ENV_VAR, "smoke")    # what %env does: os.environ in the kernel
    assert notebook.start("x").is_smoke


def _start_calls(path):
    tree = ast.parse(path.read_text())
    return [node for node in ast.walk(tree) if isinstance(node, ast.Call)
            and ast.unparse(node.func) == "notebook.start"]


@pytest.mark.parametrize("chapter", CHAPTERS, ids=lambda p: p.stem)
def test_every_chapter_starts_with_notebook_start_and_a_smoke_note(chapter):
    calls = _start_calls(chapter)
    assert len(calls) == 1, f"{chapter.name} must call notebook.start exactly once"
    note = ast.literal_eval(calls[0].args[0])
    assert len(note) > 40, f"{chapter.name}'s smoke note says too little: {note!r}"
    # A chapter that reads stored results says that they, unlike its live runs, are real:
    # "every number means nothing" would be wrong about most of such a chapter.
    tree = ast.parse(chapter.read_text())
    if any(isinstance(node, ast.Call)
           and ast.unparse(node.func) in ("read_result", "table_one.load")
           for node in ast.walk(tree)):
        assert "stored" in note and "real" in note, (
            f"{chapter.name} reads stored results but its smoke note does not say they are "
            f"real: {note!r}")
    # No chapter asks the budget for itself: notebook.start is what quiets the library's
    # warnings and pins torch to one thread first.
    assert "budget.current()" not in chapter.read_text(), chapter.name
