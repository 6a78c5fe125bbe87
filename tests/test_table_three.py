"""Chapter 06's readers of the single-mode benchmark: the rules, on constructed records."""

import numpy as np
import pytest

from dc_lesson.experiments import table_three as t3

# the rules on constructed records; the stored competence gate's reach: test_competence.py
pytestmark = pytest.mark.usefixtures("judge_every_learner")


def _record(values: dict, task="halfcheetah", n=11):
    rows = [{"task": task, "n_demos": n, "row": r, "n_seeds": 3, "scaled_return_mean": v,
             "scaled_return_lo": v - 0.1, "scaled_return_hi": v + 0.1} for r, v in values.items()]
    return {"table": rows, "observations": []}


def test_the_paper_table_has_one_entry_per_column_and_bc_grows_with_demonstrations():
    for task, by_n in t3.PAPER_TABLE_III.items():
        for n, cols in by_n.items():
            assert len(cols) == len(t3.PAPER_COLUMNS), (task, n)
            assert all(s >= 0 for _, s in cols)
    # the reading of the lost header rests on these two statements of the text
    gpril, lowest = t3.PAPER_COLUMNS.index("gpril"), []
    for task, by_n in t3.PAPER_TABLE_III.items():
        bc = [by_n[n][0][0] for n in sorted(by_n)]
        # BC grows on every locomotion task; the paper's Reacher row falls from 18 to 25
        assert (bc[-1] > bc[0]) == (task != "reacher1"), task
        lowest += [(task, n) for n, cols in by_n.items()
                   if cols[gpril][0] != min(m for m, _ in cols)]
    assert sorted(lowest) == [("halfcheetah", 4), ("walker", 4)], "DRIL is lower there"
    for task, n, learner in t3.UNCERTAIN:
        assert n in t3.PAPER_TABLE_III[task] and learner in t3.PAPER_COLUMNS
    assert {r["uncertain"] for r in t3.paper_rows()} == {True, False}
    assert sorted(t3.PAPER_COLUMNS) == sorted(t3.LEARNERS)


def test_kendall_tau_matches_scipy_and_refuses_bad_input():
    scipy_stats = pytest.importorskip("scipy.stats")
    rng = np.random.default_rng(0)
    for _ in range(20):
        x, y = rng.normal(size=6), rng.normal(size=6)
        assert t3.kendall_tau(x, y) == pytest.approx(scipy_stats.kendalltau(x, y).statistic)
    with pytest.raises(ValueError, match="one length"):
        t3.kendall_tau([1, 2, 3], [1, 2])


def test_rank_agreement_reads_orderings_not_scales():
    paper = dict(zip(t3.PAPER_COLUMNS, (m for m, _ in t3.PAPER_TABLE_III["halfcheetah"][11])))
    same = _record({k: v / 10_000 for k, v in paper.items()})      # another scale, same order
    flipped = _record({k: -v for k, v in paper.items()})
    assert t3.rank_agreement(same, "halfcheetah", 11)["tau"] == pytest.approx(1.0)
    assert t3.rank_agreement(flipped, "halfcheetah", 11)["tau"] == pytest.approx(-1.0)
    r = t3.rank_agreement(same, "halfcheetah", 11)
    assert r["paper_best"] == r["our_best"] == max(paper, key=paper.get)
    # too few shared learners, or a count the paper does not have: no verdict
    assert t3.rank_agreement(_record({"bc": 1, "dc": 2}), "halfcheetah", 11)["tau"] is None
    assert t3.rank_agreement(same, "halfcheetah", 7)["tau"] is None


def test_figure_readers_group_sort_and_keep_seeds():
    rec = {"table": [{"task": "ant", "n_demos": n, "row": "dc", "n_seeds": 2,
                      "scaled_return_mean": n / 25, "scaled_return_lo": 0, "scaled_return_hi": 1}
                     for n in (25, 4, 11)],
           "observations": [{"task": "ant", "n_demos": 4, "row": "gail", "seed": s,
                             "curve": [{"steps": 10, "scaled_return": 0.1 * s},
                                       {"steps": 20, "scaled_return": 0.2 * s}]}
                            for s in range(3)]}
    n, mean, lo, hi = t3.figure9(rec, "ant")["dc"]
    assert n.tolist() == [4, 11, 25] and mean.tolist() == [4 / 25, 11 / 25, 1.0]
    curves = t3.figure11(rec, "ant")["gail"]
    assert len(curves) == 3 and curves[2] == [(10, 0.2), (20, 0.4)]
    # the fewest count by default, another on request; every curve cut at the checkpoints
    # all of that count's curves reached (a learner one batch short of the last mark)
    rec["observations"] += [{"task": "ant", "n_demos": 11, "row": r, "seed": 0,
                             "curve": [{"steps": k, "scaled_return": 0.5} for k in ks]}
                            for r, ks in (("dc", (10, 20, 30)), ("dril", (10, 20)))]
    assert set(t3.figure11(rec, "ant")) == {"gail"}
    at11 = t3.figure11(rec, "ant", 11)
    assert set(at11) == {"dc", "dril"} and at11["dc"] == [[(10, 0.5), (20, 0.5)]]
    rec1 = {"mean": {"observations": [
        {"task": "reacher4", "row": r, "seed": s, "emd": 0.1 * s, "scaled_return": 0.5}
        for r in ("expert", "dc", "dc-raw") for s in range(4)]}}
    fig = t3.figure8(rec1)["reacher4"]
    assert set(fig) == {"expert", "dc"}, "controls are not learners of Figure 8"
    assert len(fig["dc"][0]) == 4, "one point per seed"


