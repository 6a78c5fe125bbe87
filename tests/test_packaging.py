"""Every third-party package the library or the book imports is declared in pyproject.toml
(issue 19: pandas was imported by every chapter but not declared)."""

import ast
import importlib.metadata
import pathlib
import re
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
# imported lazily, with a clear error: data.convert.to_imitation and the perf benchmarks
# against imitation 1.0.1 (and its stable-baselines3), installed in their own environment
OPTIONAL = {"imitation", "stable_baselines3"}


def _imports(path: pathlib.Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module.split(".")[0])
    return out


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def test_every_imported_package_is_declared():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    # a dependency, or an extra's (ray: `dc-lesson sweep`, installed with the test extra)
    extras = [d for group in project.get("optional-dependencies", {}).values() for d in group]
    declared = {_norm(re.split(r"[=<>!~\[ ;]", d)[0]) for d in project["dependencies"] + extras}
    files = sorted((ROOT / "dc_lesson").rglob("*.py")) + sorted((ROOT / "book").glob("*.py"))
    modules = set().union(*map(_imports, files)) - set(sys.stdlib_module_names) \
        - {"dc_lesson", "__future__"} - OPTIONAL
    dists = importlib.metadata.packages_distributions()
    missing = {m: dists.get(m) for m in modules
               if not any(_norm(d) in declared for d in dists.get(m, [m]))}
    assert not missing, f"imported but not declared in pyproject.toml: {missing}"


def test_python_versions():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["requires-python"] == ">=3.11"
