"""Table I rerun under the gate (issue 41, item 4): its rows from the gate, the mixture BC
trained until it matches plain BC, and DC from the best BC."""

import pytest

from dc_lesson import budget
from dc_lesson.experiments import cells
from dc_lesson.experiments.studies import benchmark as bm
from dc_lesson.experiments.studies import modes

GATE = {"gate": {"dc": {"passed": True, "reason": ""},
                 "dril": {"passed": True, "reason": ""},
                 "gail": {"passed": False, "reason": "keep on cartpole"}}}


@pytest.fixture
def gate(monkeypatch):
    monkeypatch.setattr(bm, "_stored", lambda name: GATE if name == bm.COMPETENCE else None)


def test_rows_follow_the_gate_and_the_mixture_rows_run_on_fewer_seeds(gate):
    lesson = budget.get("lesson")
    table = modes.rows()
    assert "dril" in table and table["dril"].stage == 3
    assert not any(r.startswith("gail") for r in table)
    grid = [c for c in modes.cells_at(lesson) if c.learner != "expert"]
    for task in modes.TASKS:
        n = {r: sum(c.task == task and c.row == r for c in grid) for r in table}
        assert n["dc"] == n["dc-lib"] == n["bc-lib"] == lesson.modes_seeds
        assert n["bc-mix"] == n["dc-mix"] == lesson.table1_mixture_seeds
    dc = next(c for c in grid if c.row == "dc" and c.task == "reacher2")
    assert dc.config["steps"] == lesson.benchmark_steps_for("reacher2")
    assert dc.config["dc"]["start_log_std"] == -2.0
    coin = {c.config["demo_variant"] for c in grid if c.row.endswith("coin")}
    assert coin == {"coin"}
    # a mixture BC runs just before the DC that starts from it (one worker reuses it)
    order = [(c.seed, c.task, c.row) for c in grid if c.stage == 4]
    for s, t, r in order:
        if r == "dc-mix":
            assert order.index((s, t, "bc-mix")) < order.index((s, t, "dc-mix"))
    experts = [c for c in modes.cells_at(lesson) if c.learner == "expert"]
    assert len(experts) == len(modes.TASKS) * lesson.modes_seeds


def test_a_variant_that_failed_the_gate_loses_its_rows_and_the_aggregate_says_why(monkeypatch):
    """dc-mix failed: its rows (dc-mix, dc-mix-coin) leave the grid, the mixture BC rows and
    DC's own stay, and ``failed_variants`` gives the reason the aggregate records.  Undecided
    (None), the rows stay: the gate may still pass it."""
    lesson = budget.get("lesson")
    for passed, gone in ((False, True), (None, False), (True, False)):
        g = {"gate": {**GATE["gate"], "dc-mix": {"passed": passed, "reason": "keep on x"}}}
        monkeypatch.setattr(bm, "_stored", lambda name: g if name == bm.COMPETENCE else None)
        table = modes.rows()
        assert ("dc-mix" not in table and "dc-mix-coin" not in table) is gone
        assert {"dc", "dc-coin", "bc-mix", "bc-mix-coin", "bc-full-coin"} <= set(table)
        assert not gone or not any(c.row.startswith("dc-mix") for c in modes.cells_at(lesson))
        assert modes.failed_variants() == (
            {"dc-mix": "failed the competence gate: keep on x"} if gone else {})


def test_the_mixture_trains_longer_until_it_matches_plain_bc(monkeypatch):
    lesson = budget.get("lesson")
    trained = []

    class Fake:
        def __init__(self, epochs, mixture):
            self.policy = (epochs, mixture)

    match = modes._match   # the rule both mixture-start studies apply
    monkeypatch.setattr(match._bc, "train",
                        lambda task, demos, cfg, progress: trained.append(cfg.epochs) or
                        Fake(cfg.epochs, cfg.policy == "mixture"))
    monkeypatch.setattr(match.protocol, "check_disjoint", lambda *a: None)
    scores = {(200, False): 0.9, (200, True): 0.5, (400, True): 0.86, (800, True): 0.95}
    monkeypatch.setattr(match, "_match_score", lambda task, p: scores[p])
    policy, rec = modes.matched_mixture("reacher2", None, 0, lesson)
    assert policy == (400, True) and rec["matched"] and rec["target"] == 0.9
    assert [t["epochs"] for t in rec["tries"]] == [200, 400]     # stopped at the first match
    scores[(400, True)] = 0.7
    scores[(800, True)] = 0.7
    policy, rec = modes.matched_mixture("reacher2", None, 0, lesson)
    assert policy == (800, True) and not rec["matched"] and len(rec["tries"]) == 3


