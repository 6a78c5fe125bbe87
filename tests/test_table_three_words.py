"""Chapter 06's rendered answer: the start-level gates, the summary with reasons, the per-claim
lines and the one-paragraph conclusion, each rule on constructed aggregates (a wrong threshold,
a swapped side or a lost not-judged group changes what is asserted here)."""

import numpy as np
import pytest

from dc_lesson.experiments import claims, table_three as t3, table_three_words as w

# the rules on constructed records; the stored competence gate's reach: test_competence.py
pytestmark = pytest.mark.usefixtures("judge_every_learner")


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


def test_the_start_level_is_gated_by_the_declared_gap():
    g = 0.05
    rec = _rec({("a", 4): 1 - g + 0.01, ("b", 4): 1 - g - 0.01, ("c", 4): g - 0.01,
                ("d", 4): -0.3, ("e", 4): g + 0.01}, {})
    assert w.start_levels(rec) == {("a", 4): w.CEILING, ("b", 4): None, ("c", 4): w.FLOOR,
                                   ("d", 4): w.FLOOR, ("e", 4): None}


def test_the_conclusion_separates_room_from_ceiling_and_floor():
    starts = {("reacher1", 4): 0.5, ("reacher1", 11): 0.6, ("hopper", 4): 1.0,
              ("hopper", 11): 1.0, ("walker", 4): 0.0}
    shifts = {("reacher1", 4): +0.2, ("reacher1", 11): -0.2, ("hopper", 4): -0.001,
              ("hopper", 11): -0.5}
    s = w.conclusion(_rec(starts, shifts, dc_minus_gail=0.3))
    assert "leaves room (2 task-count pairs: reacher1 (4, 11))" in s
    assert "above its start's on 1, below on 1, equal within 0.05 on 0" in s
    assert "against GAIL, above on 2, below on 0" in s
    # at the ceiling a tiny loss keeps the start's return, a large sure one is named
    assert "keeps it (equal within 0.05) on 1 of 2 pairs, surely loses more on 1" in s
    assert "at the random level (walker (4))" in s


def test_no_answer_without_enough_seeds():
    assert "cannot answer yet" in w.conclusion(_rec({("hopper", 4): 1.0}, {}, n_seeds=4))
    s = w.conclusion(_rec({("hopper", 4): 1.0}, {}))
    assert "On no task-count pair" in s and "on 1 of 1 pairs" in s


def test_the_summary_puts_the_reason_beside_the_word():
    starts = {("reacher1", 4): 0.5, ("hopper", 4): 1.0, ("cartpole", 4): 0.6}
    rec = _rec(starts, {("reacher1", 4): 0.2, ("hopper", 4): -0.2, ("cartpole", 4): 0.0})
    rec["observations"] = [o for o in rec["observations"]
                           if not (o["task"] == "cartpole" and o["seed"] >= 4)]
    rows = [r for r in w.summary(t3.verdicts(rec)) if r["claim"] == claims.DC_BEATS_BC.name]
    got = {(r["task"], r["word"], r["reason"]) for r in rows}
    assert got == {("reacher1", "reproduced", ""), ("hopper", "not judged",
                                                    "start at the ceiling"),
                   ("cartpole", "not judged", "fewer than 5 paired seeds"),
                   # the claim across tasks: cartpole's four seeds count as one unit there,
                   # hopper's ceiling start none, so two tasks, fewer than the rule needs
                   ("across tasks", "not judged", "fewer than 5 tasks")}
    line = w.claim_line(next(v for v in t3.verdicts(rec) if v.claim ==
                             claims.DC_BEATS_BC.name))
    assert line == (f"* **{claims.DC_BEATS_BC.name}**: reproduced on reacher1 (4); not "
                    "judged: fewer than 5 paired seeds on cartpole (4); not judged: start at "
                    "the ceiling on hopper (4).")
    assert len(w.lines(rec)) == len(t3.CLAIMS) - 1     # one count: no growth to judge


def test_a_benchmark_held_back_by_the_gate_says_why_not_that_seeds_are_missing():
    rec = _rec({("reacher1", 4): 0.5, ("hopper", 4): 0.6}, {("reacher1", 4): 0.2})
    vs = t3.verdicts(rec, competence={"dc": "failed the competence gate — keep on hopper: a "
                                            "checkpoint fell 0.84 below its start"})
    text = w.conclusion(rec, vs)
    assert text.startswith("No (task, demonstration count) pair is judged: dc failed the "
                           "competence gate — keep on hopper")
    assert "paired seeds" not in text and "implementations" in text


def test_a_gail_kept_out_by_the_gate_is_named_with_its_reason_not_counted_as_zeros():
    rec = _rec({("reacher1", 4): 0.5}, {("reacher1", 4): 0.2})
    rec["observations"] = [o for o in rec["observations"] if o["row"] != "gail"]   # not run
    vs = t3.verdicts(rec, competence={"gail": "failed the competence gate — keep on "
                                              "cartpole: a checkpoint fell 0.3 below"})
    s = w.conclusion(rec, vs)
    assert "against GAIL, not judged (gail failed the competence gate" in s
    assert "above on 0, below on 0" not in s.split("against GAIL")[1]


def test_a_partial_benchmark_judges_the_fewest_only_claims_at_its_designed_fewest_count():
    rec = _rec({("reacher1", 25): 0.5}, {("reacher1", 25): 0.2})   # only the most has run
    rec["design"] = [{"task": "reacher1", "counts": [11, 25]}]
    few = {v.claim: v for v in t3.verdicts(rec)}[claims.DC_BEATS_DRIL_FEW.name]
    assert few.per_task == ()                    # nothing at 11 yet: not judged at 25
    del rec["design"]
    few = {v.claim: v for v in t3.verdicts(rec)}[claims.DC_BEATS_DRIL_FEW.name]
    assert [e.key for e in few.per_task] == [("reacher1", 25)]


def test_a_claim_with_no_pairs_says_why_instead_of_not_run_yet():
    """A claim whose learner the gate held out of the grid has no (task, count) pairs: its
    line gives the verdict's own words ("not judged" and the gate's reason), and only a
    claim with no verdict at all reads "not run yet"."""
    from dc_lesson.experiments import verdicts as V
    held = V.Verdict("DC is at least comparable to GAIL", "s", "r",
                     "not judged: gail failed the competence gate — why", "")
    assert w.claim_line(held).endswith("not judged: gail failed the competence gate — why.")
    assert w.claim_line(V.Verdict("x", "s", "r", "", "")).endswith("not run yet.")
