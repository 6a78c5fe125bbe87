"""``dc-lesson bench bc``: at a tiny size it runs, writes a well-formed result file with its
provenance, repeats exactly, and refuses inputs it cannot run with."""

import json
import math

import numpy as np
import pytest

from dc_lesson.experiments import bc as bench_bc
from dc_lesson import budget, cli, data
from dc_lesson.data import rollout

TINY = dict(demo_counts=(2, 3), seeds=(0, 1), eval_episodes=2, max_epochs=2, emd_n_max=200,
            progress=False)


@pytest.fixture(scope="module")
def tiny_result(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "bc.json"
    record = bench_bc.run(["reacher1", "reacher4"], **TINY, out=out, command="test tiny")
    return record, json.loads(out.read_text())


def test_result_file_has_provenance_runs_and_summary(tiny_result):
    record, stored = tiny_result
    for key in ("command", "seeds", "budget", "revision", "time"):
        assert key in stored, key
    assert stored["command"] == "test tiny" and stored["seeds"] == [0, 1]
    assert stored["budget"] == budget.current().name
    assert stored["tasks"] == ["reacher1", "reacher4"] and stored["demo_counts"] == [2, 3]
    assert stored["eval_episodes"] == 2 and stored["bc_config"]["epochs"] == 2
    assert len(stored["runs"]) == 2 * 2 * 2 and len(stored["summary"]) == 2 * 2
    assert {(r["task"], r["n_demos"], r["seed"]) for r in stored["runs"]} == {
        (t, n, s) for t in ("reacher1", "reacher4") for n in (2, 3) for s in (0, 1)}
    assert stored["runs"] == json.loads(json.dumps(record["runs"]))


def test_each_run_is_consistent_with_the_manifest_and_its_own_returns(tiny_result):
    _, stored = tiny_result
    for r in stored["runs"]:
        info = stored["task_info"][r["task"]]
        entry = data.manifest_entry(r["task"])
        assert info["expert_return"] == entry["expert_return"]["mean"]
        assert len(r["returns"]) == 2
        assert r["return"] == pytest.approx(np.mean(r["returns"]), abs=1e-3)
        scaled = (r["return"] - info["random_return"]) / (info["expert_return"]
                                                          - info["random_return"])
        assert r["scaled_return"] == pytest.approx(scaled, abs=1e-6)
        for k in ("emd", "kl", "rkl", "train_seconds", "eval_seconds", "measure_seconds"):
            assert math.isfinite(r[k]), k
        assert r["emd"] >= 0 and r["train_seconds"] > 0 and r["eval_seconds"] > 0
        assert r["train_episodes"] + r["val_episodes"] == r["n_demos"]
        assert 1 <= r["best_epoch"] <= r["epochs_run"] <= 2
        if r["task"] == "reacher4":
            assert set(r["mode_shares"]) == {"red", "green", "blue", "yellow", "none"}
            assert sum(r["mode_shares"].values()) == pytest.approx(1.0)
        else:
            assert r["mode_shares"] is None


def test_summary_is_the_mean_and_sample_std_over_seeds(tiny_result):
    _, stored = tiny_result
    for row in stored["summary"]:
        runs = [r for r in stored["runs"]
                if (r["task"], r["n_demos"]) == (row["task"], row["n_demos"])]
        assert row["n_seeds"] == len(runs) == 2
        for m in bench_bc.MEASURES:
            v = np.array([r[m] for r in runs])
            assert row[f"{m}_mean"] == pytest.approx(v.mean())
            assert row[f"{m}_std"] == pytest.approx(v.std(ddof=1))
        if row["task"] == "reacher4":
            assert sum(row["mode_shares_mean"].values()) == pytest.approx(1.0)
    text = bench_bc.format_table(stored["summary"])
    assert "reacher4" in text and "±" in text and "modes:" in text


def test_same_settings_give_the_same_numbers():
    kwargs = dict(TINY, demo_counts=(2,), seeds=(3,))
    a = bench_bc.run(["reacher1"], **kwargs)["runs"][0]
    b = bench_bc.run(["reacher1"], **kwargs)["runs"][0]
    for k in ("returns", "scaled_return", "emd", "kl", "rkl", "best_epoch", "best_val_nll"):
        assert a[k] == b[k], k


def test_evaluation_episodes_are_not_demonstrations():
    demo_seeds = {t.seed for t in data.load_demos("reacher1").trajectories}
    assert not demo_seeds & set(rollout.episode_seeds(bench_bc.EVAL_SEED, 50).tolist())
    # The demonstrations were collected with seed 0: evaluating there would replay them.
    with pytest.raises(bench_bc.BenchInputError, match="demonstration started"):
        bench_bc.run(["reacher1"], **dict(TINY, eval_episodes=3), eval_seed=0)


def test_bad_sizes_raise_before_any_training():
    with pytest.raises(bench_bc.BenchInputError, match="needs 2 to 25"):
        bench_bc.run(["reacher1"], **dict(TINY, demo_counts=(1,)))
    with pytest.raises(bench_bc.BenchInputError, match="needs 2 to 25"):
        bench_bc.run(["reacher1"], **dict(TINY, demo_counts=(26,)))
    with pytest.raises(bench_bc.BenchInputError, match="at least one"):
        bench_bc.run([], **TINY)
    with pytest.raises(bench_bc.BenchInputError, match="eval_episodes"):
        bench_bc.run(["reacher1"], **dict(TINY, eval_episodes=0))


def test_cli_runs_bench_bc_and_reports_bad_input(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(budget.ENV_VAR, "smoke")
    out = tmp_path / "bc.json"
    assert cli.main(["bench", "bc", "--tasks", "reacher1", "--demos", "2", "--seeds", "0",
                     "--episodes", "1", "--epochs", "1", "--out", str(out)]) == 0
    stored = json.loads(out.read_text())
    assert stored["budget"] == "smoke" and stored["command"].startswith("dc-lesson")
    assert len(stored["runs"]) == 1
    assert cli.main(["bench", "bc", "--tasks", "reacher1", "--demos", "30"]) == 2
    assert "needs 2 to 25" in capsys.readouterr().err


def test_bc_budget_fields_grow_from_smoke_to_paper():
    s, l, p = (budget.PRESETS[n] for n in ("smoke", "lesson", "paper"))
    for field in ("bc_eval_episodes", "bc_max_epochs"):
        assert getattr(s, field) < getattr(l, field) <= getattr(p, field), field
    assert len(s.bc_seeds) < len(l.bc_seeds) <= len(p.bc_seeds)
    assert l.bc_demo_counts == p.bc_demo_counts == (4, 11, 18, 25)   # the paper's subsets
    assert all(2 <= n <= 25 for b in (s, l, p) for n in b.bc_demo_counts)
