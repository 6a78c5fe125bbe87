"""Chapter 06's answer in words, rendered from :func:`table_three.verdicts` by fixed rules.

Every word is :mod:`verdicts`' (*reproduced*, *contradicted*, *equal within 0.05*,
*inconclusive*, *not judged: reason*); this module only groups them.  Where the common BC
start already earns the expert's return (within ``verdicts.LEVEL_GAP`` of 1: the first
grid's cartpole and hopper) "DC outperforms BC" cannot be shown, so that comparison is *not judged: start at
the ceiling*, and what is left to ask there is whether DC keeps the start's return
(``claims.COMPARABLE_BC``: *equal within 0.05*); where the start sits at random's level, no
learner has anything to start from (*not judged: start at the floor*).

* :func:`summary` : one row per (claim, task, count): the word and, beside it, the reason
  or the bound;
* :func:`lines`: one Markdown line per claim, its pairs grouped by word;
* :func:`conclusion`: the chapter's question ("does DC add to its start and match the
  baselines on one-mode tasks?") in one paragraph.

``tests/test_table_three_words.py`` checks each rule on constructed aggregates.
"""

from __future__ import annotations

from dc_lesson.experiments import claims, table_three
from dc_lesson.experiments import verdicts as V

CEILING, FLOOR = V.CEILING, V.FLOOR


def start_levels(rec: dict) -> dict:
    """``{(task, n_demos): CEILING | FLOOR | None}`` from the BC row's mean scaled return."""
    return {(r["task"], r["n_demos"]): V.start_gate(r["scaled_return_mean"])
            for r in rec["table"] if r["row"] == "bc" and r.get("scaled_return_mean")
            is not None}


def _span(pairs: list) -> str:
    """``[(task, n)]`` as ``cartpole (4, 11), hopper (4)``: tasks in order, counts after."""
    by: dict = {}
    for t, n in pairs:
        by.setdefault(t, []).append(str(n))
    return ", ".join(f"{t} ({', '.join(ns)})" for t, ns in by.items())


def _split(word: str) -> tuple[str, str]:
    """A rendered word as (the vocabulary's word, what stands beside it)."""
    k = V.kind(word)
    if k == V.NOT_JUDGED:
        return k, word.split(": ", 1)[1]
    if k == V.EQUAL:
        return k, f"bound {word[len(V.EQUAL):].strip()}"
    return k, ""


def summary(vs: list) -> list[dict]:
    """One row per (claim, task, count): the word, and beside it the reason it is not judged
    (or the equivalence bound), the difference and the Holm-adjusted p."""
    out = []
    for v in vs:
        for e in v.per_task:
            word, why = _split(e.word)
            task, n = e.key
            out.append({"claim": v.claim, "task": task, "demonstrations": n, "word": word,
                        "reason": why, "difference": (f"{V.fmt_num(e.mean)} "
                                                      f"[{V.fmt_num(e.lo)}, {V.fmt_num(e.hi)}]"
                                                      if e.n >= 2 else ""),
                        "seeds": e.n, "p (Holm)": "" if e.p_holm != e.p_holm
                        else f"{e.p_holm:.3f}"})
        if v.across is not None:   # the claim across tasks: one unit per (task, count)
            e = v.across
            word, why = _split(e.word)
            out.append({"claim": v.claim, "task": "across tasks", "demonstrations": "all",
                        "word": word, "reason": why,
                        "difference": (f"{V.fmt_num(e.mean)} [{V.fmt_num(e.lo)}, "
                                       f"{V.fmt_num(e.hi)}]" if e.n >= 2 else ""),
                        "seeds": f"{e.n} task means", "p (Holm)": ""})
    return out


def claim_line(v) -> str:
    """One Markdown line: the claim's (task, count) pairs grouped by word, each not-judged
    group with its reason; a claim with no pairs gives its verdict's own words (a learner
    the gate held out of the grid: "not judged" with the gate's reason), or "not run yet"."""
    groups: dict = {}
    for e in v.per_task:
        groups.setdefault(e.word, []).append(e.key)
    order = sorted(groups, key=lambda w: (V.WORDS.index(V.kind(w)), w))
    parts = [f"{w} on {_span(groups[w])}" for w in order]
    return f"* **{v.claim}**: " + ("; ".join(parts) or v.verdict or "not run yet") + "."


def lines(rec: dict, vs: list | None = None) -> list[str]:
    """:func:`claim_line` for every claim of :data:`table_three.CLAIMS`, in order."""
    return [claim_line(v) for v in (vs if vs is not None else table_three.verdicts(rec))]


def _words(v) -> dict:
    return {e.key: V.kind(e.word) for e in v.per_task}