def _obs(diff, n_seeds=6, tasks=("ant", "walker"), counts=(4, 11), noise=0.01, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for task in tasks:
        for n in counts:
            for s in range(n_seeds):
                base = rng.normal(0.5, 0.1)
                for row, v in (("bc", base), ("dril", base), ("gail", base), ("pwil", base),
                               ("ndi", base), ("gpril", base - diff),
                               ("dc", base + diff + noise * (-1) ** s)):
                    out.append({"task": task, "n_demos": n, "row": row, "seed": s,
                                "scaled_return": v})
    return {"observations": out}


def _by(vs):
    return {v.claim: v for v in vs}


def test_verdicts_give_each_answer_and_judge_dril_at_the_fewest_demonstrations_only():
    c = t3._claims
    better = _by(t3.verdicts(_obs(0.2)))
    assert better[c.DC_BEATS_BC.name].verdict == \
        "reproduced (all 4 task-count pairs, Holm over 4)"
    assert {e.key[1] for e in better[c.DC_BEATS_DRIL_FEW.name].per_task} == {4}
    assert better[c.GPRIL_LOWEST.name].verdict.startswith("reproduced (all 4")
    worse = _by(t3.verdicts(_obs(-0.2)))
    assert worse[c.DC_BEATS_BC.name].verdict.startswith("contradicted (all 4")
    assert worse[c.GPRIL_LOWEST.name].verdict.startswith("contradicted (all 4")
    null = _by(t3.verdicts(_obs(0.0, noise=0.05)))
    assert {e.word for e in null[c.DC_BEATS_BC.name].per_task} <= {
        "inconclusive", "equal within 0.05"}
    few = t3.verdicts(_obs(0.2, n_seeds=3))
    assert all(e.word == "not judged: fewer than 5 paired seeds"
               for v in few for e in v.per_task), "too few seeds"


def test_each_task_is_judged_at_its_own_fewest_and_most_demonstrations():
    # the benchmark's counts differ by task (issue 41): cartpole 1 and 25, hopper 11 and 25
    rec = {"observations": _obs(0.2, tasks=("ant",), counts=(1, 25))["observations"]
           + _obs(0.2, tasks=("walker",), counts=(11, 25))["observations"]}
    c = t3._claims
    got = _by(t3.verdicts(rec))
    assert {e.key for e in got[c.DC_BEATS_DRIL_FEW.name].per_task} == {("ant", 1),
                                                                       ("walker", 11)}
    assert {e.key for e in got[c.BC_IMPROVES.name].per_task} == {("ant", "1 -> 25"),
                                                                 ("walker", "11 -> 25")}
    assert len(got[c.DC_BEATS_BC.name].per_task) == 4


def _single(dc_minus_gail, spread, bc_growth, n_seeds=6):
    out = []
    for task in ("ant", "hopper"):
        for n in (4, 25):
            for s in range(n_seeds):
                wobble = spread * (-1) ** s
                bc = 0.4 + (bc_growth if n == 25 else 0.0) + 0.01 * s
                gail = 0.6 + 0.01 * s
                dc = gail + dc_minus_gail + wobble
                for row, v, curve in (("bc", bc, None), ("gail", gail, [gail - 0.2, gail]),
                                      ("dc", dc, [dc - 0.2 + dc_minus_gail, dc])):
                    out.append({"task": task, "n_demos": n, "row": row, "seed": s,
                                "scaled_return": v,
                                "curve": curve and [{"steps": 1, "scaled_return": curve[0]},
                                                    {"steps": 2, "scaled_return": curve[1]}]})
    return {"observations": out}


def _verdict(vs, claim):
    return _by(vs)[claim].verdict


def test_comparability_is_equality_within_the_smallest_effect_or_better():
    c = t3._claims
    assert _verdict(t3.verdicts(_single(0.0, 0.01, 0.2)), c.COMPARABLE.name) == \
        "equal within 0.05 (all 4 task-count pairs, Holm over 4)"
    # better than GAIL is "comparable or better": reproduced, not contradicted
    assert _verdict(t3.verdicts(_single(0.3, 0.01, 0.2)), c.COMPARABLE.name).startswith(
        "reproduced (all 4")
    assert _verdict(t3.verdicts(_single(-0.3, 0.01, 0.2)), c.COMPARABLE.name).startswith(
        "contradicted (all 4")
    # a mean inside the bound with a wide interval decides nothing
    assert _verdict(t3.verdicts(_single(0.0, 0.2, 0.2)), c.COMPARABLE.name).startswith(
        "inconclusive (all 4")
    assert _verdict(t3.verdicts(_single(0.0, 0.01, 0.2, n_seeds=4)), c.COMPARABLE.name) == \
        ("not judged on ant (4), ant (25), hopper (4), hopper (25) (fewer than 5 paired "
         "seeds)")
    # one seed has no interval: the evidence says so, never "[nan, nan]"
    one = _by(t3.verdicts(_single(0.0, 0.01, 0.2, n_seeds=1)))[c.COMPARABLE.name]
    assert "(no interval)" in one.evidence and "nan" not in one.evidence
    assert "over 1 seed ->" in one.evidence and "1 seeds" not in one.evidence


def test_bc_growth_compares_the_fewest_with_the_most_demonstrations_and_curves_are_judged():
    c = t3._claims
    grows = _by(t3.verdicts(_single(0.1, 0.01, 0.2)))
    assert grows[c.BC_IMPROVES.name].verdict.startswith("reproduced (all 2")
    assert [e.key[1] for e in grows[c.BC_IMPROVES.name].per_task] == ["4 -> 25"] * 2
    assert _verdict(t3.verdicts(_single(0.1, 0.01, -0.2)), c.BC_IMPROVES.name).startswith(
        "contradicted (all 2")
    assert grows[c.DC_FASTER.name].verdict.startswith("reproduced (all 2")
    assert _verdict(t3.verdicts(_single(-0.1, 0.01, 0.2)), c.DC_FASTER.name).startswith(
        "contradicted (all 2")
    assert t3.verdicts({"observations": []}) == []


def test_the_lesson_grid_has_seeds_enough_for_a_verdict():
    from dc_lesson import budget
    from dc_lesson.experiments import claims
    for name in ("lesson", "paper"):
        assert budget.get(name).table3_seeds >= claims.MIN_SEEDS, name


def test_dc_against_its_start_is_judged_for_comparability_too():
    c = t3._claims
    # _single: bc = 0.4 (+0.01 s), dc = gail + shift = 0.6 + shift: dc - bc = 0.2 + shift
    keeps = _by(t3.verdicts(_single(-0.2, 0.01, 0.0)))       # dc - bc = 0: equal
    assert keeps[c.COMPARABLE_BC.name].verdict.startswith("equal within 0.05 (all 4")
    assert keeps[c.DC_BEATS_BC.name].verdict.startswith("equal within 0.05 (all 4")
    loses = _by(t3.verdicts(_single(-0.5, 0.01, 0.0)))       # dc - bc = -0.3: beyond it
    assert loses[c.COMPARABLE_BC.name].verdict.startswith("contradicted (all 4")
    assert "dc - bc" in loses[c.COMPARABLE_BC.name].evidence


def test_a_failed_competence_gate_is_not_judged_with_its_reason():
    c = t3._claims
    got = _by(t3.verdicts(_single(0.3, 0.01, 0.2),
                          competence={"gail": "failed the competence gate — lost its start"}))
    assert got[c.COMPARABLE.name].per_task[0].word == \
        "not judged: gail failed the competence gate — lost its start"
    assert got[c.DC_BEATS_BC.name].verdict.startswith("reproduced")


def test_across_tasks_gives_iqm_and_probability_of_improvement():
    rows = t3.across_tasks(_obs(0.2))
    by = {r["learner"]: r for r in rows}
    assert by["dc"]["P(dc > learner)"] == "" and by["bc"]["pairs"] == 4
    assert by["gpril"]["P(dc > learner)"].startswith("1.00")


def test_the_old_new_table_judges_the_first_grid_ungated_and_the_new_under_the_gate():
    old, new = _obs(0.2), _obs(-0.2)
    rows = {r["claim"]: r for r in t3.old_new(old, new, competence={"dc": "failed the gate"})}
    c = t3._claims
    assert rows[c.DC_BEATS_BC.name]["first grid"].startswith("reproduced")
    assert rows[c.DC_BEATS_BC.name]["benchmark with headroom"].startswith("not judged")
    assert all(r["benchmark with headroom"] == "not run yet" for r in t3.old_new(old, None))
