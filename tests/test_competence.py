"""The competence gate's rules on constructed runs (issue 38): what "keeps a perfect start"
and "learns" mean, and how a failed gate reaches a verdict as "not judged"."""

import pytest

from dc_lesson import budget
from dc_lesson.experiments import studies
from dc_lesson.experiments.studies import competence as comp


def run(start, final, curve=()):
    return {"start": start, "final": final, "curve": list(curve)}


def test_keeping_allows_the_tolerance_and_one_seed_in_ten():
    ok = [run(1.0, 0.96, [0.99, 0.97])] * 9 + [run(1.0, 0.7, [0.85])]
    assert comp.keeps(ok) == comp.Part(True, "", True, False)
    two_bad = [run(1.0, 0.96)] * 8 + [run(1.0, 0.7)] * 2
    passed, why, *_ = comp.keeps(two_bad)
    assert not passed and "2 of 10 seeds" in why


def test_a_dip_below_the_start_fails_even_when_the_end_recovers():
    runs = [run(1.0, 1.0, [1.0, 0.75, 1.0])] + [run(1.0, 1.0, [1.0])] * 9
    passed, why, *_ = comp.keeps(runs)
    assert not passed and "0.25 below" in why


def test_a_knife_edge_start_shows_its_dips_and_judges_by_the_finals():
    shares = [{"task": "hopper", "scale": comp.STEP_SCALE, "share": 16 / 30},
              {"task": "hopper", "scale": 1e-3, "share": 1 / 30},
              {"task": "cartpole", "scale": comp.STEP_SCALE, "share": 0.0},
              {"task": "walker", "scale": comp.STEP_SCALE, "share": comp.KNIFE_EDGE_SHARE}]
    # the share must exceed the keep rule's allowance, and only at the step's scale counts
    assert comp.knife_edge(shares) == {"hopper"}
    assert comp.knife_edge(None) == frozenset()
    dipping = [run(1.0, 1.0, [0.2, 1.0])] * 10
    assert comp.keeps(dipping)[0] is False
    assert comp.keeps(dipping, gate_dip=False)[:2] == (True, comp.DIP_NOT_GATED)
    # the finals rule still decides on a knife-edge task
    ending_low = [run(1.0, 0.7, [1.0])] * 2 + [run(1.0, 1.0, [1.0])] * 8
    assert comp.keeps(ending_low, gate_dip=False)[0] is False
    obs = _obs("dc", "keep", "hopper", 1.0, 1.0, 10, [0.2, 1.0])
    assert "0.80 below" in comp.gate(obs)["dc"]["reason"]
    assert "keep on hopper" not in comp.gate(obs, frozenset({"hopper"}))["dc"]["reason"]


def test_learning_needs_the_floor_from_a_start_that_is_weak():
    assert comp.learns([run(0.2, 0.85), run(0.1, 0.8)])[:2] == (True, "")
    passed, why, *_ = comp.learns([run(0.2, 0.6), run(0.3, 0.7)])
    assert passed is False and "0.65" in why
    # a start already near the expert says nothing about learning: neither pass nor fail
    passed, why, open_, _ = comp.learns([run(0.9, 0.95)] * 5)
    assert passed is None and "not weak" in why
    assert not open_   # more seeds of a start that is not weak would not make it weak


def _obs(learner, part, task, start, final, seeds, curve=None):
    return [{"row": learner, "part": part, "task": task, "start": start, "final": final,
             "curve": curve or [final]} for _ in range(seeds)]


def test_the_gate_is_one_word_per_learner_with_its_reasons():
    good = []
    for task in comp.KEEP_TASKS:
        good += _obs("gail", "keep", task, 1.0, 0.99, 10)
    for task in comp.LEARN_TASKS:
        good += _obs("gail", "learn", task, 0.2, 0.9, 5)
    bad = [dict(o, row="ndi") for o in good]
    bad = [dict(o, final=0.1, curve=[0.1]) if o["task"] == "cartpole" else o for o in bad]
    g = comp.gate(good + bad)
    assert g["gail"] == {"passed": True, "reason": ""}
    assert g["ndi"]["passed"] is False and "keep on cartpole" in g["ndi"]["reason"]
    # a learner with no runs has not failed: it has not yet shown competence
    assert g["dc"]["passed"] is None and "not run yet" in g["dc"]["reason"]
    # a failure names the failing part only; the open ones wait for it to be fixed
    half = [o for o in bad if o["part"] == "keep"]
    assert comp.gate(half)["ndi"] == {"passed": False,
                                      "reason": "keep on cartpole: ended more than 0.05 below "
                                                "its start on 10 of 10 seeds"}
    mapping = comp.competence({"observations": good + bad})
    assert "gail" not in mapping and mapping["ndi"].startswith("failed the competence gate")
    assert mapping["dc"].startswith("has not yet shown competence — keep on cartpole")


