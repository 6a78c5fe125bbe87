"""The benchmark with headroom (issue 41): its demonstrations from the headroom study, its
rows from the competence gate, its interactions from the competence curves, and cells whose
learners share their seed's BC start."""

import pytest

from dc_lesson import budget
from dc_lesson.algorithms import base
from dc_lesson.experiments import competence as gate_report
from dc_lesson.experiments.studies import benchmark as bm
from dc_lesson.experiments.studies import headroom

HEADROOM = {"benchmark": [
    {"task": "cartpole", "protocol": "subsampled", "every": 20, "counts": [1, 25], "why": ""},
    {"task": "hopper", "protocol": "subsampled", "every": 20, "counts": [11, 25], "why": ""},
    {"task": "walker", "protocol": "full", "every": None, "counts": [11, 25], "why": ""},
    {"task": "ant", "protocol": None, "every": None, "counts": [],
     "why": "BC passes the band between two neighbouring counts"}]}
GATE = {"gate": {"dc": {"passed": True, "reason": ""},
                 "gail": {"passed": False, "reason": "keep on cartpole: a dip"},
                 "dril": {"passed": None, "reason": "keep on hopper: 4 of 10 seeds"}}}


def test_the_design_follows_the_headroom_choice_and_says_why_where_it_falls_back():
    assert bm.design("hopper", HEADROOM) == {"task": "hopper", "protocol": "subsampled",
                                             "every": 20, "counts": [11, 25], "why": ""}
    assert bm.design("walker", HEADROOM)["every"] is None          # whole demonstrations
    ant = bm.design("ant", HEADROOM)
    assert ant["protocol"] == headroom.PREFERENCE[0] and ant["every"] == headroom.EVERY
    assert ant["counts"] == list(bm.FALLBACK_COUNTS) and "neighbouring" in ant["why"]
    assert bm.design("halfcheetah", HEADROOM)["counts"] == []       # no headroom row on record
    assert bm.design("humanoid", HEADROOM)["counts"] == []          # none on record either


def test_a_task_whose_default_expert_is_a_planner_has_no_row(monkeypatch):
    real = bm._data.manifest_entry
    monkeypatch.setattr(bm._data, "manifest_entry", lambda task, **kw: (
        {"expert": {"kind": "planner"}} if task == "hopper" else real(task, **kw)))
    planned = bm.design("hopper", HEADROOM)
    assert planned["counts"] == [] and "planner" in planned["why"]
    assert bm.design("walker", HEADROOM)["counts"] == [11, 25]


def test_only_learners_that_passed_the_gate_are_rows_and_the_others_say_why():
    said = bm.learners(GATE)
    assert said["dc"] == "passed" and said["gail"].startswith("failed the competence gate")
    assert "not decided" in said["dril"] and "no competence study" in said["pwil"]
    assert bm.listed(GATE) == ("bc", "dc")
    assert bm.listed({}) == ("bc",)


@pytest.fixture
def stored(monkeypatch):
    records = {bm.HEADROOM: HEADROOM, bm.COMPETENCE: GATE}
    monkeypatch.setattr(bm, "_stored", lambda name: records.get(name))
    return records


def test_the_grid_shares_each_seeds_start_and_runs_the_gates_settings(stored):
    lesson = budget.get("lesson")
    grid = [c for c in bm.cells_at(lesson) if c.learner != "expert"]
    assert {c.learner for c in grid} == {"bc", "dc"}
    assert {c.task for c in grid} == {"cartpole", "hopper", "walker", "ant"}
    assert len(grid) == 4 * 2 * lesson.benchmark_seeds * 2
    for c in grid:
        twin = next(x for x in grid if (x.task, x.n_demos, x.seed, x.learner)
                    == (c.task, c.n_demos, c.seed, "bc"))
        assert c.config["bc"] == twin.config["bc"]                  # one start per seed
        sub = c.config["subsample_every"]
        assert c.config["bc"]["epochs"] == (headroom.EVERY if sub else 1) * lesson.bc_max_epochs
        assert (c.config["bc"]["val_fraction"] == 0) == (c.n_demos == 1)
        if c.learner == "dc":
            cfg = c.config["dc"]
            assert c.config["steps"] == lesson.benchmark_steps_for(c.task)
            assert cfg["start_log_std"] == base.START_LOG_STD
            assert (cfg["ppo"]["terminate"] == "hopper-fall") == (c.task == "hopper")
    experts = {c.task for c in bm.cells_at(lesson) if c.learner == "expert"}
    assert experts == {"cartpole", "hopper", "walker", "ant"}


