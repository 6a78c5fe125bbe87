"""Every ``dc_lesson.x.y`` the prose names exists: in the library's docstrings and comments,
the README and the book's chapters.  A module that moved (``dc_lesson.bc`` became
``dc_lesson.algorithms.bc``) leaves its old name behind in prose no import checks; this does.
String constants are not prose: a file format's name (``"dc_lesson.ppo.checkpoint"``) is an
identifier written into stored files, not a reference."""

import ast
import importlib
import io
import pathlib
import re
import tokenize

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
NAME = re.compile(r"\bdc_lesson(?:\.[A-Za-z_]\w*)+")


def _prose_of_module(path: pathlib.Path) -> list[tuple[int, str]]:
    """(line, text) of every docstring and comment of a Python module."""
    source = path.read_text()
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                out.append((body[0].lineno, body[0].value.value))
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            out.append((tok.start[0], tok.string))
    return out


def _texts():
    for path in sorted((ROOT / "dc_lesson").rglob("*.py")):
        for line, text in _prose_of_module(path):
            yield path, line, text
    yield ROOT / "README.md", 1, (ROOT / "README.md").read_text()
    for path in sorted((ROOT / "book").glob("[0-9][0-9]_*.py")):
        yield path, 1, path.read_text()      # markdown cells and code alike


def resolves(name: str) -> bool:
    """Whether ``name`` is a module, or an attribute path from the longest importable one."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def test_the_check_can_fail():
    assert resolves("dc_lesson.algorithms.bc.bc_loss") and resolves("dc_lesson.nn.fast")
    assert not resolves("dc_lesson.bc") and not resolves("dc_lesson.algorithms.bc.no_such")


def test_every_dc_lesson_name_in_docstrings_readme_and_chapters_resolves():
    stale = []
    for path, line, text in _texts():
        for m in NAME.finditer(text):
            name = m.group(0)
            if not resolves(name):
                where = line + text[:m.start()].count("\n")
                stale.append(f"{path.relative_to(ROOT)}:{where}: {name}")
    assert not stale, "names of nothing:\n" + "\n".join(stale)


@pytest.mark.parametrize("fmt", ["dc_lesson.ppo.checkpoint", "dc_lesson.policy"])
def test_format_names_in_string_constants_are_not_read_as_references(fmt, tmp_path):
    f = tmp_path / "m.py"
    f.write_text(f'"""A module."""\nFORMAT = "{fmt}"   # a format name\n')
    assert all(fmt not in text for _, text in _prose_of_module(f))
