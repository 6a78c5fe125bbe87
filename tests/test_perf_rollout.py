"""``dc-lesson perf rollout``: the rows it prints and stores (not its timings)."""

import numpy as np

from dc_lesson import tasks
from dc_lesson.perf import rollout as perf_rollout


def test_every_task_has_an_envpool_counterpart():
    assert set(perf_rollout.ENVPOOL) == set(tasks.NAMES)


def test_a_row_gives_each_path_and_its_ratios(monkeypatch):
    monkeypatch.setattr(perf_rollout, "envpool_version", lambda: None)
    (row,) = perf_rollout.rollout_benchmark(["cartpole"], n_steps=320, repeats=1)
    for key in ("raw mj_step (ctrl steps/s)", "dm_control Environment", "dc_lesson rollout"):
        assert np.isfinite(row[key]) and row[key] > 0
    assert np.isclose(row["rollout / raw"],
                      row["dc_lesson rollout"] / row["raw mj_step (ctrl steps/s)"])
    assert "EnvPool" not in row
    text = perf_rollout.format_rows([row])
    assert "EnvPool is not installed" in text and "pip install envpool" in text


def test_envpool_is_compared_where_it_is_installed(monkeypatch):
    # EnvPool is an optional extra: fake its timing so the test runs without it.
    monkeypatch.setattr(perf_rollout, "envpool_version", lambda: "test")
    monkeypatch.setattr(perf_rollout, "_envpool_steps_per_s", lambda name, n, b: 1e9)
    (row,) = perf_rollout.rollout_benchmark(["reacher1"], n_steps=320, repeats=1)
    assert row["envpool task"] == "ReacherEasy-v1" and row["EnvPool"] == 1e9
    assert np.isclose(row["rollout / EnvPool"], row["dc_lesson rollout"] / 1e9)
    text = perf_rollout.format_rows([row])
    assert "rollout/EnvPool" in text and "not installed" not in text


def test_the_batch_sweep_gives_a_row_per_batch_with_its_ratio_to_raw():
    rows = perf_rollout.batch_sweep("reacher1", batches=(1, 4), n_steps=80, repeats=1)
    assert [r["batch"] for r in rows] == [1, 4]
    assert all(r["dc_lesson rollout"] > 0 and 0 < r["rollout / raw"] < 10 for r in rows)