def test_a_failed_gate_makes_a_verdict_not_judged():
    from dc_lesson.experiments import verdicts
    g = comp.gate(_obs("ndi", "keep", "cartpole", 1.0, 0.1, 10))
    claim = verdicts.Claim("x", "test", "scaled_return", "dc", "ndi", 1, "constructed")
    members = [("hopper", [0.3, 0.2, 0.4, 0.3, 0.35], 0.5, 0.0)]   # a clear difference
    judged = verdicts.judge_family(claim, members, competence=comp.competence({"gate": g}))
    text = repr(judged)
    assert "not judged" in text and "competence gate" in text
    assert "not judged" not in repr(verdicts.judge_family(claim, members))


@pytest.mark.parametrize("name", ["smoke", "lesson", "paper"])
def test_the_grid_has_every_learner_on_every_part_and_seed(name):
    b = budget.get(name)
    grid = studies.get("competence").grid(b)
    keep = [c for c in grid if c.variant == "keep"]
    learn = [c for c in grid if c.variant == "learn"]
    assert len(keep) == len(comp.LEARNERS) * len(comp.KEEP_TASKS) * b.competence_keep_seeds
    assert len(learn) == len(comp.LEARNERS) * len(comp.LEARN_TASKS) * b.competence_learn_seeds
    assert {c.learner for c in grid} == set(comp.LEARNERS)
    assert all(c.config["steps"] == b.competence_learn_steps for c in learn)
    # the weak start is BC stopped early; the perfect start is BC run to its limit
    assert {c.config["start_epochs"] for c in learn} == {b.competence_weak_epochs}
    assert {c.config["start_epochs"] for c in keep} == {b.bc_max_epochs}


# -- the gate's first question run for real, small enough for CI -------------------------------
# Every registered RL learner from the same perfect cartpole BC start (4 demonstrations) for
# the smoke budget's interactions, on 3 seeds. Kept: the one-sided 95% upper bound of the mean
# drop (paired t, 2 degrees of freedom) below KEEP_TOLERANCE. Measured when the test was
# written (4 December 2026, smoke, 1 seed): GAIL and DRIL kept 1.00; PPO ended at -0.18, PWIL
# 0.02, NDI 0.09, GPRIL -0.01 and DC 0.33. After PPO's frozen start normaliser and the shared
# start noise (algorithms.base.START_LOG_STD; 5 December, smoke, drops on seeds 0-2): GAIL,
# DRIL, DC 0 0 0; PWIL 0.004 0 0; PPO 0 0 0.31; NDI 0 0.69 0; GPRIL 0.83 0.78 0.89. Those
# still failing are strict expected failures (a fix turns them into errors to remove the
# mark, as it should).
# GPRIL with the study's predecessor weight (0.1) still drops 0.68-0.89 here (5 December): at
# smoke it makes 3 AdamW steps at lr 1e-3 on a converged BC loss, whose normalised steps move
# every weight by about the learning rate in the direction of the gradient's noise, with no
# iteration left to recover; at lesson (400,000 interactions, seeds 0-3) it ended at 1.00 on
# all four, its worst checkpoint at most 0.20 below the start. The test stays a strict
# expected failure of the smoke proxy, not of the learner.
# NDI with the study's settings (entropy bonus off, advantages not standardised): drops
# 0.00003 / 0.00001 / 0.00001, so it passes (it dropped 0.69 on seed 1 before).
# PWIL with the study's kernel (beta = 1, which lets it learn hopper): drops 0 / 0 / 0.49 on
# seeds 0-2 here (5 December, sixth session); the wider kernel pays a graded reward from
# the start, and at smoke's few iterations one seed's steps carry it off. The lesson cells
# say whether it keeps the start at the study's budget.
FAILS_TODAY = {"ppo", "gpril", "pwil"}
SEEDS = 3


def _drops(learner):
    import dataclasses
    import torch
    torch.set_num_threads(1)
    b = dataclasses.replace(budget.get("smoke"), competence_keep_seeds=SEEDS)
    grid = [c for c in studies.get("competence").grid(b)
            if c.learner == learner and c.task == "cartpole" and c.variant == "keep"]
    assert len(grid) == SEEDS
    out = []
    for c in grid:
        res, _ = comp.run_cell(c, [])
        out.append(res["start"]["scaled_return"] - res["final"]["scaled_return"])
    return out


@pytest.mark.parametrize("learner", [pytest.param(
    x, marks=pytest.mark.xfail(strict=True, reason="loses its perfect start today (issue 38)"))
    if x in FAILS_TODAY else x for x in comp.LEARNERS if x not in comp.VARIANTS])
def test_a_learner_keeps_a_perfect_cartpole_start(learner):
    # the mixture variant is left out: at smoke its start (the mixture BC matched to plain BC,
    # at most 12 epochs) matches on 1 of seeds 0-2 (6 December), so there is no perfect start
    # to keep; the gate then calls its keep part not informative (the test below)
    import numpy as np
    from scipy import stats as sstats
    d = np.array(_drops(learner))
    upper = d.mean() + (sstats.t.ppf(0.95, len(d) - 1) * d.std(ddof=1) / np.sqrt(len(d))
                        if d.std(ddof=1) > 0 else 0.0)
    assert upper < comp.KEEP_TOLERANCE, f"{learner}: drops {np.round(d, 3)}"