def test_a_mixture_dc_cell_starts_from_the_matched_mixture(gate, monkeypatch):
    from dc_lesson import evaluation
    real = evaluation.evaluate_both
    monkeypatch.setattr(modes._t1._evaluation, "evaluate_both",
                        lambda task, policy, reference, **kw: real(task, policy, None, **{
                            **kw, "keep_features": True, "divergences": False}))
    monkeypatch.setattr(modes._common, "reference", lambda needs: None)
    smoke = budget.get("smoke")
    grid = [c for c in modes.cells_at(smoke) if c.task == "reacher2" and c.seed == 0]
    bc_mix = next(c for c in grid if c.row == "bc-mix")
    dc_mix = next(c for c in grid if c.row == "dc-mix")
    a, _ = modes.run_cell(bc_mix, ())
    b, _ = modes.run_cell(dc_mix, ())
    assert a["match"] == b["match"] and a["match"]["tries"]
    assert "start" not in b and b["curve"]
    for out in (a, b):   # the mixture's third evaluation: a drawn component, its mean action
        assert set(out["final"]) == set(modes.EVALUATIONS)
        assert "mode_shares" in out["final"]["components"]


def test_an_unmatched_mixture_is_shown_and_paired_with_nothing():
    def rec(row, variant, matched, value):
        return {"cell": {"learner": row, "variant": variant, "task": "reacher2", "seed": 0,
                         "n_demos": 18},
                "config": {"demo_variant": None},
                "result": {"final": {"mean": {"scaled_return": value}},
                           **({"match": {"matched": matched}} if variant == "mix" else {})}}
    obs = modes.observations([rec("bc", "mix", False, 0.3), rec("dc", "mix", False, 0.4),
                              rec("bc", "full", None, 0.9)], "mean")
    assert [o["row"] for o in obs] == ["bc-mix (unmatched)", "dc-mix (unmatched)", "bc-full"]
    matched = modes.observations([rec("dc", "mix", True, 0.4)], "mean")
    assert matched[0]["row"] == "dc-mix" and matched[0]["matched"]


def test_the_components_evaluation_reads_a_gaussians_mean_and_refuses_an_old_mixture_cell():
    """Under ``"components"`` a Gaussian row is its mean action (one component); a mixture
    cell stored without that evaluation is an error naming the fix, never its mean action
    passed off as the drawn components."""
    def rec(learner, variant, final, match=None):
        return {"cell": {"learner": learner, "variant": variant, "task": "reacher2",
                         "seed": 0, "n_demos": 18, "study": "modes"},
                "config": {"demo_variant": None},
                "result": {"final": final, **({"match": match} if match else {})}}
    gauss = rec("bc", "full", {"mean": {"scaled_return": 0.9}, "sampled": {"scaled_return": 0.5}})
    mix = rec("bc", "mix", {"mean": {"scaled_return": 0.8}, "sampled": {"scaled_return": 0.1},
                            "components": {"scaled_return": 0.6}}, {"matched": True})
    got = {o["row"]: o["scaled_return"] for o in modes.observations([gauss, mix], "components")}
    assert got == {"bc-full": 0.9, "bc-mix": 0.6}
    old = rec("dc", "mix", {"mean": {"scaled_return": 0.8}, "sampled": {"scaled_return": 0.1}},
              {"matched": True})
    with pytest.raises(cells.CellError, match="delete it and run the sweep again"):
        modes.observations([old], "components")
