"""Cells: identity by config hash, atomic checked records, never recomputed; studies expand
into their grids at every budget (no compute)."""

import json

import numpy as np
import pytest
import torch

from dc_lesson import budget
from dc_lesson.experiments import cells, studies, sweep


def _cell(**config):
    return cells.make_cell("demo", "bc", "reacher4", 4, 0, {"epochs": 3, **config})


def test_a_cell_is_named_by_its_config_hash():
    a, b = _cell(), _cell()
    assert a == b and a.path() == b.path() and a.hash == cells.config_hash(a.config)
    # the task's demonstrations (sha256) and expert are part of the config
    assert a.config["epochs"] == 3 and len(a.config["demos"]["sha256"]) == 64
    c = _cell(epochs=4)
    assert c.hash != a.hash and c.path() != a.path()
    assert a.path().name == f"bc__n4__s0__{a.hash}.json"
    with pytest.raises(cells.CellError, match="may hold only"):
        cells.make_cell("demo", "b c", "reacher4", 4, 0, {})


def test_a_new_reference_makes_new_cells():
    ref1 = cells.make_cell("reference", "expert", "reacher4", 0, 3000, {"episodes": 25},
                           stage=0)
    ref2 = cells.make_cell("reference", "expert", "reacher4", 0, 3000, {"episodes": 26},
                           stage=0)
    a = cells.make_cell("demo", "bc", "reacher4", 4, 0, {}, needs=(ref1,))
    b = cells.make_cell("demo", "bc", "reacher4", 4, 0, {}, needs=(ref2,))
    assert a.hash != b.hash


def test_records_are_written_whole_and_read_back_checked(tmp_path):
    c = _cell()
    prov = cells.provenance(command="test", budget="smoke", threads=1, wall_seconds=1.5)
    assert not cells.is_done(c, tmp_path)
    path = cells.write_record(c, {"x": np.float64(0.25)}, {"f": np.ones((3, 2))}, prov,
                              tmp_path)
    assert cells.is_done(c, tmp_path) and not list(tmp_path.rglob("*.tmp"))
    record, feats = cells.load(c, tmp_path)
    assert record["result"] == {"x": 0.25} and feats["f"].dtype == np.float32
    assert record["provenance"]["wall_seconds"] == 1.5 and record["provenance"]["revision"]
    # which machine kind the numbers reproduce on: the CPU's vector unit and the libraries
    platform = record["provenance"]["platform"]
    assert platform["torch_cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert platform["numpy"] == np.__version__ and platform["mujoco"] and platform["cpu"]
    # A record whose content does not match its name is refused, with the fix.
    bad = json.loads(path.read_text())
    bad["config"]["epochs"] = 99
    path.write_text(json.dumps(bad))
    with pytest.raises(cells.CellError, match="delete it and rerun"):
        cells.read_record(path)
    path.write_text("{not json")
    with pytest.raises(cells.CellError, match="unreadable"):
        cells.is_done(c, tmp_path)


def test_a_record_without_its_features_is_not_done(tmp_path):
    c = _cell()
    prov = cells.provenance(command="t", budget="smoke", threads=1, wall_seconds=0)
    cells.write_record(c, {}, {"f": np.zeros(2)}, prov, tmp_path)
    cells.features_path(c.path(tmp_path)).unlink()
    assert not cells.is_done(c, tmp_path)


@pytest.mark.parametrize("name", ["smoke", "lesson", "paper"])
def test_every_study_expands_at_every_budget(name):
    b = budget.get(name)
    for study in studies.NAMES:
        grid = studies.get(study).grid(b)
        keys = [(c.study, c.task, c.name) for c in grid]
        assert len(keys) == len(set(keys)), study
        assert [c.stage for c in grid] == sorted(c.stage for c in grid)
        for c in grid:     # what a cell needs is in the grid, before it
            for n in c.needs:
                assert (n.study, n.task, n.name) in keys[:keys.index((c.study, c.task,
                                                                      c.name))]


def test_lesson_seeds_are_ten_on_the_reachers_and_five_elsewhere():
    b = budget.get("lesson")
    assert b.seeds_for("reacher4") == tuple(range(10)) and len(b.seeds_for("halfcheetah")) == 5
    grid = studies.get("table1").grid(b)
    gail = [c for c in grid if c.row == "gail"]
    assert len(gail) == 10 + 10 + 5
    assert "--address" in budget.get("paper").sweep_command


@pytest.mark.parametrize("name", ["table1", "gail_lr"])
def test_the_dc_and_gail_cells_of_a_seed_share_the_warm_start_settings(name):
    b = budget.get("lesson")
    other = studies.get("dc_lr") if name == "gail_lr" else studies.get(name)
    g = next(c for c in studies.get(name).grid(b) if c.learner == "gail")
    d = next(c for c in other.grid(b) if c.learner == "dc" and c.seed == g.seed
             and c.task == g.task)
    keys = ("n_demos", "bc_max_epochs", "eval_episodes", "eval_seed", "needs")
    assert {k: g.config[k] for k in keys} == {k: d.config[k] for k in keys}


def test_only_selects_cells_and_keeps_what_they_need():
    grid = studies.get("bc_demos").grid(budget.get("smoke"))
    sel = sweep.select(grid, ["task=reacher4", "seed=0", "learner=bc"])
    assert {c.study for c in sel} == {"reference", "bc_demos"}
    assert all(c.seed == 0 and c.task == "reacher4" for c in sel if c.study == "bc_demos")
    with pytest.raises(sweep.SweepError, match="KEY=VALUE"):
        sweep.select(grid, ["colour=red"])
    with pytest.raises(sweep.SweepError, match="matches none"):
        sweep.select(grid, ["task=humanoid"])


def test_unknown_study_is_a_clear_error():
    with pytest.raises(studies.UnknownStudyError, match="the studies are"):
        studies.get("bc_modes")


@pytest.mark.parametrize("name", ["gail_lr", "dc_lr", "dc_ablation", "table1"])
def test_the_seeds_of_a_row_differ_only_in_their_seed(name):
    """A learner config listed for one seed is the config every seed runs with (GAIL's PPO
    carries a seed of its own: it is stripped too), so the run-time check passes for all."""
    rows = {}
    for c in studies.get(name).grid(budget.get("lesson")):
        if c.learner in ("gail", "dc"):
            rows.setdefault((c.task, c.row), set()).add(json.dumps(c.config[c.learner],
                                                                   sort_keys=True))
    assert rows and all(len(v) == 1 for v in rows.values())