def test_the_start_noise_rule_reaches_every_learner_and_leaves_stored_cells_alone():
    import dataclasses
    import json
    import torch
    from dc_lesson import algorithms
    from dc_lesson.algorithms import base
    from dc_lesson.algorithms.bc import warm_start_policy
    from dc_lesson.data import store
    b = budget.get("smoke")
    for learner in comp.LEARNERS:
        cfg = comp.learner_config(learner, b, "keep", 0)
        assert cfg.start_log_std == base.START_LOG_STD          # one rule, every learner
        assert json.loads(cfg.to_json())["start_log_std"] == base.START_LOG_STD
        unset = dataclasses.replace(cfg, start_log_std=None)
        # unset, the field is not in the config a stored cell was hashed from
        assert ("start_log_std" in json.loads(unset.to_json())) == (learner == "gail")
    # the rule is applied: a start given at log-std -0.5 trains from START_LOG_STD (ppo's
    # first batch is drawn at the start's noise; with no step taken, it is still there)
    demos = store.load_demos("cartpole", n_trajectories=2)
    start = warm_start_policy(demos, 0, max_epochs=2)
    cfg = dataclasses.replace(algorithms.get("dc").preset(b, 0), start_log_std=-1.25)
    base.set_start_noise(start, cfg.start_log_std)
    assert torch.all(start.log_std == -1.25)
    base.set_start_noise(start, None)                           # None keeps it
    assert torch.all(start.log_std == -1.25)


def test_ppo_keeps_a_given_start_s_input_scale():
    import copy
    import torch
    from dc_lesson.algorithms import ppo
    from dc_lesson.algorithms.bc import warm_start_policy
    from dc_lesson.data import store
    torch.set_num_threads(1)
    start = warm_start_policy(store.load_demos("cartpole", n_trajectories=2), 0, max_epochs=2)
    before = copy.deepcopy(start.obs_norm.state_dict())
    out = ppo.train("cartpole", policy=start, config=ppo.preset(budget.get("smoke"), 0),
                    progress=False)
    after = out.policy.obs_norm.state_dict()
    # a broken run merges its rollouts into the start's normaliser (the fault found)
    assert all(torch.equal(before[k], after[k]) for k in before)


@pytest.mark.parametrize("learner", ["gail", "pwil", "dc", "gpril"])
def test_a_training_only_termination_reaches_every_loop_that_steps_the_task(learner,
                                                                          monkeypatch):
    # GAIL's loop, _reward_ppo's (DRIL, PWIL, NDI) and DC's built their environments without
    # PPO's termination before issue 38: a hopper that fell went on lying there
    import dataclasses
    import torch
    from dc_lesson import algorithms
    from dc_lesson.algorithms import dc as dc_mod
    from dc_lesson.algorithms import ppo
    from dc_lesson.data import store
    torch.set_num_threads(1)
    seen = []
    real = ppo.EnvBatch

    class Recording(real):
        def __init__(self, task, n_envs, seed, episode_steps=None, terminate=None):
            seen.append(terminate)
            super().__init__(task, n_envs, seed, episode_steps, terminate)
    monkeypatch.setattr(ppo, "EnvBatch", Recording)
    monkeypatch.setattr(dc_mod, "EnvBatch", Recording)
    b = dataclasses.replace(budget.get("smoke"), competence_keep_steps=1024)
    def end(cfg):
        return cfg.ppo.terminate if hasattr(cfg, "ppo") else cfg.terminate
    assert end(comp.learner_config(learner, b, "keep", 0, "hopper")) == "hopper-fall"
    assert end(comp.learner_config(learner, b, "keep", 0, "cartpole")) is None
    algorithms.get(learner).train("hopper", store.load_demos("hopper", n_trajectories=2),
                                  comp.learner_config(learner, b, "keep", 0, "hopper"),
                                  progress=False)
    assert seen and set(seen) == {"hopper-fall"}


# -- the chapter's reading of the aggregate (experiments.competence) ---------------------------

def _record(obs):
    for i, o in enumerate(obs):
        o.setdefault("seed", i)
        o.setdefault("curve_steps", [1000 * (k + 1) for k in range(len(o["curve"]))])
    return {"observations": obs, "steps": {"keep": 1000, "learn": 2000},
            "cells": {"n": len(obs), "of": 99, "wall_seconds": 3600.0}, "budget": "smoke",
            "complete": False, "benchmark": "competence"}


