"""Chapter 06's readers of the single-mode benchmark: the rules, on constructed records."""

import numpy as np
import pytest

from dc_lesson.experiments import table_three as t3


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
           "observations": [{"task": "ant", "row": "gail", "seed": s,
                             "curve": [{"steps": 10, "scaled_return": 0.1 * s},
                                       {"steps": 20, "scaled_return": 0.2 * s}]}
                            for s in range(3)]}
    n, mean, lo, hi = t3.figure9(rec, "ant")["dc"]
    assert n.tolist() == [4, 11, 25] and mean.tolist() == [4 / 25, 11 / 25, 1.0]
    curves = t3.figure11(rec, "ant")["gail"]
    assert len(curves) == 3 and curves[2] == [(10, 0.2), (20, 0.4)]
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


def test_verdicts_give_each_answer_and_judge_dril_at_the_fewest_demonstrations_only():
    better = t3.verdicts(_obs(0.2))
    assert {v["verdict"] for v in better if v["claim"] == t3.DC_BEATS_BC.name} == \
        {"reproduced (all 2 tasks)"}
    assert [v["n_demos"] for v in better if v["claim"] == t3.DC_BEATS_DRIL_FEW.name] == [4]
    assert {v["verdict"] for v in better if v["claim"] == t3.GPRIL_LOWEST.name} == \
        {"reproduced (all 2 tasks)"}
    worse = t3.verdicts(_obs(-0.2))
    assert {v["verdict"] for v in worse if v["claim"] == t3.DC_BEATS_BC.name} == \
        {"contradicted (all 2 tasks)"}
    null = t3.verdicts(_obs(0.0, noise=0.05))
    assert {v["verdict"] for v in null if v["claim"] == t3.DC_BEATS_BC.name} == \
        {"inconclusive (all 2 tasks)"}
    assert {v["verdict"] for v in worse if v["claim"] == t3.GPRIL_LOWEST.name} == \
        {"contradicted (all 2 tasks)"}
    few = t3.verdicts(_obs(0.2, n_seeds=3))
    assert {v["claim"] for v in few} >= {t3.DC_BEATS_BC.name, t3.GPRIL_LOWEST.name,
                                         t3.COMPARABLE}
    assert all(v["verdict"].startswith("inconclusive") for v in few), "too few seeds"


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


def _verdict(vs, claim, n=None):
    return {v["verdict"] for v in vs if v["claim"] == claim and (n is None or v["n_demos"] == n)}


def test_comparability_is_non_inferiority_with_a_declared_margin():
    assert _verdict(t3.verdicts(_single(0.0, 0.01, 0.2)), t3.COMPARABLE) == \
        {"reproduced (all 2 tasks)"}
    # better than GAIL is "comparable or better": reproduced, not contradicted
    assert _verdict(t3.verdicts(_single(0.3, 0.01, 0.2)), t3.COMPARABLE) == \
        {"reproduced (all 2 tasks)"}
    assert _verdict(t3.verdicts(_single(-0.3, 0.01, 0.2)), t3.COMPARABLE) == \
        {"contradicted (all 2 tasks)"}
    # a mean beyond the margin whose interval straddles it decides nothing, nor does a
    # mean inside it with a wide interval
    assert _verdict(t3.verdicts(_single(-0.12, 0.05, 0.2)), t3.COMPARABLE) == \
        {"inconclusive (all 2 tasks)"}
    assert _verdict(t3.verdicts(_single(0.0, 0.2, 0.2)), t3.COMPARABLE) == \
        {"inconclusive (all 2 tasks)"}
    assert _verdict(t3.verdicts(_single(0.0, 0.01, 0.2, n_seeds=4)), t3.COMPARABLE) == \
        {"inconclusive; not judged on ant, hopper (fewer than 5 paired seeds)"}
    # one seed has no interval: the evidence says so, never "[nan, nan]"
    one = [v for v in t3.verdicts(_single(0.0, 0.01, 0.2, n_seeds=1)) if v["claim"] ==
           t3.COMPARABLE]
    assert one and all("(no interval)" in v["evidence"] and "nan" not in v["evidence"]
                       and "fewer than" in v["evidence"] for v in one)


def test_bc_growth_compares_the_fewest_with_the_most_demonstrations_and_curves_are_judged():
    grows = t3.verdicts(_single(0.1, 0.01, 0.2))
    assert _verdict(grows, t3.BC_IMPROVES.name) == {"reproduced (all 2 tasks)"}
    assert [v["n_demos"] for v in grows if v["claim"] == t3.BC_IMPROVES.name] == ["4 -> 25"]
    assert _verdict(t3.verdicts(_single(0.1, 0.01, -0.2)), t3.BC_IMPROVES.name) == \
        {"contradicted (all 2 tasks)"}
    assert _verdict(grows, t3.DC_FASTER.name, 4) == {"reproduced (all 2 tasks)"}
    assert _verdict(t3.verdicts(_single(-0.1, 0.01, 0.2)), t3.DC_FASTER.name, 4) == \
        {"contradicted (all 2 tasks)"}
    assert t3.verdicts({"observations": []}) == []


