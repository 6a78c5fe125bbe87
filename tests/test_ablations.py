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


# -- the claims' rules, on constructed records ------------------------------------------------

from dc_lesson.experiments import ablations, claims   # noqa: E402


def _obs(row, seed, ret, curve=None, gap=None, per_loop=None):
    o = {"row": row, "task": "hopper", "n_demos": 11, "seed": seed, "scaled_return": ret}
    if curve is not None:
        o["eval_curve"] = [{"steps": 1000 * (i + 1), "scaled_return": v}
                           for i, v in enumerate(curve)]
    if gap is not None:
        o["curve"], o["iterations"] = {"pi_pi_prime_l1": gap}, per_loop
    return o


def _recs(obs):
    return {"ablation": {"observations": obs, "table": [], "cells": {}}}


def test_the_ablation_measures_read_the_curves_they_name():
    o = _obs("dc", 0, 1.0, curve=[0.2, 0.4, 0.9, 0.5, 0.9, 0.5])
    assert ablations.early_return(o) == pytest.approx(0.5)        # steps <= half: 3 points
    assert ablations.late_spread(o) == pytest.approx(np.std([0.5, 0.9, 0.5]))
    shrinking = _obs("dc", 0, 1.0, gap=[4, 4, 3, 2, 1, 1, 1, 1] * 2, per_loop=8)
    assert ablations.log_gap_ratio(shrinking) == pytest.approx(np.log(1 / 4))
    assert ablations.log_gap_ratio(_obs("dc", 0, 1.0, gap=[2.0] * 8, per_loop=4)) == 0.0
    assert ablations.early_return(_obs("dc", 0, 1.0)) is None     # no curve: no measure


def test_the_worst_rate_needs_every_rate_of_the_seed():
    obs = [_obs(f"dc-lr={lr}", s, r) for s in (0, 1) for lr, r in ((1e-4, 0.9), (1e-3, 0.2))]
    obs = obs[:-1]                                   # seed 1 lost its 1e-3 cell
    worst = ablations.worst_lr(obs, "dc")
    assert worst == [{"task": "hopper", "seed": 0, "row": "dc", "worst_lr_return": 0.2}]


@pytest.mark.usefixtures("judge_every_learner")
def test_each_ablation_claim_can_be_reproduced_contradicted_or_left_open():
    rng = np.random.default_rng(0)
    seeds = range(6)
    better = [_obs("dc-loops=4", s, 0.9 + 0.01 * rng.normal()) for s in seeds] + \
             [_obs("dc-loops=1", s, 0.5 + 0.01 * rng.normal()) for s in seeds] + \
             [_obs("dc-loops=1-long", s, 0.98 + 0.01 * rng.normal()) for s in seeds]
    v = {x.claim: x.verdict for x in ablations.verdicts(_recs(better))}
    assert v[claims.LOOPS.name] == "reproduced"
    assert v[claims.EQUAL_BUDGET.name] == "contradicted"      # the long loop did better
    null = [_obs(r, s, 0.7 + 0.1 * rng.normal()) for r in ("dc-loops=4", "dc-loops=1")
            for s in seeds]
    assert {x.claim: x.verdict for x in ablations.verdicts(_recs(null))}[
        claims.LOOPS.name] == "inconclusive"
    few = better[:3] + better[6:9]                   # three seeds: too few, whatever the gap
    assert {x.claim: x.verdict for x in ablations.verdicts(_recs(few))}[
        claims.LOOPS.name] == "not judged: fewer than 5 paired seeds"
    top = better + [_obs("bc", s, 1.0) for s in seeds]     # a start at the expert's return
    got = {x.claim: x.verdict for x in ablations.verdicts(_recs(top))}
    assert got[claims.LOOPS.name] == "not judged: start at the ceiling"
    assert got[claims.LONG_LOOP.name] == "reproduced"   # comparable: the ceiling leaves it open