def test_a_part_with_seeds_still_to_run_is_decided_only_where_they_cannot_change_it():
    def runs(finals, dip=0.0):
        return [{"start": 1.0, "final": f, "curve": [1.0 - dip]} for f in finals]
    need = {"keep": 10, "learn": 5}
    # three perfect seeds of ten: not yet a pass
    assert comp.judge_part("keep", "cartpole", runs([1.0] * 3), n_seeds=10)[0] is None
    # one of three ended low: within the rule's allowance of 1 in 10, so not yet a failure
    assert comp.judge_part("keep", "cartpole", runs([1.0, 1.0, 0.5]), n_seeds=10)[0] is None
    ok, why, _, _ = comp.judge_part("keep", "cartpole", runs([1.0, 0.5, 0.5]), n_seeds=10)
    assert ok is False and "allows 1 of 10" in why                  # no seed can undo it
    assert comp.judge_part("keep", "cartpole", runs([1.0], dip=0.3), n_seeds=10)[0] is False
    assert comp.judge_part("keep", "hopper", runs([1.0], dip=0.3), frozenset({"hopper"}),
                           n_seeds=10)[0] is None                   # a knife-edge dip
    learn = [{"start": 0.0, "final": 0.9, "curve": [0.9]}] * 2
    assert comp.judge_part("learn", "hopper", learn, n_seeds=5) == comp.Part(
        None, "2 of 5 seeds on record", True, False)
    assert comp.judge_part("learn", "hopper", learn * 3, n_seeds=5)[:2] == (True, "")
    # the gate: a learner whose every part passes on some of its seeds has not yet passed
    obs = [dict(r, row="dril", part="keep", task=t) for t in comp.KEEP_TASKS
           for r in runs([1.0] * 2)]
    obs += [dict(r, row="dril", part="learn", task=t) for t in comp.LEARN_TASKS for r in learn]
    assert comp.gate(obs)["dril"]["passed"] is True                 # the seeds as the whole
    got = comp.gate(obs, seeds=need)["dril"]
    assert got["passed"] is None and "2 of 10 seeds on record" in got["reason"]
    from dc_lesson.experiments import competence as report
    rec = dict(_record([dict(o) for o in obs]), budget="lesson")     # 10 and 5 seeds a part
    assert set(report.overview(rec)["DRIL"].values()) == {"not decided (2)"}
    assert report.gate_words(rec)["DRIL"].startswith("not yet shown")


def test_a_failure_to_learn_is_read_beside_the_control_on_the_same_starts():
    from dc_lesson.experiments import competence as report

    def seeds(learner, task, finals):
        return [dict(o, seed=i, final=f, curve=[f]) for i, (o, f) in enumerate(
            zip(_obs(learner, "learn", task, 0.02, 0.0, len(finals)), finals))]
    obs = (seeds("ppo", "hopper", [0.95, 0.9, 0.97]) + seeds("gail", "hopper", [0.5, 0.4, 0.6])
           + seeds("ppo", "halfcheetah", [0.2, 0.3]) + seeds("pwil", "halfcheetah", [0.1, 0.2])
           + seeds("dril", "hopper", [0.9, 0.95, 0.99])          # passes: no row
           + seeds("gpril", "hopper", [0.1, 0.1, 0.1])           # no RL step: no row
           + seeds("ndi", "halfcheetah", [0.0, 0.0, 0.1]))      # the control ran seeds 0-1
    got = {(r["learner"], r["task"]): r for r in report.beside_control(_record(obs))}
    assert set(got) == {("GAIL", "hopper"), ("PWIL", "halfcheetah"), ("NDI", "halfcheetah")}
    gail = got[("GAIL", "hopper")]
    assert gail["paired seeds"] == 3 and gail["hi"] < 0
    assert abs(gail["difference"] - (-0.45 - 0.5 - 0.37) / 3) < 1e-9    # paired by seed
    assert "not in RL from this start" in gail["reading"]
    assert "either" in got[("PWIL", "halfcheetah")]["reading"]       # PPO fails there too
    assert got[("NDI", "halfcheetah")]["paired seeds"] == 2           # only seeds both ran


def test_the_chapter_table_words_each_part_from_the_seeds_on_record():
    from dc_lesson.experiments import competence as report
    obs = _obs("gail", "keep", "cartpole", 1.0, 1.0, 9, [1.0, 1.0]) + \
        _obs("gail", "keep", "cartpole", 1.0, 1.0, 1, [1.0, 0.7])       # one dip of 0.3
    obs += _obs("dc", "keep", "cartpole", 1.0, 0.99, 10, [1.0, 0.99])
    rec = _record([dict(o) for o in obs])
    rows = {(r["learner"], r["part"], r["task"]): r for r in report.rows(rec)}
    gail = rows[("GAIL", "keep", "cartpole")]
    assert gail["seeds"] == 10 and gail["word"].startswith("fails") and "0.30" in gail["word"]
    assert abs(gail["worst dip"] - 0.3) < 1e-12
    assert rows[("DC", "keep", "cartpole")]["word"] == "passes"
    assert rows[("DC", "keep", "hopper")]["word"] == "not run yet"
    words = report.gate_words(rec)
    assert words["GAIL"].startswith("failed") and "keep on cartpole" in words["GAIL"]
    # parts not yet run never pass and never fail: DC is "not yet shown", naming them
    assert words["DC"].startswith("not yet shown") and "keep on hopper" in words["DC"]
    assert report.overview(rec)["DC"] == {"keep: cartpole": "passes (10)",
                                          "keep: hopper": "not run", "learn: hopper": "not run",
                                          "learn: halfcheetah": "not run"}
    text = report.sentence(rec)
    assert "GAIL" in text and "failed" in text and "passed the whole gate" not in text
    assert "still accumulating" in report.status(rec)


