"""The verdict rule every claim of the book is judged by (``claims``, ``ablations``,
``table_three``): a claim declares one measure, one comparison ``a - b`` of rows that share
their seeds, and the paper's sign; its verdict comes from the paired 95% bootstrap interval of
the per-seed differences (:func:`stats.paired_diff`): *reproduced* if it excludes zero on the
paper's side, *contradicted* on the other, *inconclusive* if it includes zero or rests on
fewer than ``MIN_SEEDS`` seeds (``claims``' docstring gives the reason for five).  A claim over
several tasks reports each task and the count, never "partly"."""

from __future__ import annotations

import dataclasses

import numpy as np

from dc_lesson.evaluation import stats

VERDICTS = ("reproduced", "contradicted", "inconclusive")
MIN_SEEDS = 5           # fewer paired seeds than this: inconclusive, whatever the interval
# The margin of every non-inferiority claim ("comparable"): a tenth of the expert's return
# over random's on the scaled axis; declared before any Table III result.
MARGIN = 0.1


@dataclasses.dataclass(frozen=True)
class Claim:
    """A claim and its rule, declared in advance."""
    name: str
    source: str          # where the paper makes it
    measure: str         # the primary measure (per seed)
    a: str               # the comparison a - b (table rows: bc, gail, dc, dc-loops=4, ...)
    b: str
    direction: int       # +1: the paper says a - b > 0; -1: a - b < 0
    reason: str          # why this measure and this comparison
    margin: float | None = None   # set: non-inferiority, "a is not worse than b by margin"

    @property
    def rule(self) -> str:
        if self.margin is not None:
            return (f"{self.measure}: paired 95% interval of ({self.a} - {self.b}) per seed; "
                    f"reproduced if it lies above -{self.margin}, contradicted if wholly below "
                    f"-{self.margin}, inconclusive otherwise (or with fewer than {MIN_SEEDS} "
                    f"seeds)")
        side = "above" if self.direction > 0 else "below"
        return (f"{self.measure}: paired 95% interval of ({self.a} - {self.b}) per seed; "
                f"reproduced if it lies {side} zero, contradicted if on the other side, "
                f"inconclusive if it includes zero")


@dataclasses.dataclass(frozen=True)
class Verdict:
    claim: str
    source: str
    rule: str
    verdict: str          # one of VERDICTS, or a count over tasks
    evidence: str
    reason: str = ""
    per_task: tuple = ()  # (task, verdict, mean, lo, hi, n_seeds) per task


def judge(interval: stats.Interval, direction: int) -> str:
    """The rule: one of :data:`VERDICTS` from a paired interval and the paper's sign."""
    side = interval.excludes_zero()
    if side == 0:
        return "inconclusive"
    return "reproduced" if side == direction else "contradicted"


def non_inferior(interval: stats.Interval, margin: float) -> str:
    """The non-inferiority rule: reproduced if the interval of a - b lies above -margin,
    contradicted if wholly below it, inconclusive if it straddles it (or has no bounds)."""
    if not (np.isfinite(interval.lo) and np.isfinite(interval.hi)):
        return "inconclusive"
    if interval.lo > -margin:
        return "reproduced"
    return "contradicted" if interval.hi < -margin else "inconclusive"


def count(per_task) -> str:
    """``reproduced`` etc. when every task agrees, else "reproduced on k of n tasks, ..."."""
    words = [p[1] for p in per_task]
    if not words:
        return "inconclusive"
    if len(set(words)) == 1:
        return words[0] + (f" (all {len(words)} tasks)" if len(words) > 1 else "")
    return ", ".join(f"{w} on {words.count(w)} of {len(words)} tasks" for w in VERDICTS
                     if w in words)


def paired_values(obs, task: str, a: str, b: str, measure) -> tuple[list, list, list]:
    """Per seed both rows have on ``task``: ``(seeds, a values, b values)``; ``measure`` is a
    key or a function of an observation."""
    get = measure if callable(measure) else (lambda o: o.get(measure))
    ra = {o["seed"]: get(o) for o in obs if o["task"] == task and o["row"] == a}
    rb = {o["seed"]: get(o) for o in obs if o["task"] == task and o["row"] == b}
    seeds = sorted(s for s in set(ra) & set(rb) if ra[s] is not None and rb[s] is not None)
    return seeds, [ra[s] for s in seeds], [rb[s] for s in seeds]


def judge_claim(claim: Claim, obs, tasks=None, measure=None, note: str = "") -> Verdict:
    """Each task's paired interval and verdict, and the count."""
    tasks = list(tasks or dict.fromkeys(o["task"] for o in obs))
    per_task, parts = [], []
    for task in tasks:
        seeds, va, vb = paired_values(obs, task, claim.a, claim.b, measure or claim.measure)
        if not seeds:
            continue
        ci = stats.paired_diff(va, vb)
        word = ("inconclusive" if len(seeds) < MIN_SEEDS else
                non_inferior(ci, claim.margin) if claim.margin is not None else
                judge(ci, claim.direction))
        few = f" (fewer than {MIN_SEEDS} seeds)" if len(seeds) < MIN_SEEDS else ""
        per_task.append((task, word, ci.mean, ci.lo, ci.hi, len(seeds)))
        band = (f"[{ci.lo:+.3f}, {ci.hi:+.3f}]" if np.isfinite(ci.lo) and np.isfinite(ci.hi)
                else "(no interval)")
        parts.append(f"{task}: {claim.a} - {claim.b} = {ci.mean:+.3f} {band} over "
                     f"{len(seeds)} seeds -> {word}{few}")
    evidence = "; ".join(parts) or "no paired results"
    return Verdict(claim.name, claim.source, claim.rule, count(per_task),
                   evidence + (f" ({note})" if note else ""), claim.reason, tuple(per_task))


__all__ = ["MARGIN", "non_inferior", "Claim", "MIN_SEEDS", "VERDICTS", "Verdict", "count", "judge", "judge_claim",
           "paired_values"]