def test_benchmark_steps_follow_the_competence_curves():
    """Lesson's interactions are the stored competence study's budgets: the latest plateau of
    the gate-passing learners on each task it measures, the longest of those elsewhere."""
    rec = gate_report.load()
    if rec is None:
        pytest.skip("no competence.json on this checkout")
    lesson = budget.get("lesson")
    measured = {r["task"]: r["flattens at"] for r in gate_report.budgets(rec)
                if r["learner"] == "budget"}
    assert None not in measured.values()
    for task in bm.TASKS:
        want = measured.get(task, max(measured.values()))
        assert lesson.benchmark_steps_for(task) == want, task


def test_a_learners_cell_starts_from_its_seeds_bc_row(stored, monkeypatch):
    from dc_lesson import evaluation
    smoke = budget.get("smoke")
    real = evaluation.evaluate_policy

    def scaled_only(task, policy, reference, **kw):   # no fresh reference in a unit test
        return real(task, policy, None, **{**kw, "divergences": False})

    monkeypatch.setattr(bm._evaluation, "evaluate_policy", scaled_only)
    monkeypatch.setattr(bm._common, "reference", lambda needs: None)
    grid = [c for c in bm.cells_at(smoke) if c.task == "cartpole" and c.n_demos == 1]
    bc_cell = next(c for c in grid if c.learner == "bc")
    dc_cell = next(c for c in grid if c.learner == "dc")
    bc_out, _ = bm.run_cell(bc_cell, ())
    dc_out, _ = bm.run_cell(dc_cell, ())
    assert dc_out["start"] == bc_out["final"]          # the very policy the BC row scores
    assert len(dc_out["curve"]) == smoke.benchmark_curve_points


def test_the_ablations_start_where_the_benchmarks_hopper_row_starts_and_control_the_budget(
        stored):
    from dc_lesson.experiments.studies import ablations
    lesson = budget.get("lesson")
    grid = [c for c in ablations.cells_at(lesson) if c.learner != "expert"]
    bench = {(c.seed, c.learner): c for c in bm.cells_at(lesson)
             if c.task == "hopper" and c.n_demos == 11}
    assert {c.n_demos for c in grid} == {11}
    for c in grid:
        assert c.config["bc"] == bench[(c.seed, "bc")].config["bc"]   # the very start
    steps = {c.variant: c.config["steps"] for c in grid if c.seed == 0}
    total = {c.variant: c.config["curve_total"] for c in grid if c.seed == 0}
    assert steps["loops=4"] == 4 * steps["loops=1"]      # the loops: fixed iterations each
    assert steps["loops=4"] <= lesson.benchmark_steps_for("hopper")
    # the equal-budget control spends the 4 loops' interactions, their refits included
    assert total["loops=4"] <= total["loops=1-long"] < total["loops=4"] + 2000
    default = next(c for c in grid if c.seed == 0 and c.variant == "")
    assert default.config["dc"] == bench[(0, "dc")].config["dc"]         # the benchmark's DC
    lrs = sorted(v for v in steps if v.startswith("lr="))
    assert len(lrs) == len(lesson.lr_sweep_lrs) - 1 and "lr=0.0003" not in lrs


