"""What this book found about DC: the paper's three claims, answered from the stored verdicts.

The paper's contributions (its Sec. I) are three: DC *performs* comparably or better than the
imitation-learning baselines, its ADMM-based training is *stable* (more loops help, the
update converges, it works in a wide range of learning rates) and it *keeps the expert's
modes* where adversarial imitation collapses.  Each is a :class:`Question` here with the
claims of :mod:`claims` that test it; :func:`answer` renders one question's answer from the
verdicts of those claims, by fixed rules and no word of its own:

* each claim is one sentence: its name, the rule's word (as :func:`verdicts.count` put it:
  per task, or per task and count) and the grid it rests on;
* the question's lead sentence counts the claims by their word task by task: how many
  reproduced, how many contradicted, how many came out equal within the bound,
  inconclusive, with different words on different tasks (:data:`MIXED`), or not judged,
  and why (:func:`why_not`: a learner that failed the competence gate, a grid run before
  the gate, too few paired seeds yet, a start at the ceiling or floor); a word that rests
  on part of its claim's (task, count) pairs says on how many;
* then, for the claims judged across tasks too (``Verdict.across``: the across-task IQM,
  issue 41's headline), it counts their across-task words; each such claim's line shows
  that word beside its own.  Both counts are given because they answer different
  questions: "at every count" is the task-by-task one, "on the benchmark as a whole" the
  across-task one, and neither stands in for the other;
* a grid still accumulating is named as such in the lead, so a reader sees when an answer
  is provisional (:func:`provisional`).

A question is never given one word of its own ("partly", "mostly"): the answer is its
claims' words, counted.  ``tests/test_findings.py`` checks the rules on constructed verdicts.
"""

from __future__ import annotations

import dataclasses

from dc_lesson.experiments import claims as C
from dc_lesson.experiments import verdicts as V

MIXED = "with different words on different tasks"   # its tasks (or counts) disagree


@dataclasses.dataclass(frozen=True)
class Question:
    key: str
    question: str
    claims: tuple       # of claims.Claim, in the order the answer lists them


QUESTIONS = (
    Question("performance", "Does DC perform as well as or better than the baselines?",
             (C.DC_BEATS_BC, C.COMPARABLE_BC, C.DC_BEATS_DRIL_FEW, C.COMPARABLE)),
    Question("stability", "Is DC's training stable, and does its update converge?",
             (C.LOOPS, C.LONG_LOOP, C.EQUAL_BUDGET, C.LR_WIDE, C.CONVERGES, C.DC_STABLE_DRIL,
              C.STABLE, C.DC_STABLE)),
    Question("modes", "Does DC keep the expert's modes where GAIL collapses?",
             (C.DC_KEEPS_MODES, C.GAIL_COLLAPSES, C.DRIL_COLLAPSES, C.LOWEST_DIVERGENCE,
              C.DC_BELOW_DRIL, C.HIGHER_RETURN)),
)


def word_of(v: V.Verdict) -> str:
    """A claim's one word: the rule's word when every judged task agrees (or the claim has
    one member), :data:`MIXED` when they differ, not judged when no member was judged."""
    members = [V.kind(e.word) for e in v.per_task]
    judged = [w for w in members if w != V.NOT_JUDGED]
    if not members:
        return V.kind(v.verdict)
    if not judged:
        return V.NOT_JUDGED
    return judged[0] if len(set(judged)) == 1 else MIXED


# why a claim was not judged, by the words of its reason (verdicts' reasons), in this order
WHY_NOT = (("before the gate", "its grid ran before the competence gate"),
           ("failed the competence gate", "a learner compared failed the competence gate"),
           ("paired seeds", "too few paired seeds yet"),
           ("start at the", "a start at the ceiling or floor"))


def why_not(v: V.Verdict) -> list[str]:
    """The kinds of reason (:data:`WHY_NOT`) a claim's not-judged members give, in order;
    ``["other"]`` for a reason none names."""
    texts = [e.word for e in v.per_task if V.kind(e.word) == V.NOT_JUDGED] or [v.verdict]
    found = [label for key, label in WHY_NOT if any(key in t for t in texts)]
    return found or ["other"]


def coverage(v: V.Verdict) -> tuple[int, int]:
    """(judged members, all members) of a claim's family."""
    return (sum(V.kind(e.word) != V.NOT_JUDGED for e in v.per_task), len(v.per_task))


def provisional(sources: dict) -> list[str]:
    """The grids still accumulating: ``sources`` maps a grid's name to its aggregate (or
    ``None`` when it has not been made), each with ``complete`` and ``cells``."""
    out = []
    for name, rec in sources.items():
        if rec is None:
            out.append(f"{name} (not aggregated yet)")
        elif not rec.get("complete"):
            c = rec.get("cells") or {}
            out.append(f"{name} ({c.get('n', '?')} of {c.get('of', '?')} cells)")
    return out


def answer(q: Question, verdicts: list, sources: dict | None = None) -> dict:
    """``{"question", "lead", "lines", "words"}``: :attr:`Question.question`, the lead
    sentence (module docstring), one Markdown line per claim of ``q`` found in
    ``verdicts`` (a claim not found says "not run yet"), and ``{claim: word}``."""
    by = {v.claim: v for v in verdicts}
    words, lines, why, part, across = {}, [], {}, 0, []
    for c in q.claims:
        v = by.get(c.name)
        if v is None:
            words[c.name] = "not run yet"
            lines.append(f"* {c.name} ({c.source}): not run yet.")
            continue
        words[c.name] = word_of(v)
        judged, members = coverage(v)
        if words[c.name] == V.NOT_JUDGED:
            for reason in why_not(v):
                why[reason] = why.get(reason, 0) + 1
        elif judged < members:
            part += 1
        whole = (V.kind(v.across.word) if v.across is not None
                 and V.kind(v.across.word) != V.NOT_JUDGED else None)
        if whole:
            across.append(whole)
        lines.append(f"* {c.name} ({c.source}): **{v.verdict}**."
                     + (f" Across tasks: {whole}." if whole else ""))
    order = (V.REPRODUCED, V.CONTRADICTED, V.EQUAL, V.INCONCLUSIVE, MIXED, V.NOT_JUDGED,
             "not run yet")
    said = [f"{sum(w == k for w in words.values())} {k}" for k in order
            if any(w == k for w in words.values())]
    lead = (f"Of its {len(q.claims)} claims" + (", task by task" if across else "") + ": "
            + ", ".join(said))
    if why:
        lead += " (" + "; ".join(f"{r}: {k}" for r, k in why.items()) + ")"
    lead += "."
    if part:
        lead += (f" {part} of the judged claims {'rests' if part == 1 else 'rest'} on part "
                 f"of {'its' if part == 1 else 'their'} (task, count) pairs; the lines name "
                 f"the pairs not judged.")
    if across:
        counted = [f"{sum(w == k for w in across)} {k}" for k in order if k in across]
        lead += (f" Across tasks, the {len(across)} "
                 f"{'claim' if len(across) == 1 else 'claims'} judged that way: "
                 + ", ".join(counted) + ".")
    late = provisional(sources or {})
    if late:
        lead += " Provisional: it rests on grids still accumulating, " + "; ".join(late) + "."
    return {"question": q.question, "lead": lead, "lines": lines, "words": words}


__all__ = ["MIXED", "QUESTIONS", "Question", "WHY_NOT", "answer", "coverage", "provisional",
           "why_not", "word_of"]
