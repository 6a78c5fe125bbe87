import pathlib
import re

import pytest

from dc_lesson import budget, cli

ROOT = pathlib.Path(__file__).resolve().parent.parent


def test_budget_comes_from_the_environment(monkeypatch):
    monkeypatch.delenv(budget.ENV_VAR, raising=False)
    assert budget.current().name == "lesson"
    monkeypatch.setenv(budget.ENV_VAR, "smoke")
    assert budget.current().is_smoke


def test_unknown_budget_lists_the_valid_ones(monkeypatch):
    monkeypatch.setenv(budget.ENV_VAR, "huge")
    with pytest.raises(budget.BudgetError, match="smoke, lesson, paper"):
        budget.current()


def test_budgets_grow_from_smoke_to_paper():
    s, l, p = (budget.PRESETS[n] for n in ("smoke", "lesson", "paper"))
    for field in ("tour_episodes", "video_steps", "bench_steps"):
        assert getattr(s, field) < getattr(l, field) <= getattr(p, field), field


def test_cli_reports_bad_input_without_a_traceback(capsys, monkeypatch):
    monkeypatch.setenv(budget.ENV_VAR, "huge")
    assert cli.main(["tasks"]) == 2
    assert "unknown budget" in capsys.readouterr().err
    monkeypatch.setenv(budget.ENV_VAR, "smoke")
    assert cli.main(["perf", "rollout", "--tasks", "nope"]) == 2
    assert "cartpole" in capsys.readouterr().err


def test_ci_runs_exactly_the_test_command_of_the_readme():
    readme = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```(?:bash|sh)?\n(.*?)```", readme, flags=re.S)
    test_cmds = [line.strip() for b in blocks for line in b.splitlines() if "pytest" in line]
    assert len(test_cmds) == 1, "README must give one test command"
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert test_cmds[0] in [line.strip() for line in ci]


def test_readme_cell_counts_are_the_stored_aggregates():
    # README quotes each grid's size; it is prose no notebook renders, so a rerun grid must
    # not leave it stale: every count it states is the stored aggregate's, and complete.
    from dc_lesson.storage import read_result

    text = " ".join((ROOT / "README.md").read_text().split())
    said = re.search(r"Every committed grid is complete at the `lesson` budget \((.*?)\)", text)
    assert said, "README lost its sentence on the committed grids"
    files = {"Table I": "table1", "Table III": "table3", "the competence study": "competence",
             "benchmark": "benchmark", "ablations": "ablations", "modes": "modes"}
    counts = {name: int(n) for name, n in
              re.findall(r"(Table III|Table I|the competence study|benchmark|ablations|modes)"
                         r" (\d+)", said.group(1))}
    assert set(counts) == set(files), counts
    for name, n in counts.items():
        stored = read_result(f"{files[name]}.json")
        assert stored["complete"] and stored["cells"]["n"] == n, (name, n, stored["cells"])