def test_an_ablation_cell_keeps_dcs_iteration_log(stored, monkeypatch):
    from dc_lesson import evaluation
    from dc_lesson.experiments.studies import ablations
    real = evaluation.evaluate_policy
    monkeypatch.setattr(bm._evaluation, "evaluate_policy",
                        lambda task, policy, reference, **kw: real(
                            task, policy, None, **{**kw, "divergences": False}))
    monkeypatch.setattr(ablations._common, "reference", lambda needs: None)
    cell = next(c for c in ablations.cells_at(budget.get("smoke"))
                if c.variant == "update=admm")
    out, _ = ablations.run_cell(cell, ())
    assert len(out["log"]["pi_pi_prime_l1"]) == cell.config["dc"]["loops"] * \
        cell.config["dc"]["iterations"]
    assert out["log"]["primal_residual"][-1] is not None                # ADMM's residuals


def test_the_ablation_claims_read_the_rerun_and_hold_gails_back():
    """The rerun's aggregate judged by the first grid's claims: its loops compared on every
    seed, GAIL's comparisons not judged (GAIL failed the gate, no GAIL row ran)."""
    from dc_lesson.experiments import ablations as words
    from dc_lesson.experiments import competence as gate
    obs = []
    for s in range(6):
        start = {"scaled_return": 0.45 + 0.01 * s}
        for row, v in (("dc-loops=1", 0.5), ("dc-loops=4", 0.9), ("dc-loops=1-long", 0.6),
                       ("dc", 0.8), ("dc-lr=0.0001", 0.7), ("dc-lr=0.001", 0.75),
                       ("dc-lr=0.003", 0.2)):
            obs.append({"row": row, "task": "hopper", "n_demos": 11, "seed": s,
                        "scaled_return": v + 0.01 * (-1) ** s, "start": start,
                        "curve": [{"steps": k, "scaled_return": v} for k in (1, 2, 3, 4)],
                        "log": {"pi_pi_prime_l1": [1.0, 0.5, 0.25, 0.1] * 2},
                        "iterations": 4})
    recs = words.from_rerun({"observations": obs, gate.GRID_MARK: gate.RULES})
    assert sum(o["row"] == "bc" for o in recs["ablation"]["observations"]) == 6
    got = {v.claim: v for v in words.verdicts(recs, competence={"gail": "failed the gate"})}
    c = words._claims
    assert got[c.LOOPS.name].verdict.startswith("reproduced")
    assert got[c.EQUAL_BUDGET.name].verdict.startswith("reproduced")
    assert got[c.CONVERGES.name].verdict.startswith("reproduced")
    for claim in (c.FASTER, c.STABLE, c.LR_ROBUST):
        assert got[claim.name].verdict.startswith("not judged"), got[claim.name].verdict


def test_dril_gets_the_same_pair_visits_and_dcs_curve_spans_its_whole_run(stored):
    """A review found DRIL's ensemble fitted for a twentieth of the gradient steps on
    subsampled demonstrations, and DC's checkpoints spread over fewer interactions than its
    run (the refit rollouts), before any such cell ran."""
    gate = {"gate": {"dc": {"passed": True, "reason": ""},
                     "dril": {"passed": True, "reason": ""}}}
    stored[bm.COMPETENCE] = gate
    lesson = budget.get("lesson")
    grid = [c for c in bm.cells_at(lesson) if c.learner in ("dril", "dc") and c.seed == 0]
    plain = bm._competence.gated_config("dril", lesson, 300_000, 0, "hopper").ensemble_epochs
    for c in grid:
        if c.learner == "dril":
            every = c.config["subsample_every"] or 1
            assert c.config["dril"]["ensemble_epochs"] == plain * every
        else:
            cfg = bm.learner_config("dc", lesson, c.task, 0, c.config["subsample_every"])
            assert c.config["curve_total"] == cfg.env_steps(c.task) > c.config["steps"] - 1
    from dc_lesson.experiments.studies import ablations
    cfgs = {c.variant: c.config for c in ablations.cells_at(lesson) if c.seed == 0}
    assert cfgs["loops=1-long"]["curve_total"] >= cfgs["loops=4"]["curve_total"]
    assert cfgs["loops=1-long"]["curve_total"] - cfgs["loops=4"]["curve_total"] < 2000
