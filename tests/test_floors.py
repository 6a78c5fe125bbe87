"""The expert floors: per-mode and hopping checks that a mean return alone would miss."""

from types import SimpleNamespace

import numpy as np

from dc_lesson import tasks
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


def test_the_report_covers_every_task_and_agrees_with_the_manifest():
    rows = floors.report()
    assert [r["task"] for r in rows] == list(tasks.NAMES)
    for r in rows:
        if "expert return" in r and r["task"] not in ("reacher2", "reacher4", "halfcheetah2",
                                                       "hopper"):
            assert r["meets floor"] == (r["expert return"] >= r["floor"])