def _against_gail(v, gail: dict, room: list, n) -> str:
    """The GAIL half of :func:`conclusion`'s first sentence: the counts where GAIL was
    judged; where it was not run (it failed the competence gate), that reason instead of
    counts of zero that would read as a comparison made."""
    if not any(w != V.NOT_JUDGED for w in gail.values()):
        why = v.verdict.split(": ", 1)[1] if V.kind(v.verdict) == V.NOT_JUDGED and \
            ": " in v.verdict else "no pair judged"
        return f"against GAIL, not judged ({why})."
    return (f"against GAIL, above on {n(gail, room, V.REPRODUCED)}, below on "
            f"{n(gail, room, V.CONTRADICTED)}, equal on {n(gail, room, V.EQUAL)}, undecided "
            f"on {n(gail, room, V.INCONCLUSIVE)}.")


def conclusion(rec: dict, vs: list | None = None) -> str:
    """The chapter's answer in one paragraph, by a fixed rule on the verdicts:

    * where the start left room (DC against BC judged): on how many pairs DC's return is above
      its start's (*reproduced*), below (*contradicted*), equal within the bound, or
      inconclusive; and against GAIL (``claims.COMPARABLE``) on the same pairs;
    * at the ceiling: on how many pairs DC keeps the start's return (*equal within*), loses
      more than the bound (*contradicted*), or cannot be told;
    * at the floor: that no learner has anything to start from;
    * with no pair judged because a learner has not shown competence: that, with the gate's
      reason (chapter 5's study), since the numbers then describe our implementation;
    * with no pair judged otherwise: no answer yet.
    """
    vs = vs if vs is not None else table_three.verdicts(rec)
    by = {v.claim: v for v in vs}
    if claims.DC_BEATS_BC.name not in by:
        return "The benchmark has no paired DC and BC seeds yet, so it cannot answer yet."
    beats, keeps = _words(by[claims.DC_BEATS_BC.name]), _words(by[claims.COMPARABLE_BC.name])
    gail = _words(by[claims.COMPARABLE.name])
    levels = start_levels(rec)
    room = sorted(k for k, w in beats.items() if w != V.NOT_JUDGED)
    ceil = sorted(k for k in keeps if levels.get(k) == CEILING and keeps[k] != V.NOT_JUDGED)
    floor = sorted(k for k in beats if levels.get(k) == FLOOR)
    gated = sorted({e.word.split(": ", 1)[1] for e in by[claims.DC_BEATS_BC.name].per_task
                    if V.kind(e.word) == V.NOT_JUDGED and "competence" in e.word})
    if not room and not ceil and gated:
        return ("No (task, demonstration count) pair is judged: " + "; ".join(gated) +
                ". Until the learners compared have shown competence (chapter 5), the table's "
                "numbers describe our implementations, not the paper's algorithms, and the "
                "benchmark gives no answer.")
    if not room and not ceil:
        return (f"No (task, demonstration count) pair has {V.MIN_SEEDS} paired seeds of DC "
                f"and its start away from the floor yet, so the benchmark cannot answer yet.")
    n = lambda ws, keys, w: sum(ws.get(k) == w for k in keys)
    s = []
    if room:
        s.append(f"Where the BC start leaves room ({len(room)} task-count pairs: "
                 f"{_span(room)}), DC's return is above its start's on "
                 f"{n(beats, room, V.REPRODUCED)}, below on {n(beats, room, V.CONTRADICTED)}, "
                 f"equal within {V.SMALLEST['scaled_return']} on {n(beats, room, V.EQUAL)} and "
                 f"undecided on {n(beats, room, V.INCONCLUSIVE)}; " + _against_gail(
                     by[claims.COMPARABLE.name], gail, room, n))
    else:
        s.append("On no task-count pair with enough seeds does the BC start leave room: it "
                 "is at the expert's return or at random's on every one.")
    if ceil:
        s.append(f"Where the start already earns the expert's return ({_span(ceil)}), there "
                 f"is nothing to add: DC keeps it (equal within "
                 f"{V.SMALLEST['scaled_return']}) on {n(keeps, ceil, V.EQUAL)} of {len(ceil)} "
                 f"pairs, surely loses more on {n(keeps, ceil, V.CONTRADICTED)} and cannot be "
                 f"told on {n(keeps, ceil, V.INCONCLUSIVE)}.")
    if floor:
        s.append(f"Where the start is at the random level ({_span(floor)}), every RL learner "
                 f"starts from nothing it can use: not judged.")
    return " ".join(s)


__all__ = ["CEILING", "FLOOR", "claim_line", "conclusion", "lines", "start_levels", "summary"]
