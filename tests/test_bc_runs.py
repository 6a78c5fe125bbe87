"""The BC runs behind the ``bc_demos`` cells (:func:`experiments.bc.run_one`): each is
consistent with the manifest and with its own returns, the summary is the mean and sample std
over seeds, the same settings repeat exactly, and the evaluation episodes are never a
demonstration's."""

import math

import numpy as np
import pytest

from dc_lesson import budget, data
from dc_lesson.data import rollout
from dc_lesson.experiments import bc as bc_runs
from dc_lesson.experiments import protocol

TINY = dict(eval_episodes=2, max_epochs=2, emd_n_max=200)


def _run(task, n, seed):
    return bc_runs.run_one(task, n, seed, reference=data.load_demos(task), **TINY)


@pytest.fixture(scope="module")
def runs():
    return [_run(task, n, seed) for task in ("reacher1", "reacher4") for n in (2, 3)
            for seed in (0, 1)]


def test_each_run_is_consistent_with_the_manifest_and_its_own_returns(runs):
    for r in runs:
        entry = data.manifest_entry(r["task"])
        assert len(r["returns"]) == 2
        assert r["return"] == pytest.approx(np.mean(r["returns"]), abs=1e-3)
        lo, hi = entry["random_return"]["mean"], entry["expert_return"]["mean"]
        assert r["scaled_return"] == pytest.approx((r["return"] - lo) / (hi - lo), abs=1e-6)
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


def test_summary_is_the_mean_and_sample_std_over_seeds(runs):
    summary = bc_runs.summarise(runs)
    assert len(summary) == 4
    for row in summary:
        mine = [r for r in runs if (r["task"], r["n_demos"]) == (row["task"], row["n_demos"])]
        assert row["n_seeds"] == len(mine) == 2
        for m in bc_runs.MEASURES:
            v = np.array([r[m] for r in mine])
            assert row[f"{m}_mean"] == pytest.approx(v.mean())
            assert row[f"{m}_std"] == pytest.approx(v.std(ddof=1))
        if row["task"] == "reacher4":
            assert sum(row["mode_shares_mean"].values()) == pytest.approx(1.0)


def test_same_settings_give_the_same_numbers():
    a, b = _run("reacher1", 2, 3), _run("reacher1", 2, 3)
    for k in ("returns", "scaled_return", "emd", "kl", "rkl", "best_epoch", "best_val_nll"):
        assert a[k] == b[k], k


def test_evaluation_episodes_are_not_demonstrations():
    demos = data.load_demos("reacher1")
    demo_seeds = {t.seed for t in demos.trajectories}
    assert not demo_seeds & set(rollout.episode_seeds(bc_runs.EVAL_SEED, 50).tolist())
    # The demonstrations were collected with seed 0: evaluating there would replay them.
    with pytest.raises(protocol.BenchInputError, match="demonstration started"):
        protocol.check_eval_seeds(demos, 0, 3)


def test_bc_budget_fields_grow_from_smoke_to_paper():
    s, l, p = (budget.PRESETS[n] for n in ("smoke", "lesson", "paper"))
    for field in ("bc_eval_episodes", "bc_max_epochs"):
        assert getattr(s, field) < getattr(l, field) <= getattr(p, field), field
    assert len(s.bc_seeds) < len(l.bc_seeds) <= len(p.bc_seeds)
    assert l.bc_demo_counts == p.bc_demo_counts == (4, 11, 18, 25)   # the paper's subsets
    assert all(2 <= n <= 25 for b in (s, l, p) for n in b.bc_demo_counts)