def test_the_lesson_grid_has_seeds_enough_for_a_verdict():
    from dc_lesson import budget
    from dc_lesson.experiments import claims
    for name in ("lesson", "paper"):
        assert budget.get(name).table3_seeds >= claims.MIN_SEEDS, name


def test_dc_against_its_start_is_judged_for_non_inferiority_too():
    # _single: bc = 0.4 (+0.01 s), dc = gail + shift = 0.6 + shift: dc - bc = 0.2 + shift
    keeps = t3.verdicts(_single(-0.25, 0.01, 0.0))       # dc - bc = -0.05: within the margin
    assert _verdict(keeps, t3.COMPARABLE_BC) == {"reproduced (all 2 tasks)"}
    assert _verdict(keeps, t3.DC_BEATS_BC.name) == {"contradicted (all 2 tasks)"}
    loses = t3.verdicts(_single(-0.5, 0.01, 0.0))        # dc - bc = -0.3: beyond it
    assert _verdict(loses, t3.COMPARABLE_BC) == {"contradicted (all 2 tasks)"}
    assert all("dc - bc" in v["evidence"] and "(dc - bc)" in v["rule"]
               for v in loses if v["claim"] == t3.COMPARABLE_BC)


def test_stability_compares_the_spread_of_the_second_half_of_each_curve():
    def rec(dc_wobble, gail_wobble, dc_early=0.5, n_seeds=6):
        out = []
        for s in range(n_seeds):
            for row, wob, early in (("dc", dc_wobble, dc_early), ("gail", gail_wobble, 0.5)):
                # four checkpoints; only the last two (the second half) count
                vals = [early, 0.5, 0.6 + wob * (1 + 0.1 * s), 0.6 - wob]
                out.append({"task": "hopper", "n_demos": 4, "row": row, "seed": s,
                            "scaled_return": 0.6, "curve": [
                                {"steps": 10 * (i + 1), "scaled_return": v}
                                for i, v in enumerate(vals)]})
        return {"observations": out}
    assert _verdict(t3.verdicts(rec(0.01, 0.2)), t3.DC_STABLE.name) == {"reproduced"}
    assert _verdict(t3.verdicts(rec(0.2, 0.01)), t3.DC_STABLE.name) == {"contradicted"}
    # a jump in the first half is learning, not instability: equal late spreads decide nothing
    assert _verdict(t3.verdicts(rec(0.05, 0.05, dc_early=-0.9)), t3.DC_STABLE.name) == \
        {"inconclusive"}


def test_curves_are_compared_on_the_checkpoints_every_learner_reached():
    # GAIL's whole batches stop short of the last mark: DC's curve is cut there too, so a late
    # wobble only DC's extra checkpoint shows cannot decide stability or speed.
    out = []
    for s in range(6):
        dc = [0.5, 0.6, 0.6 + 0.01 * s, 0.6, -0.9 + 0.1 * s]       # its 5th point: a collapse
        gail = [0.5, 0.6, 0.6 + 0.01 * s, 0.6]
        for row, vals, marks in (("dc", dc, (20, 40, 60, 80, 100)), ("gail", gail,
                                                                      (20.5, 41, 61.5, 82))):
            out.append({"task": "hopper", "n_demos": 4, "row": row, "seed": s,
                        "scaled_return": 0.6, "curve": [{"steps": m, "scaled_return": v}
                                                        for m, v in zip(marks, vals)]})
    vs = t3.verdicts({"observations": out})
    assert _verdict(vs, t3.DC_STABLE.name) == {"inconclusive"}
    assert _verdict(vs, t3.DC_FASTER.name) == {"inconclusive"}
    assert [p["steps"] for p in t3._common_curves(out)[0]["curve"]] == [20, 40, 60, 80]


def test_the_papers_returns_are_scaled_by_its_own_table_two():
    # every task of its Table III has its expert and random returns, the expert above random
    assert set(t3.PAPER_TABLE_III) <= set(t3.PAPER_TABLE_II)
    for task, ((expert, _), (random, _)) in t3.PAPER_TABLE_II.items():
        assert expert > random, task
        assert t3.paper_scaled(task, expert) == 1 and t3.paper_scaled(task, random) == 0
    # Reacher's returns are negative: scaling keeps "less negative is better"
    assert 0 < t3.paper_scaled("reacher1", -9.63) < t3.paper_scaled("reacher1", -5.82) < 1
    rows = t3.paper_rows()
    hop = {r["row"]: r["paper_scaled"] for r in rows if (r["task"], r["n_demos"]) == ("hopper", 4)}
    assert hop["gpril"] < 0.01 < hop["bc"] < hop["dc"] < 1
