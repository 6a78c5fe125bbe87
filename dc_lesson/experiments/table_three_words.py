"""Chapter 06's answer in words, rendered from the Table III aggregate by fixed rules.

:func:`table_three.verdicts` judges each of the paper's single-mode claims per task and
demonstration count.  A verdict alone can mislead on this grid: where the common BC start
already earns the expert's return (our cartpole and hopper ports), "DC outperforms BC" can
only be contradicted or inconclusive, and a difference of a thousandth of the expert's return
is as *significant* as a large one when every seed agrees; where the start sits at the random
level (the planner tasks), every RL learner starts from nothing it can use.  So each
sentence says, beside its verdicts, where the start left no room, by a rule declared here
(after the paired rule, which it never changes):

* **at the ceiling**: the BC start's mean scaled return at that count is within
  :data:`table_three.MARGIN` (a tenth of the expert's return over random) of the expert's 1;
* **at the random level**: it is within :data:`table_three.MARGIN` of random's 0 (or below).

:func:`conclusion` answers the chapter's question ("does DC add to its start and match the
baselines on one-mode tasks?") in one sentence, over the (task, count) pairs with at least
:data:`verdict_rules.MIN_SEEDS` paired seeds, separating those where the start left room.
``tests/test_table3.py`` checks each rule on constructed aggregates.
"""

from __future__ import annotations

import numpy as np

from dc_lesson.experiments import table_three
from dc_lesson.experiments.verdict_rules import MIN_SEEDS, VERDICTS

CEILING, RANDOM = "at the ceiling", "at the random level"


def start_levels(rec: dict) -> dict:
    """``{(task, n_demos): CEILING | RANDOM | None}`` from the BC row's mean scaled return."""
    out = {}
    for r in rec["table"]:
        if r["row"] != "bc" or r.get("scaled_return_mean") is None:
            continue
        m = r["scaled_return_mean"]
        out[(r["task"], r["n_demos"])] = (CEILING if m >= 1 - table_three.MARGIN else
                                          RANDOM if m <= table_three.MARGIN else None)
    return out


def _span(pairs: list) -> str:
    """``[(task, n)]`` as ``cartpole (4, 11), hopper (4)``: tasks in order, counts after."""
    by: dict = {}
    for t, n in pairs:
        by.setdefault(t, []).append(str(n))
    return ", ".join(f"{t} ({', '.join(ns)})" for t, ns in by.items())


def _level(levels: dict, key) -> str | None:
    """The start's level at (task, count); for a comparison of two counts ("4 -> 25", BC's
    growth), the level both ends share, else none: growth from the ceiling to the ceiling, or
    within the random level, is no room used."""
    task, n = key
    if isinstance(n, str) and "->" in n:
        ends = {levels.get((task, int(e))) for e in n.split("->")}
        return ends.pop() if len(ends) == 1 else None
    return levels.get(key)


def claim_line(rec: dict, claim: str, verdicts: list | None = None) -> str:
    """One Markdown line: the claim's verdicts over its (task, count) pairs, grouped by
    verdict, the pairs with too few seeds apart and the start's level beside each group."""
    levels = start_levels(rec)
    rows = [v for v in (verdicts if verdicts is not None else table_three.verdicts(rec))
            if v["claim"] == claim]
    groups: dict = {w: [] for w in VERDICTS}
    few = []
    for v in rows:
        for task, word, _mean, _lo, _hi, n_seeds in v.get("per_task", ()):
            key = (task, v["n_demos"])
            (few if n_seeds < MIN_SEEDS else groups[word]).append(key)
    parts = []
    for word in VERDICTS:
        pairs = groups[word]
        if not pairs:
            continue
        flat = [p for p in pairs if _level(levels, p)]
        note = "; ".join(f"{lvl}: {_span([p for p in flat if _level(levels, p) == lvl])}"
                         for lvl in (CEILING, RANDOM)
                         if any(_level(levels, p) == lvl for p in flat))
        parts.append(f"{word} on {_span(pairs)}" + (f" (the start {note})" if note else ""))
    if few:
        parts.append(f"too few paired seeds (fewer than {MIN_SEEDS}) on {_span(few)}")
    return f"* **{claim}**: " + ("; ".join(parts) if parts else "not run yet") + "."


def lines(rec: dict) -> list[str]:
    """:func:`claim_line` for every claim of :data:`table_three.CLAIMS` and the
    non-inferiority claims, in the chapter's order."""
    vs = table_three.verdicts(rec)
    return [claim_line(rec, c, vs) for c in
            [c.name for c in table_three.CLAIMS] + list(table_three.NON_INFERIOR)]


