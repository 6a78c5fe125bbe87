"""The package's layers: imports go one way, so no cycle can return.

Each module belongs to a layer (its top-level folder, or itself); a module may import only from
its own layer or a lower one.  The checker reads every ``import`` statement with ``ast``,
including the imports inside functions, so a lazy upward import is caught too.
"""

import ast
import pathlib

import pytest

import dc_lesson

PACKAGE = pathlib.Path(dc_lesson.__file__).parent

# Lowest first.  ``density`` sits above ``nn`` (it saves models through nn.checkpoint);
# ``experts`` above ``algorithms`` (PPO trains the locomotion experts); ``experiments`` and
# ``perf`` share a rank and never import each other.
LAYERS = [
    {"budget", "storage", "progress", "checks", "timing"},
    {"tasks"},
    {"data"},
    {"nn"},
    {"density"},
    {"algorithms"},
    {"experts"},
    {"evaluation"},
    {"viz"},
    {"experiments", "perf"},
    {"cli", "notebook", "__init__"},
]
RANK = {name: i for i, layer in enumerate(LAYERS) for name in layer}
SIBLINGS_APART = [{"experiments", "perf"}]


def layer_of(module: str) -> str:
    """``dc_lesson.algorithms.gail`` -> ``algorithms``; ``dc_lesson`` -> ``__init__``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def module_name(path: pathlib.Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_module(name: str) -> bool:
    path = PACKAGE.parent.joinpath(*name.split("."))
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


def imported_modules(source: str, this: str) -> list[tuple[int, str]]:
    """(line, module) for every dc_lesson module ``source`` imports (``from dc_lesson import x``
    counts as importing ``dc_lesson.x``)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.startswith("dc_lesson")]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                and node.module.startswith("dc_lesson"):
            if node.module == "dc_lesson":
                out += [(node.lineno, f"dc_lesson.{a.name}") for a in node.names]
            else:   # ``from package import module`` imports that module, not the package
                subs = [f"{node.module}.{a.name}" for a in node.names
                        if _is_module(f"{node.module}.{a.name}")]
                out += [(node.lineno, m) for m in subs] or [(node.lineno, node.module)]
    return out


def violations(source: str, this: str) -> list[str]:
    """The upward (or sideways-between-siblings) imports of module ``this``."""
    bad = []
    mine = layer_of(this)
    for line, target in imported_modules(source, this):
        theirs = layer_of(target)
        if theirs not in RANK:
            bad.append(f"{this}:{line} imports {target}, which is in no layer")
        elif RANK[theirs] > RANK[mine]:
            bad.append(f"{this}:{line} imports {target}: layer {theirs!r} is above {mine!r}")
        elif theirs != mine and {theirs, mine} in SIBLINGS_APART:
            bad.append(f"{this}:{line} imports {target}: {mine!r} and {theirs!r} stay apart")
    return bad


def all_modules():
    return sorted(PACKAGE.rglob("*.py"))


def test_every_module_is_in_a_layer():
    for path in all_modules():
        assert layer_of(module_name(path)) in RANK, f"{path} is in no layer of LAYERS"


def test_imports_only_go_down():
    bad = [v for path in all_modules()
           for v in violations(path.read_text(), module_name(path))]
    assert not bad, "upward imports:\n" + "\n".join(bad)


@pytest.mark.parametrize("source", [
    "from dc_lesson.experiments import claims\n",            # a learner reaching up
    "def f():\n    from dc_lesson import cli\n",               # a lazy upward import
    "import dc_lesson.evaluation.metrics\n",
])
def test_the_checker_catches_a_deliberate_upward_import(source):
    assert violations(source, "dc_lesson.algorithms.bc")


def test_the_checker_sees_a_module_imported_from_its_package():
    """``from package import module`` is an edge to the module (a cycle through it counts)."""
    got = [m for _, m in imported_modules(
        "def f():\n    from dc_lesson.experiments.studies import modes\n", "x")]
    assert got == ["dc_lesson.experiments.studies.modes"]


def test_the_checker_lets_a_downward_import_through():
    assert not violations("from dc_lesson import tasks\nfrom dc_lesson.nn import policies\n",
                          "dc_lesson.algorithms.bc")


def test_no_import_cycle_between_modules():
    """Within a layer imports may go sideways; still no module may reach itself."""
    graph = {}
    for path in all_modules():
        name = module_name(path)
        graph[name] = {t for _, t in imported_modules(path.read_text(), name)
                       if t != name and t in {module_name(p) for p in all_modules()}}
    # a package's __init__ imports its own modules, which import the package: not a cycle
    # of code, so edges into a package's own __init__ from inside it are dropped
    for name, targets in graph.items():
        graph[name] = {t for t in targets if not name.startswith(t + ".")}
    state = {}

    def visit(n, stack):
        state[n] = "open"
        for m in graph.get(n, ()):
            if state.get(m) == "open":
                raise AssertionError("import cycle: " + " -> ".join(stack + [n, m]))
            if m not in state:
                visit(m, stack + [n])
        state[n] = "done"

    for n in graph:
        if n not in state:
            visit(n, [])


def test_help_lists_every_public_module():
    doc = dc_lesson.__doc__
    for path in sorted(PACKAGE.iterdir()):
        name = path.stem if path.suffix == ".py" else path.name
        if name.startswith("_") or not (path.suffix == ".py" or (path / "__init__.py").exists()):
            continue
        assert f"``{name}``" in doc, f"dc_lesson's docstring does not list {name}"


def test_readme_module_table_names_every_module():
    """README's layer table is the tree: every public module of every layer is named in it."""
    readme = (PACKAGE.parent / "README.md").read_text()
    table = readme[readme.index("| layer | modules | holds |"):]
    table = table[:table.index("\n\n")]
    for path in all_modules():
        name = module_name(path).split(".")
        leaf = name[-1] if len(name) > 1 else None
        if leaf is None or leaf in ("__init__",) or (leaf.startswith("_") and leaf != "_trace"):
            continue
        mark = f"`{leaf}/`" if path.name == "__init__.py" else f"`{leaf}`"
        assert mark in table, f"README's module table does not name {'.'.join(name)}"