def test_the_chapter_curves_carry_an_interval_over_seeds():
    from dc_lesson.experiments import competence as report
    obs = [{"row": "pwil", "part": "learn", "task": "hopper", "start": 0.1, "final": f,
            "curve": [0.1, f]} for f in (0.5, 0.7, 0.9)]
    c = report.curves(_record(obs), "learn", "hopper")["PWIL"]
    assert c["seeds"] == 3 and c["steps"] == [1000, 2000]
    assert abs(c["mean"][1] - 0.7) < 1e-12 and c["lo"][1] < 0.7 < c["hi"][1]
    assert report.curves(_record(obs), "keep", "hopper") == {}


def test_each_learner_s_own_fixes_reach_its_config_and_its_cells():
    import json
    b = budget.get("lesson")
    for learner, fixes in comp.FIXES.items():
        cfg = comp.learner_config(learner, b, "keep", 0, "hopper")
        for name, value in fixes.items():
            got = cfg
            for part in name.split("."):
                got = getattr(got, part)
            assert got == value, (learner, name)
        assert cfg.start_log_std == -2     # the shared rules kept
        assert getattr(cfg, "ppo", cfg).terminate == "hopper-fall"
        cell = next(c for c in studies.get("competence").grid(b) if c.learner == learner)
        text = json.dumps(cell.config, sort_keys=True)
        assert all(json.dumps(k.split(".")[-1]) in text for k in fixes)   # part of its identity


def test_dril_s_bc_steps_follow_dc_s_balance_rule_at_every_budget():
    # the fix is a rule (one BC step per PPO minibatch step, as DC), not a tuned number
    from dc_lesson.algorithms import dc
    for name in ("smoke", "lesson", "paper"):
        b = budget.get(name)
        cfg = comp.learner_config("dril", b, "keep", 0, "cartpole")
        assert cfg.bc_steps == cfg.ppo.n_epochs * cfg.ppo.n_minibatches
    ppo = dc.DCConfig().ppo_config      # DC's own default follows the same rule
    assert dc.DCConfig().bc_steps == ppo.n_epochs * ppo.n_minibatches


def test_the_aggregate_reads_a_record_s_wall_clock_from_its_timing():
    # a sweep record keeps wall-clock figures apart from the numbers (cells.split_timing)
    b = budget.get("smoke")
    cell = studies.get("competence").grid(b)[0]
    point = {"scaled_return": 1.0}
    rec = {"cell": {"learner": cell.learner, "task": cell.task, "seed": cell.seed,
                    "variant": cell.variant},
           "result": {"start": point, "final": point,
                      "curve": [{"steps": 1024, "scaled_return": 1.0}]},
           "timing": {"train_seconds": 12.5}}
    agg = comp.aggregate([rec], b)
    assert agg["observations"][0]["train_seconds"] == 12.5
    assert agg["observations"][0]["curve_steps"] == [1024]


def test_the_book_s_verdicts_read_the_stored_gate_by_default(monkeypatch):
    """Every verdict entry point (here Table I's claims on constructed mode shares) holds back
    a learner the stored study has not shown competent, and judges it once it passed; with no
    study on record nothing RL-based is judged."""
    from dc_lesson.experiments import claims, competence as report
    shares = {"r2": {"red": 0.5, "blue": 0.5}}
    obs = []
    for s in range(10):
        obs += [{"task": "r2", "seed": s, "row": "bc", "mode_shares": {"red": .5, "blue": .5}},
                {"task": "r2", "seed": s, "row": "gail", "mode_shares": {"red": 1., "blue": 0.}}]
    passing = []
    for task in comp.KEEP_TASKS:
        passing += _obs("gail", "keep", task, 1.0, 0.99, 10)
    for task in comp.LEARN_TASKS:
        passing += _obs("gail", "learn", task, 0.2, 0.9, 5)
    failing = [dict(o, final=0.1, curve=[0.1]) for o in passing]

    def word(study):
        monkeypatch.setattr(report, "load", lambda name=report.RESULT: study)
        v = {x.claim: x for x in claims.verdicts(obs, shares)}[claims.GAIL_COLLAPSES.name]
        return v.per_task[0][1]

    # constructed observations name no grid: the gate holds back even a passed learner ...
    assert word({"observations": passing}) == "not judged: gail " + report.PRE_GATE
    # ... until the grid is one made under the gate's settings
    monkeypatch.setattr(report, "under_gate", lambda *grids: True)
    assert word({"observations": passing}) == "reproduced"
    assert word({"observations": failing}).startswith(
        "not judged: gail failed the competence gate — keep on cartpole")
    assert word(None).startswith("not judged: gail has not yet shown competence — no "
                                 "competence study on record")
    # a mapping given explicitly wins over the stored gate ({}: judge every learner)
    assert claims.verdicts(obs, shares, competence={})[2].per_task[0][1] == "reproduced"


