"""The rules that turn the stored verdicts into chapter 06's closing answers
(:mod:`dc_lesson.experiments.findings`), on constructed verdicts."""

from dc_lesson.experiments import claims as C, findings as F
from dc_lesson.experiments import verdicts as V


def _v(claim, *words):
    entries = tuple(V.Entry(("hopper", i), w, 0.1, 0.0, 0.2, 5, 0.01, 0.05)
                    for i, w in enumerate(words))
    return V.Verdict(claim.name, claim.source, claim.rule, V.count(
        [(e.key, e.word) for e in entries]), "", "", entries)


def test_a_claim_is_one_word_when_its_judged_tasks_agree_and_mixed_when_they_differ():
    assert F.word_of(_v(C.DC_BEATS_BC, "reproduced", "reproduced")) == V.REPRODUCED
    assert F.word_of(_v(C.DC_BEATS_BC, "reproduced", "not judged: start at the ceiling")
                     ) == V.REPRODUCED                    # not-judged members are apart
    assert F.word_of(_v(C.DC_BEATS_BC, "reproduced", "inconclusive")) == F.MIXED
    assert F.word_of(_v(C.DC_BEATS_BC, "not judged: fewer than 5 seeds")) == V.NOT_JUDGED
    gated = V.Verdict("x", "s", "r", "not judged: gail failed the competence gate", "")
    assert F.word_of(gated) == V.NOT_JUDGED               # no members: the verdict's word


def test_the_lead_counts_the_claims_by_word_and_names_a_missing_claim():
    q = F.QUESTIONS[0]
    vs = [_v(q.claims[0], "reproduced"), _v(q.claims[1], "equal within 0.05"),
          _v(q.claims[2], "contradicted", "inconclusive")]      # the fourth never ran
    got = F.answer(q, vs)
    assert got["lead"] == (f"Of its {len(q.claims)} claims: 1 reproduced, 1 equal within, "
                           f"1 {F.MIXED}, 1 not run yet.")
    assert got["words"][q.claims[3].name] == "not run yet"
    assert len(got["lines"]) == len(q.claims)
    assert "**reproduced**" in got["lines"][0]


def test_an_answer_on_an_unfinished_grid_says_it_is_provisional():
    q = F.QUESTIONS[1]
    done = {"ablations": {"complete": True, "cells": {"n": 56, "of": 56}}}
    assert "Provisional" not in F.answer(q, [], done)["lead"]
    late = {**done, "benchmark": {"complete": False, "cells": {"n": 12, "of": 216}},
            "modes": None}
    lead = F.answer(q, [], late)["lead"]
    assert "Provisional" in lead and "benchmark (12 of 216 cells)" in lead
    assert "modes (not aggregated yet)" in lead


def test_every_question_asks_claims_the_book_declares():
    declared = {c.name for c in C.CLAIMS}
    assert [q.key for q in F.QUESTIONS] == ["performance", "stability", "modes"]
    for q in F.QUESTIONS:
        assert q.claims and {c.name for c in q.claims} <= declared


def test_the_lead_says_why_claims_were_not_judged_and_when_a_word_rests_on_part_of_a_claim():
    q = F.QUESTIONS[0]
    gate = V.Verdict(q.claims[3].name, "s", "r", "not judged: gail failed the competence "
                     "gate — keep on cartpole", "")
    vs = [_v(q.claims[0], "reproduced", "not judged: fewer than 5 paired seeds"),
          _v(q.claims[1], "not judged: fewer than 5 paired seeds"),
          _v(q.claims[2], "not judged: start at the ceiling"), gate]
    lead = F.answer(q, vs)["lead"]
    assert lead.startswith(f"Of its {len(q.claims)} claims: 1 reproduced, 3 not judged (")
    assert "too few paired seeds yet: 1" in lead and "a start at the ceiling or floor: 1" in lead
    assert "a learner compared failed the competence gate: 1" in lead
    assert "1 of the judged claims rests on part of its (task, count) pairs" in lead
    assert F.why_not(V.Verdict("x", "s", "r", "not judged: something new", "")) == ["other"]


def test_a_claim_judged_across_tasks_shows_that_word_too():
    v = _v(C.DC_BEATS_BC, "not judged: fewer than 5 paired seeds")
    across = V.Entry("across tasks", "reproduced", 0.1, 0.05, 0.2, 6, 0.01, 0.05)
    v = V.Verdict(v.claim, v.source, v.rule, v.verdict, "", "", v.per_task, across)
    got = F.answer(F.QUESTIONS[0], [v])
    assert got["lines"][0].endswith("Across tasks: reproduced.")
    # the lead counts task by task, then the across-task words apart: neither stands in
    mixed = _v(C.COMPARABLE_BC, "reproduced", "inconclusive")
    mixed = V.Verdict(mixed.claim, mixed.source, mixed.rule, mixed.verdict, "", "",
                      mixed.per_task, across)
    lead = F.answer(F.QUESTIONS[0], [v, mixed])["lead"]
    assert f"task by task: 1 {F.MIXED}, 1 not judged" in lead
    assert lead.endswith("Across tasks, the 2 claims judged that way: 2 reproduced.")