# the claim whose paired interval of dc - b per (task, count) a tally reads
_INTERVAL_OF = {"bc": table_three.DC_BEATS_BC.name, "gail": table_three.COMPARABLE}


def tally(rec: dict, b: str = "bc", verdicts: list | None = None) -> dict:
    """Per (task, count) with at least ``MIN_SEEDS`` paired seeds: ``above`` / ``below`` /
    ``same`` (the paired 95% interval of dc - b, read from the verdict that computed it, above
    zero, below zero, or across it) and whether DC stays within the margin (``kept``: the
    interval lies above -MARGIN) or surely loses more than it (``lost``: the interval lies
    below -MARGIN), with the start's level."""
    levels = start_levels(rec)
    out: dict = {}
    for v in (verdicts if verdicts is not None else table_three.verdicts(rec)):
        if v["claim"] != _INTERVAL_OF[b]:
            continue
        for task, _word, mean, lo, hi, n_seeds in v["per_task"]:
            if n_seeds < MIN_SEEDS or not (np.isfinite(lo) and np.isfinite(hi)):
                continue
            side = "above" if lo > 0 else ("below" if hi < 0 else "same")
            out[(task, v["n_demos"])] = {"level": levels.get((task, v["n_demos"])),
                                         "side": side, "kept": lo > -table_three.MARGIN,
                                         "lost": hi < -table_three.MARGIN,
                                         "mean": mean, "lo": lo, "hi": hi}
    return out


def _count(pairs: dict, side: str) -> list:
    return [k for k, v in pairs.items() if v["side"] == side]


def conclusion(rec: dict) -> str:
    """The chapter's answer in one paragraph, by a fixed rule on :func:`tally`:

    * where the start left room (neither at the ceiling nor at the random level): on how
      many (task, count) pairs DC's return is above, below or indistinguishable from its BC
      start's, and from GAIL's;
    * at the ceiling: on how many pairs DC keeps the start's return (its paired interval
      above -MARGIN), on which it loses more than the margin (the interval below -MARGIN),
      and on which the interval is too wide to tell (it straddles -MARGIN);
    * at the random level: that no learner has anything to start from;
    * with no pair of enough seeds: no answer yet.
    """
    vs = table_three.verdicts(rec)
    t_bc, t_gail = tally(rec, "bc", vs), tally(rec, "gail", vs)
    if not t_bc:
        return (f"No (task, demonstration count) pair has {MIN_SEEDS} paired seeds of DC and "
                f"its BC start yet, so the benchmark cannot answer yet.")
    room = {k: v for k, v in t_bc.items() if v["level"] is None}
    ceil = {k: v for k, v in t_bc.items() if v["level"] == CEILING}
    rand = {k: v for k, v in t_bc.items() if v["level"] == RANDOM}
    s = []
    if room:
        up, down, same = (_count(room, w) for w in ("above", "below", "same"))
        g = {k: v for k, v in t_gail.items() if k in room}
        s.append(f"Where the BC start leaves room ({len(room)} task-count pairs: "
                 f"{_span(sorted(room))}), DC's return is above its start's on {len(up)}, "
                 f"below on {len(down)} and indistinguishable on {len(same)}"
                 + (f"; against GAIL, above on {len(_count(g, 'above'))}, below on "
                    f"{len(_count(g, 'below'))}, indistinguishable on "
                    f"{len(_count(g, 'same'))}" if g else "") + ".")
    else:
        s.append("On no task-count pair with enough seeds does the BC start leave room: it "
                 "is at the expert's return or at random's on every one.")
    if ceil:
        kept = [k for k, v in ceil.items() if v["kept"]]
        lost = [k for k, v in ceil.items() if v["lost"]]
        wide = [k for k, v in ceil.items() if not (v["kept"] or v["lost"])]
        more = [f"loses more than that on {_span(sorted(lost))}" if lost else "",
                f"may lose more on {_span(sorted(wide))} (intervals too wide to tell)"
                if wide else ""]
        more = [m for m in more if m]
        s.append(f"Where the start already earns the expert's return ({_span(sorted(ceil))}), "
                 f"there is nothing to add: DC keeps it within {table_three.MARGIN} on "
                 f"{len(kept)} of {len(ceil)} pairs"
                 + (", " + " and ".join(more) if more else "") + ".")
    if rand:
        s.append(f"Where the start is at the random level ({_span(sorted(rand))}), every RL "
                 f"learner starts from nothing it can use, and none is expected to rise.")
    return " ".join(s)


__all__ = ["CEILING", "RANDOM", "claim_line", "conclusion", "lines", "start_levels", "tally"]
