"""Chapter 06's rendered answer: the start-level flags, the per-claim lines and the one-paragraph
conclusion, each rule on constructed aggregates (a wrong threshold, a swapped side or a lost
too-few-seeds group changes a sentence asserted here)."""

import numpy as np

from dc_lesson.experiments import table_three as t3, table_three_words as w


def _rec(starts: dict, dc_minus_bc: dict, dc_minus_gail: float = 0.0, n_seeds=6, noise=0.005):
    """``starts``: {(task, n): BC's mean scaled return}; DC = BC + the given shift per pair,
    GAIL = DC - ``dc_minus_gail``; every other learner a little below BC."""
    rng = np.random.default_rng(0)
    obs, table = [], []
    for (task, n), bc in starts.items():
        table.append({"task": task, "n_demos": n, "row": "bc", "scaled_return_mean": bc})
        for seed in range(n_seeds):
            e = rng.normal(0, noise, 3)
            dc = bc + dc_minus_bc.get((task, n), 0.0) + e[0]
            vals = {"bc": bc + e[1], "dc": dc, "gail": dc - dc_minus_gail + e[2]}
            vals.update({r: bc - 0.05 for r in ("dril", "pwil", "ndi", "gpril")})
            obs += [{"task": task, "n_demos": n, "seed": seed, "row": r, "scaled_return": v}
                    for r, v in vals.items()]
    return {"table": table, "observations": obs}


def test_the_start_level_is_flagged_by_the_declared_margin():
    m = t3.MARGIN
    rec = _rec({("a", 4): 1 - m + 0.01, ("b", 4): 1 - m - 0.01, ("c", 4): m - 0.01,
                ("d", 4): -0.3, ("e", 4): m + 0.01}, {})
    assert w.start_levels(rec) == {("a", 4): w.CEILING, ("b", 4): None, ("c", 4): w.RANDOM,
                                   ("d", 4): w.RANDOM, ("e", 4): None}


def test_the_conclusion_separates_room_from_ceiling_and_random():
    starts = {("reacher1", 4): 0.5, ("reacher1", 11): 0.6, ("hopper", 4): 1.0,
              ("hopper", 11): 1.0, ("walker", 4): 0.0}
    shifts = {("reacher1", 4): +0.2, ("reacher1", 11): -0.2, ("hopper", 4): -0.001,
              ("hopper", 11): -0.5}
    s = w.conclusion(_rec(starts, shifts, dc_minus_gail=0.3))
    assert "leaves room (2 task-count pairs: reacher1 (4, 11))" in s
    assert "above its start's on 1, below on 1 and indistinguishable on 0" in s
    assert "against GAIL, above on 2, below on 0" in s
    # at the ceiling a tiny loss is kept within the margin, a large sure one is named
    assert "keeps it within 0.1 on 1 of 2 pairs, loses more than that on hopper (11)." in s
    assert "at the random level (walker (4))" in s


def test_a_loss_the_interval_cannot_size_is_said_as_such():
    # hopper (4): DC loses 0.1 on average with seeds spread wide: the interval straddles -0.1
    starts = {("hopper", 4): 1.0, ("hopper", 11): 1.0}
    s = w.conclusion(_rec(starts, {("hopper", 4): -0.1, ("hopper", 11): -0.5}, noise=0.1))
    assert ("keeps it within 0.1 on 0 of 2 pairs, loses more than that on hopper (11) and "
            "may lose more on hopper (4) (intervals too wide to tell).") in s


def test_no_answer_without_enough_seeds_and_no_room_said_as_such():
    starts = {("hopper", 4): 1.0}
    assert "cannot answer yet" in w.conclusion(_rec(starts, {}, n_seeds=4))
    s = w.conclusion(_rec(starts, {}))
    assert "On no task-count pair" in s and "keeps it within 0.1 on 1 of 1 pairs" in s


def test_a_claim_line_groups_verdicts_flags_levels_and_sets_few_seeds_apart():
    starts = {("reacher1", 4): 0.5, ("hopper", 4): 1.0, ("cartpole", 4): 1.0}
    rec = _rec(starts, {("reacher1", 4): 0.2, ("hopper", 4): -0.2, ("cartpole", 4): 0.0})
    # cartpole with too few seeds: drop its seeds 4 and 5
    rec["observations"] = [o for o in rec["observations"]
                           if not (o["task"] == "cartpole" and o["seed"] >= 4)]
    line = w.claim_line(rec, t3.DC_BEATS_BC.name)
    assert line.startswith(f"* **{t3.DC_BEATS_BC.name}**: reproduced on reacher1 (4); "
                           "contradicted on hopper (4) (the start at the ceiling: hopper (4))")
    assert line.endswith("too few paired seeds (fewer than 5) on cartpole (4).")
    assert len(w.lines(rec)) == len(t3.CLAIMS) + len(t3.NON_INFERIOR)
    assert w.claim_line({"table": [], "observations": []}, "x").endswith("not run yet.")


def test_bc_growth_is_flagged_where_both_counts_sit_at_one_level():
    starts = {("hopper", 4): 0.999, ("hopper", 25): 1.0, ("walker", 4): 0.0,
              ("walker", 25): 0.02, ("reacher1", 4): 0.5, ("reacher1", 25): 0.95}
    rec = _rec(starts, {})
    # BC's own seeds: a small steady rise at every task
    for o in rec["observations"]:
        if o["row"] == "bc":
            o["scaled_return"] = starts[(o["task"], o["n_demos"])] + 0.001 * o["seed"]
    line = w.claim_line(rec, t3.BC_IMPROVES.name)
    assert "(the start at the ceiling: hopper (4 -> 25); at the random level: walker " \
           "(4 -> 25))" in line
    # reacher1 rose from room to room: grouped with the others, never flagged
    assert "reacher1 (4 -> 25)" in line and "reacher1" not in line.split("(the start")[1]


def test_a_claims_verdict_counts_only_the_tasks_with_enough_seeds():
    per_task = [("reacher1", "reproduced", 0.1, 0.05, 0.2, 5),
                ("walker", "inconclusive", 0.0, -1, 1, 1)]
    assert t3.judged_count(per_task) == ("reproduced; not judged on walker (fewer than 5 "
                                         "paired seeds)")
    assert t3.judged_count(per_task[1:]).startswith("inconclusive; not judged on walker")