@pytest.mark.usefixtures("judge_every_learner")
def test_figure_5_and_6_claims_compare_the_default_rates_and_the_copies_gap():
    seeds = range(5)
    dc_c, gail_c = [0.9, 0.95, 1.0, 1.0, 1.0, 1.0], [0.5, 0.3, 0.6, 0.2, 0.9, 0.1]
    obs = ([_obs("dc-lr=0.0003", s, 1.0, curve=[c - 0.01 * s for c in dc_c]) for s in seeds]
           + [_obs("gail-lr=0.0003", s, 0.5, curve=[c + 0.01 * s for c in gail_c])
              for s in seeds]
           + [_obs("dc-lr=0.001", s, 0.0, curve=[0.0] * 6) for s in seeds]   # not the default
           + [_obs("dc", s, 1.0, gap=[3, 3, 2, 1] * 2, per_loop=4) for s in seeds])
    v = {x.claim: x for x in ablations.verdicts(_recs(obs))}
    assert v[claims.FASTER.name].verdict == "reproduced"
    assert v[claims.STABLE.name].verdict == "reproduced"
    assert v[claims.CONVERGES.name].verdict == "reproduced"
    assert all(c.measure and len(c.reason) > 40 for c in ablations.CLAIMS)


def test_stored_verdicts_take_the_ablations_from_the_hopper_studies():
    names = {v.claim for v in ablations.book_verdicts()}
    assert {c.name for c in ablations.CLAIMS} <= names
    assert len(names) == len(ablations.book_verdicts())       # each claim judged once


def test_the_worker_cache_keeps_a_few_seeds_and_drops_the_oldest():
    _imitation._CACHES.clear()
    cache = _imitation.worker_cache(("test",))
    for seed in range(_imitation._STARTS_KEPT + 3):
        cache[("hopper", seed)] = seed
    assert len(cache) == _imitation._STARTS_KEPT
    assert ("hopper", 0) not in cache and ("hopper", _imitation._STARTS_KEPT + 2) in cache
    assert _imitation.worker_cache(("test",)) is cache
    _imitation._CACHES.clear()


def _rerun_record(per_rate: dict, seeds=range(5)):
    """A stored ``ablations.json`` as ``studies.ablations`` writes it: DC's default row
    ``dc`` (with each seed's start) and one ``dc-lr=X`` row per other rate."""
    obs = []
    for s in seeds:
        start = {"scaled_return": 0.5}
        obs.append({"row": "dc", "task": "hopper", "n_demos": 11, "seed": s,
                    "scaled_return": per_rate[3e-4][s], "start": start,
                    "curve": [{"steps": 1000, "scaled_return": 0.6}], "log": {}})
        for lr, v in per_rate.items():
            if lr != 3e-4:
                obs.append({"row": f"dc-lr={lr:g}", "task": "hopper", "n_demos": 11,
                            "seed": s, "scaled_return": v[s], "start": start})
    return {"observations": obs, "table": [{"row": "dc", "task": "hopper"}],
            "cells": {"n": 1, "of": 1}}


def test_dc_works_in_a_wide_range_of_rates_reads_its_worst_rate_against_its_default():
    wide = {c.name: c for c in ablations.CLAIMS}[claims.LR_WIDE.name]
    same = {lr: [0.9 + 0.001 * s for s in range(5)] for lr in (1e-4, 3e-4, 1e-3)}
    got = {v.claim: v for v in ablations.verdicts(ablations.from_rerun(_rerun_record(same)),
                                                  competence=None)}
    assert got[wide.name].verdict == "equal within 0.05"
    crash = {**same, 3e-3: [0.1, 0.05, 0.2, 0.0, 0.15]}     # one rate that falls
    got = {v.claim: v for v in ablations.verdicts(ablations.from_rerun(_rerun_record(crash)),
                                                  competence=None)}
    assert got[wide.name].verdict == "contradicted"
    assert "dc-worst - dc" in got[wide.name].evidence


def test_the_rerun_is_read_with_its_default_rate_as_a_row_of_the_sweep():
    rec = ablations.from_rerun(_rerun_record({3e-4: [1.0] * 5, 1e-3: [0.5] * 5}))
    rows = {o["row"] for o in rec["ablation"]["observations"]}
    assert {"bc", "dc", "dc-lr=0.0003", "dc-lr=0.001"} <= rows
    assert sum(o["row"] == "bc" for o in rec["ablation"]["observations"]) == 5   # once a seed
    assert any(r["row"] == "dc-lr=0.0003" for r in rec["ablation"]["table"])
    with pytest.raises(ValueError, match="which="):
        ablations.load("newest")