def test_a_curve_flattens_where_every_later_mean_stays_near_its_final_level():
    from dc_lesson.experiments import competence as report
    steps = [100 * (i + 1) for i in range(8)]
    rising = [0.0, 0.3, 0.6, 0.8, 0.9, 0.93, 0.92, 0.94]     # level 0.93
    assert report.plateau(steps, rising) == 500               # 0.9 is within 0.05 of it
    # a late dip moves the plateau past it, however early the curve first got there
    dipped = [0.0, 0.9, 0.93, 0.7, 0.92, 0.93, 0.94, 0.93]
    assert report.plateau(steps, dipped) == 500
    assert report.plateau(steps, [0.5] * 8) == 100            # flat from the start
    # there early, then wobbling above the level: learned at 200 (the wobble is not learning)
    assert report.plateau(steps, [0.0, 0.98, 0.85, 0.99, 0.86, 0.85, 0.86, 0.85]) == 200
    assert report.plateau(steps[:3], rising[:3]) is None      # too short to have a level


def test_the_budget_is_the_latest_plateau_of_the_learners_that_learn():
    from dc_lesson.experiments import competence as report
    obs = []
    curve_steps = [100_000 * (i + 1) for i in range(8)]
    for s in range(5):
        obs.append({"row": "dc", "part": "learn", "task": "hopper", "seed": s, "start": 0.1,
                    "final": 0.9, "curve": [0.1, 0.5] + [0.9] * 6,
                    "curve_steps": curve_steps})
        obs.append({"row": "gail", "part": "learn", "task": "hopper", "seed": s, "start": 0.1,
                    "final": 0.85, "curve": [0.1, 0.2, 0.4, 0.6] + [0.85] * 4,
                    "curve_steps": curve_steps})
        obs.append({"row": "ndi", "part": "learn", "task": "hopper", "seed": s, "start": 0.1,
                    "final": 0.1, "curve": [0.1] * 8, "curve_steps": curve_steps})
        obs.append({"row": "ppo", "part": "learn", "task": "hopper", "seed": s, "start": 0.1,
                    "final": 0.9, "curve": [0.1] * 6 + [0.9] * 2, "curve_steps": curve_steps})
    got = {(r["task"], r["learner"]): r for r in report.budgets({"observations": obs})}
    assert got[("hopper", "PPO (task reward)")]["flattens at"] == 700_000   # the control:
    # shown, but no later grid runs it, so it does not set the budget
    assert got[("hopper", "DC")]["flattens at"] == 300_000
    assert got[("hopper", "GAIL")]["flattens at"] == 500_000
    assert got[("hopper", "NDI")]["flattens at"] == 100_000       # never rose: flat at once
    assert got[("hopper", "budget")]["flattens at"] == 500_000    # NDI does not count
    assert got[("halfcheetah", "budget")]["flattens at"] is None
    # a learner that failed the gate runs in no grid: its slower curve sets no budget
    gate = {"gail": {"passed": False, "reason": "keep on cartpole"},
            "dc": {"passed": True, "reason": ""}}
    got = {(r["task"], r["learner"]): r
           for r in report.budgets({"observations": obs, "gate": gate})}
    assert got[("hopper", "GAIL")]["flattens at"] == 500_000      # still shown
    assert got[("hopper", "budget")]["flattens at"] == 300_000    # DC's alone


def test_the_gate_vouches_only_for_grids_made_under_its_settings(monkeypatch):
    from dc_lesson.experiments import competence as report
    monkeypatch.setattr(report, "mapping", lambda rec=None: {"gail": "failed the gate — why"})
    marked = {report.GRID_MARK: report.RULES}
    assert report.resolve("stored", marked) == {"gail": "failed the gate — why"}
    for grid in (None, {}, {report.GRID_MARK: "an older rule set"}):
        held = report.resolve("stored", grid)
        # a learner that passed is held back on an older grid; a failed one keeps its reason
        assert held["dc"] == report.PRE_GATE and held["gail"] == "failed the gate — why"
        assert set(held) == set(comp.LEARNERS)
    assert report.under_gate(marked, marked) and not report.under_gate(marked, {})
    # a verdict that reads several grids (the hopper ablations) needs every one marked
    assert report.resolve("stored", marked, {})["dc"] == report.PRE_GATE
    assert "dc" not in report.resolve("stored", marked, marked)
    assert not report.under_gate()
    assert report.resolve({}, None) == {}      # an explicit mapping is used as given


def test_a_failure_a_standard_library_shares_is_the_algorithm_s_not_ours():
    ours = [{"seed": s, "final": f} for s, f in enumerate([0.5, 0.55, 0.6, 0.45])]
    worse = [{"seed": s, "final": f} for s, f in enumerate([0.15, 0.2, 0.1, 0.12])]
    better = [{"seed": s, "final": f} for s, f in enumerate([0.9, 0.95, 0.85, 0.9])]
    ok, said = comp.matches_reference(ours, worse)
    assert ok and "4 paired seeds" in said
    assert comp.matches_reference(ours, better)[0] is False
    # too few seeds in common: not matched, and says so
    ok, said = comp.matches_reference(ours, worse[:2])
    assert not ok and "2 of our seeds" in said
    # an unpaired seed of the reference does not count
    assert not comp.matches_reference(ours[:2], worse[:2] + [{"seed": 9, "final": 0.0}])[0]
    learn = [dict(o, row="gail", part="learn", task="hopper", start=0.02, curve=[o["final"]])
             for o in ours]
    refs = {("gail", "learn", "hopper"): comp.matches_reference(ours, worse)}
    assert "learn on hopper" in comp.gate(learn)["gail"]["reason"]
    assert "learn on hopper" not in comp.gate(learn, references=refs)["gail"]["reason"]
    # the part passes with the reference's evidence as its reason; a kept failure stays
    word = comp.judge_part("learn", "hopper", learn, reference=refs[("gail", "learn", "hopper")])
    assert word.ok and word.by_reference and "paired seeds" in word.why
    assert word.why.startswith("reached ")   # the failure the reference matched stays named
    assert comp.judge_part("learn", "hopper", learn,
                           reference=(False, "no"))[0] is False


