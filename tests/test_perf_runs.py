"""``dc-lesson perf runs``: whole lesson runs of an earlier revision's code against today's.
The earlier code really is the one that runs (its own package, in a fresh process), the two
trees must do the same work, and bad revisions or learners are refused with the fix."""

import dataclasses
import json
import pathlib
import subprocess
import sys

import pytest
import torch

from dc_lesson import algorithms
from dc_lesson.algorithms import dc
from dc_lesson.perf import runs

ROOT = pathlib.Path(runs.__file__).resolve().parents[2]
needs_git = pytest.mark.skipif(
    subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True
                   ).returncode != 0, reason="not a git checkout")


def test_same_work_names_a_changed_setting_and_skips_settings_the_old_code_lacked():
    before = {"lr": 1e-3, "ppo": {"n_envs": 8, "clip": 0.2}}
    now = {"lr": 1e-3, "ppo": {"n_envs": 16, "clip": 0.2, "terminate": None}, "new": 1}
    assert runs.same_work(before, now) == ["ppo.n_envs: 8 before, 16 today"]
    assert runs.same_work(before, {**before, "new": 1}) == []


@needs_git
def test_an_unknown_revision_is_refused_with_the_fix(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    with pytest.raises(runs.RevisionError, match="no revision 'no-such-thing'.*7445a95"):
        runs.extract("no-such-thing")


def test_a_learner_it_does_not_time_is_refused():
    with pytest.raises(ValueError, match="not softflow"):
        runs.benchmark("HEAD", tasks=("reacher1",), learners=("softflow",), repeats=1)


def test_every_timed_learner_counts_the_interactions_its_preset_takes():
    """The rows' steps per second divide by the interactions the lesson preset really takes
    (the RL-based learners keep them in their PPO settings, DC in its iterations)."""
    from dc_lesson import budget
    b = budget.get("lesson")
    for name in runs.LEARNERS + runs.EXTRA:
        kind = "dc" if name == "dc-stored" else name
        cfg = algorithms.get(kind).preset(b, 0)
        got = runs._env_steps(kind, cfg, "hopper")
        want = {"bc": 0, "dc": cfg.env_steps("hopper") if kind == "dc" else None}.get(
            kind, b.il_steps)
        assert got == want, name


@needs_git
def test_a_run_imports_the_package_of_the_extracted_revision(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    tree = runs.extract("HEAD")
    assert tree.is_relative_to(tmp_path) and (tree / "dc_lesson" / "__init__.py").exists()
    assert runs.extract("HEAD") == tree          # extracted once, then reused
    out = runs.run_in(tree, "bc", "reacher1")
    assert pathlib.Path(out["package"]).resolve().is_relative_to(tree.resolve())
    assert out["config"]["epochs"] == 20 and out["seconds"] > 0


def test_the_chapters_words_name_the_longest_run_and_any_learner_no_faster():
    rows = [{"learner": "bc", "task": "reacher4", "seconds_today": 2.0, "ratio": 1.2},
            {"learner": "dc", "task": "halfcheetah", "seconds_today": 67.7, "ratio": 1.3}]
    words = runs.in_words(rows)
    assert "dc on halfcheetah, 68 s" in words and "every learner ran faster" in words
    rows[0]["ratio"] = 1.0
    words = runs.in_words(rows)
    assert "every learner" not in words
    assert "no faster than with the earlier code: bc on reacher4" in words


@pytest.mark.parametrize("name, numerics", [("dc-stored", "stored"), ("dc", "today")])
def test_the_dc_stored_run_trains_todays_dc_with_the_stored_numerics(name, numerics, monkeypatch,
                                                                      capsys):
    # The run's own snippet, in-process, with training and the warm start stubbed out: what
    # reaches ``train`` is the config the timed run would use.
    seen = {}
    stub = lambda task, demos, cfg, **kw: seen.update(cfg=cfg)
    monkeypatch.setitem(algorithms.ALGORITHMS, "dc",
                        dataclasses.replace(algorithms.ALGORITHMS["dc"], train=stub))
    monkeypatch.setattr(algorithms.bc, "warm_start_policy", lambda *a, **kw: None)
    monkeypatch.setattr(sys, "argv", ["snippet", name, "reacher1", ",".join(runs._WARM)])
    threads = torch.get_num_threads()
    try:
        exec(compile(runs._SNIPPET, "perf-runs-snippet", "exec"), {})
    finally:
        torch.set_num_threads(threads)      # the snippet pins one thread for its own process
    got = {k: getattr(seen["cfg"].flow, k) for k in dc.STORED_NUMERICS}
    today = {k: getattr(dc.DCConfig().flow, k) for k in dc.STORED_NUMERICS}
    assert got == (dc.STORED_NUMERICS if numerics == "stored" else today)
    assert today != dc.STORED_NUMERICS       # else the two runs would time the same thing
    printed = json.loads(capsys.readouterr().out)
    stored_names = {v: k for k, v in dc.FLOW_STORED_NAMES.items()}   # the JSON's flat names
    assert {k: printed["config"][stored_names[k]] for k in got} == got


def test_the_speed_history_is_in_perf_docs_and_chapter_00_only_points_there():
    # issue 42: the history is maintainers' material; the page quotes every stored row as
    # format_row prints it, so a remade benchmark shows up as a failing test, not a stale page
    history = (pathlib.Path(runs.__file__).parent / "HISTORY.md").read_text()
    from dc_lesson.storage import read_result
    for name in ("perf_runs.json", "perf_runs_dc.json", "perf_runs_dc_reacher4.json",
                 "perf_runs_gpril.json"):
        rec = read_result(name)
        assert rec["revision"][:12] in history, name
        for row in rec["rows"]:
            assert runs.format_row(row) in history, (name, runs.format_row(row))
    words = runs.in_words(read_result("perf_runs.json")["rows"])   # "... halfcheetah, 61 s; ..."
    assert words.split(", ", 1)[1] in " ".join(history.split())
    chapter = (ROOT / "book" / "00_tour.py").read_text()
    assert "perf_runs" not in chapter and "issue 14" not in chapter
    pointers = [s for s in " ".join(chapter.split()).split(". ") if "perf/HISTORY.md" in s]
    assert len(pointers) == 1, pointers
