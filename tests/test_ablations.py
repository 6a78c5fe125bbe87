"""The hopper ablations' cells (Figures 3-6): their deterministic evaluation curve, and the
per-worker start cache that lets a seed's cells share one BC start."""

import copy

import numpy as np
import pytest
import torch

from dc_lesson import budget, evaluation
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies import _imitation, dc_ablation, dc_lr, gail_lr


def test_a_checkpoint_curve_evaluates_once_per_mark_and_never_stops_the_run():
    seen = []

    def evaluate(policy):
        seen.append(policy)
        return {"scaled_return": float(len(seen))}

    curve = evaluation.CheckpointCurve(evaluate, total_steps=100, points=4)
    assert curve.marks == [25, 50, 75, 100]
    assert curve({"env_steps": 10}, "p0") is False and seen == []
    assert curve({"env_steps": 30}, "p1") is False           # past 25: one evaluation
    assert curve({"env_steps": 80}, "p2") is False           # past 50 and 75: one per mark
    assert curve({"steps": 120}, "p3") is False              # GAIL's rows say "steps"
    assert curve({"env_steps": 200}, "p4") is False          # no mark left: no evaluation
    assert [p["steps"] for p in curve.points] == [30, 80, 80, 120]
    assert [p["scaled_return"] for p in curve.points] == [1.0, 2.0, 3.0, 4.0]
    assert seen == ["p1", "p2", "p2", "p3"]
    with pytest.raises(ValueError, match="at least one point"):
        evaluation.CheckpointCurve(evaluate, total_steps=100, points=0)


def test_a_checkpoint_curve_leaves_the_run_unchanged():
    """Evaluating during a run uses its own episodes and the mean action: DC with a curve ends
    with the very parameters of DC without one (a curve that drew from the run's generators
    or stepped its environments would change them)."""
    from dc_lesson.algorithms import bc, dc
    from dc_lesson import data
    smoke = budget.get("smoke")
    demos = data.load_demos("reacher1", n_trajectories=2)
    start = bc.warm_start_policy(demos, 0, max_epochs=2)
    cfg = dc.preset(smoke, seed=0)
    plain = dc.train("reacher1", demos, cfg, policy=copy.deepcopy(start), progress=False)
    curve = evaluation.CheckpointCurve(
        lambda p: evaluation.evaluate_policy("reacher1", p, n_episodes=1, divergences=False),
        cfg.loops * cfg.iterations * cfg.batch_size, 3)
    watched = dc.train("reacher1", demos, cfg, policy=copy.deepcopy(start), progress=False,
                       callback=curve)
    assert len(curve.points) >= 2
    for p, q in zip(plain.policy.parameters(), watched.policy.parameters()):
        assert torch.equal(p, q)


def _hopper_needs():
    ref = protocol.reference_cell("hopper")
    if not ref.path().exists():
        pytest.skip("the hopper reference cell is not stored")
    return [(cells.read_record(ref.path()), cells.read_features(ref.path()))]


@pytest.mark.parametrize("study, variant", [(dc_lr.STUDY, "lr=0.003"),
                                            (gail_lr.STUDY, "lr=0.003"),
                                            (dc_ablation.STUDY, "loops=2")])
def test_an_ablation_cell_keeps_its_curve_and_the_same_numbers_from_a_cached_start(study,
                                                                                 variant):
    """Every ablation cell (hopper, 11 demonstrations) records a deterministic evaluation
    curve with the budget's number of points, and a cell run on a warm worker cache (no BC
    trained) gives the record of a cold run."""
    smoke = budget.get("smoke")
    cell = next(c for c in study.cells(smoke) if c.variant == variant and c.seed == 0)
    assert cell.task == "hopper" and cell.n_demos == 11
    assert cell.config["curve"] == [smoke.ablation_curve_points, smoke.ablation_curve_episodes]
    needs = _hopper_needs()
    _imitation._CACHES.clear()
    cold, _ = study.run_cell(cell, needs)
    assert len(_imitation._CACHES) == 1
    warm, _ = study.run_cell(cell, needs)
    assert cells.split_timing(cold)[0] == cells.split_timing(warm)[0]
    points = cold["eval_curve"]
    assert len(points) == smoke.ablation_curve_points
    steps = [p["steps"] for p in points]
    assert steps == sorted(steps) and all(np.isfinite(p["scaled_return"]) for p in points)