def test_brief_cuts_a_gate_reason_to_its_head_and_keeps_other_text():
    from dc_lesson.experiments import competence as gate
    assert gate.brief(f"not judged: dc {gate.PRE_GATE}") == \
        "not judged: dc ran before the gate's settings"
    long = ("not judged on reacher4 (gail failed the competence gate — keep on cartpole: "
            "ended more than 0.05 below its start on 2 of 10 seeds)")
    assert gate.brief(long) == "not judged on reacher4 (gail failed the competence gate)"
    assert gate.brief("inconclusive") == "inconclusive"
    assert gate.brief("not judged: dc-mix cannot show competence on our ports — keep on "
                      "cartpole: its mixture start did not match") == \
        "not judged: dc-mix cannot show competence on our ports"


def test_the_mixture_variant_is_dc_from_a_mixture_start_gated_like_every_learner():
    """``dc-mix`` (chapter 04's mixture DC) runs DC's own gated config from a mixture BC
    start whose spreads are the gate's exploration noise; its rows, and the coin twin's, are
    held back by its own gate word, never by DC's."""
    import torch
    from dc_lesson.algorithms import base
    from dc_lesson.data import store
    from dc_lesson.experiments import verdicts
    from dc_lesson.nn import mixture
    lesson = budget.get("lesson")
    grid = [c for c in studies.get("competence").grid(lesson) if c.seed == 0
            and c.task == "cartpole" and c.variant == "keep"]
    mix = next(c for c in grid if c.learner == "dc-mix")
    plain = next(c for c in grid if c.learner == "dc")
    assert mix.config["dc-mix"] == plain.config["dc"] and mix.config["start_policy"] == "mixture"
    assert "start_policy" not in plain.config          # the stored DC cells keep their identity
    smoke = budget.get("smoke")
    start, match = comp.mixture_start("cartpole", store.load_demos("cartpole", n_trajectories=4),
                                      0, smoke, "learn")
    assert isinstance(start, mixture.MixturePolicy) and match is None   # weak: not matched
    with torch.no_grad():
        _, _, log_std = start.components(torch.zeros(3, start.obs_dim))
    assert torch.allclose(log_std, torch.full_like(log_std, base.START_LOG_STD))
    held = {"dc-mix": "has not yet shown competence — keep on cartpole: not run yet"}
    assert verdicts.rows_gate(("dc-mix-coin", "bc-mix-coin"), held).startswith(
        "dc-mix-coin has not yet shown competence")
    assert verdicts.rows_gate(("dc", "bc-mix"), held) is None
    # a variant that passed is judged even where its learner failed: its own word, not DC's
    failed_dc = {"dc": "failed the competence gate — x", "dc-mix": ""}
    assert verdicts.rows_gate(("dc-mix-coin", "bc-mix-coin"), failed_dc) is None
    assert verdicts.rows_gate(("dc-coin",), failed_dc).startswith("dc-coin failed")
    obs = []
    for learner in ("dc", "dc-mix"):
        for part, tasks, n in (("keep", comp.KEEP_TASKS, 10), ("learn", comp.LEARN_TASKS, 5)):
            for task in tasks:
                good = (1.0, 1.0) if part == "keep" else (0.1, 0.9)
                obs += [dict(o, match_record=True if learner != "dc" and part == "keep"
                             else None) for o in _obs(learner, part, task, *good, n)]
    obs = [dict(o, final=0.1, curve=[0.1]) if o["row"] == "dc" and o["task"] == "cartpole"
           else o for o in obs]
    mapping = comp.competence({"observations": obs})
    assert mapping["dc-mix"] == "" and mapping["dc"].startswith("failed")
    assert verdicts.rows_gate(("dc-mix",), mapping) is None


