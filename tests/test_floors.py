"""The expert floors: per-mode and hopping checks that a mean return alone would miss."""

from types import SimpleNamespace

import numpy as np

from dc_lesson import data, tasks
from dc_lesson.experts import floors


def _entry(mean, modes, name="PPO"):
    return {"expert_return": {"mean": mean, "std": 1.0}, "expert": {"name": name},
            "demo_mode_shares": {m: 1 / len(modes) for m in modes}}


def _traj(ret, mode=0, height=1.0, speed=0.0, T=10):
    feats = np.tile(np.array([height, speed], np.float32), (T + 1, 1))
    return SimpleNamespace(ret=ret, mode=mode, mode_features=feats)


def test_a_multi_mode_expert_must_reach_the_floor_in_every_mode():
    good = [_traj(900, 0), _traj(900, 1)]
    one_bad = [_traj(990, 0), _traj(990, 0), _traj(650, 1)]
    assert floors.check("reacher2", _entry(900, ["red", "blue"]), good)["meets floor"]
    row = floors.check("reacher2", _entry(877, ["red", "blue"]), one_bad)
    assert not row["meets floor"] and "blue 650" in row["per mode / behaviour"]
    missing = floors.check("reacher2", _entry(990, ["red", "blue"]), [_traj(990, 0)])
    assert not missing["meets floor"] and "blue: no demonstration" in \
        missing["per mode / behaviour"]


def test_a_hopper_that_only_stands_misses_the_floor_despite_its_return():
    standing = [_traj(250, speed=0.0) for _ in range(3)]
    assert not floors.check("hopper", _entry(250, ["single"]), standing)["meets floor"]
    hopping = [_traj(600, speed=1.0, height=0.9) for _ in range(3)]
    assert floors.check("hopper", _entry(600, ["single"]), hopping)["meets floor"]
    falls = hopping[:2] + [_traj(300, speed=1.0, height=0.3)]
    assert not floors.check("hopper", _entry(500, ["single"]), falls)["meets floor"]
    # Every demonstration must hop: a fast mean over them does not hide one that stands.
    one_stands = hopping[:2] + [_traj(250, speed=0.0)]
    assert not floors.check("hopper", _entry(500, ["single"]), one_stands)["meets floor"]


def test_the_none_class_is_counted_not_demanded():
    # the manifest lists "none" beside the modes; no competent expert must "take" it
    ok = floors.check("reacher2", _entry(990, ["red", "blue", "none"]),
                      [_traj(990, 0), _traj(990, 1)])
    assert ok["meets floor"] and "none" not in ok["per mode / behaviour"]
    # but an expert whose demonstrations arrive nowhere too often misses the floor
    lost = [_traj(990, 0), _traj(990, 1)] + [_traj(100, tasks.NO_MODE)] * 2
    row = floors.check("reacher2", _entry(990, ["red", "blue", "none"]), lost)
    assert not row["meets floor"] and "50% of demonstrations arrived nowhere" in \
        row["per mode / behaviour"]
    few = [_traj(990, 0), _traj(990, 1)] * 10 + [_traj(100, tasks.NO_MODE)]
    assert floors.check("reacher2", _entry(990, ["red", "blue", "none"]), few)["meets floor"]


def test_the_report_covers_every_task_and_agrees_with_the_manifest():
    rows = floors.report()
    assert [r["task"] for r in rows] == list(tasks.NAMES)
    manifest = data.read_manifest()["tasks"]
    for r in rows:
        demos = data.load_demos(r["task"]).trajectories
        # the report is check() of the manifest's own entry, for every task, none skipped
        assert r["meets floor"] == floors.check(r["task"], manifest[r["task"]],
                                                demos)["meets floor"]
        if not tasks.SPECS[r["task"]].multimodal and r["task"] != "hopper":
            assert r["meets floor"] == (r["expert return"] >= r["floor"])


def test_clonable_reads_bc_from_the_stored_study(tmp_path):
    import json
    (tmp_path / "clonable.json").write_text(json.dumps({"table": [
        {"task": "walker", "demonstrations": "walker", "scaled_return_mean": 0.49},
        {"task": "hopper", "demonstrations": "hopper", "scaled_return_mean": 0.51},
        # another expert's demonstrations of a task never stand for the task's own
        {"task": "ant", "demonstrations": "ant-planner", "scaled_return_mean": 0.9}]}))
    rows = {r["task"]: r for r in floors.report(results_dir=tmp_path)}
    assert rows["walker"]["clonable"] is False and rows["hopper"]["clonable"] is True
    assert rows["ant"]["clonable"] is None and rows["reacher4"]["BC from 25 demos"] is None