def test_a_mixture_start_that_never_matched_plain_bc_leaves_keeping_unasked():
    """A keep part with a seed whose mixture start did not match plain BC is not informative
    (None, with the reason), never passed or failed, on all seeds or while seeds are to come."""
    runs = [{"start": 1.0, "final": 1.0, "curve": [1.0], "matched": True} for _ in range(10)]
    assert comp.keeps(runs)[:2] == (True, "")
    runs[3] = dict(runs[3], matched=False, start=0.3, final=0.0, curve=[0.0])
    ok, why, open_, _ = comp.keeps(runs)
    assert ok is None and "did not match plain BC on 1 of 10 seeds" in why and not open_
    ok, why, open_, _ = comp.so_far("keep", runs[:4], 10)
    assert ok is None and "did not match" in why and not open_
    assert comp.so_far("keep", [runs[0]], 10).open   # a matched seed alone: seeds to come
    assert comp.keeps([dict(r, matched=None) for r in runs[:3]])[0] is not None  # a Gaussian
    # the matched seeds are judged first: a failure they already show is a failure
    falls = [dict(r, final=0.0, curve=[0.0]) if i < 3 else r for i, r in enumerate(runs)]
    assert comp.keeps(falls)[0] is False and comp.so_far("keep", falls[:4], 10)[0] is False
    # a matched seed's dip: the reason says whose (the table's worst fall is every seed's)
    dips = [dict(r, curve=[0.7, 1.0]) if i == 0 else r for i, r in enumerate(runs)]
    ok, why, *_ = comp.keeps(dips)
    assert ok is False and why == ("a checkpoint of a seed whose start matched fell 0.30 "
                                   "below its start")


def test_a_mixture_start_matches_only_if_it_is_as_good_as_plain_bc_where_the_gate_looks():
    """``judge_starts``: a mixture keep start that matched on the match episodes but scored
    more than the tolerance below the same seed's Gaussian start on the gate's own episodes
    did not match (the first stored cell: 1.00 against 0.75)."""
    def o(row, start, record=None, seed=0):
        return {"row": row, "part": "keep", "task": "cartpole", "seed": seed, "start": start,
                "final": start, "curve": [start], "match_record": record}
    got = comp.judge_starts([o("dc", 1.0), o("dc-mix", 0.75, True), o("dc", 1.0, seed=1),
                             o("dc-mix", 0.97, True, seed=1), o("dc-mix", 1.0, False, seed=2),
                             o("dc-mix", 1.0, True, seed=3)])
    assert [got[i].get("matched") for i in (1, 3, 4, 5)] == [False, True, False, True]
    assert "matched" not in got[0]                                   # a Gaussian row


def test_a_mixture_variant_cell_records_its_match_and_the_aggregate_reads_it():
    """A ``dc-mix`` keep cell runs DC from its matched mixture start and keeps the match
    record; the aggregate carries whether it matched, which the gate reads."""
    import torch
    torch.set_num_threads(1)
    smoke = budget.get("smoke")
    cell = next(c for c in studies.get("competence").grid(smoke)
                if c.learner == "dc-mix" and c.task == "cartpole" and c.variant == "keep")
    res, _ = comp.run_cell(cell, [])
    assert set(res["match"]) == {"target", "tries", "matched"} and res["curve"]
    record = {"cell": cell.identity(), "result": res, "timing": {}}
    obs = comp.aggregate([record], smoke)["observations"]
    assert obs[0]["row"] == "dc-mix" and obs[0]["match_record"] is res["match"]["matched"]


def test_a_gate_held_only_by_an_unaskable_part_says_it_cannot_pass_not_yet():
    """dc-mix's cartpole keep part: its mixture start never matched plain BC on any seed, so
    no seed to come decides it. The gate, the verdicts' phrase and the chapter's word say it
    cannot be shown (not "not yet"); while another part still has seeds to run, "not yet"."""
    from dc_lesson.experiments import competence as report
    obs = []
    for learner in ("dc", "dc-mix"):
        for part, tasks, n in (("keep", comp.KEEP_TASKS, 10), ("learn", comp.LEARN_TASKS, 5)):
            for task in tasks:
                good = (1.0, 1.0) if part == "keep" else (0.1, 0.9)
                unmatched = learner == "dc-mix" and part == "keep" and task == "cartpole"
                for s in range(n):
                    obs.append({"row": learner, "part": part, "task": task, "seed": s,
                                "start": 0.6 if unmatched else good[0], "final": good[1],
                                "curve": [good[1]], "match_record": (
                                    None if learner == "dc" or part == "learn"
                                    else not unmatched)})
    seeds = {"keep": 10, "learn": 5}
    g = comp.gate(obs, seeds=seeds)
    assert g["dc"]["passed"] is True
    assert g["dc-mix"]["passed"] is None and g["dc-mix"]["open"] is False
    assert comp.UNMATCHED in g["dc-mix"]["reason"]
    phrase = comp.competence({"gate": g})["dc-mix"]
    assert phrase.startswith("cannot show competence on our ports — keep on cartpole")
    words = report.gate_words({"observations": obs, "budget": "lesson"})
    mix, dc = report.NAMES["dc-mix"], report.NAMES["dc"]
    assert words[mix].startswith(report.CANNOT) and words[dc] == "passed"
    assert "cannot pass" in report.sentence({"observations": obs, "budget": "lesson"})
    # one hopper learn seed still to run: open, "not yet"
    fewer = [o for o in obs if not (o["row"] == "dc-mix" and o["part"] == "learn"
                                    and o["task"] == "hopper" and o["seed"] == 4)]
    g = comp.gate(fewer, seeds=seeds)
    assert g["dc-mix"]["open"] is True
    assert comp.competence({"gate": g})["dc-mix"].startswith("has not yet shown competence")
    assert report.gate_words({"observations": fewer, "budget": "lesson"})[
        mix].startswith("not yet shown")
