"""Chapter 04's mixture-policy section, read from the ``table1`` aggregate: what a policy that
can hold several modes (:class:`~dc_lesson.nn.mixture.MixturePolicy`, 4 components) changes
against the Gaussian policy trained the same way, on the realizable and the hidden-coin
demonstrations.

The comparisons (:data:`COMPARISONS`), each paired by seed over the mixture rows' seeds:

* ``bc-mix - bc-full`` and ``bc-mix-coin - bc-full-coin``: BC on all 18 demonstrations to the
  same fixed budget, mixture against Gaussian: the mixture's own effect, nothing else differs;
* ``dc-mix - bc-mixstart`` (and its coin twin): what the mixture DC's RL loop does to its own
  start (the mixture BC with its spreads reset for exploration);
* ``dc-mix - dc`` (and its coin twin): the mixture DC against the Gaussian DC.  Their starts
  differ in more than the policy class (the Gaussian DC starts from the paper's 70/30 BC, the
  mixture DC from the mixture BC on all 18), so a difference here is the whole recipe's.

The rerun under the gate (``modes.json``) records no ``bc-mixstart`` row (its mixture DC's start is
``bc-mix`` with its spreads reset, which moves no component's mean or weight), so there the
loop is measured against ``bc-mix`` (:func:`comparisons`): the same difference under the mean
action and under the drawn component (``components``); under sampled actions against the
mixture BC's learned spread, not the exploring one.
A comparison whose rows are not in the grid is left out.

Each is judged on three measures by the one rule of :mod:`verdicts` (is the mixture row
better?): the TV distance of the seed's mode shares from the expert's (``mode_tv``; lower is
better), the scaled return (higher is better) and the EMD of the mode features (lower is
better).  :func:`tally` groups the words by task; :func:`lines` renders them.
"""

from __future__ import annotations

from dc_lesson.experiments.report import fmt_entry
from dc_lesson.experiments import verdicts as _verdicts
from dc_lesson.experiments.table_one import TASKS, in_grid, judge_entries, paired

# (mixture row, the row it is compared with, the demonstrations, what the difference isolates)
COMPARISONS = (
    ("bc-mix", "bc-full", "realizable", "the policy class alone"),
    ("bc-mix-coin", "bc-full-coin", "hidden coin", "the policy class alone"),
    ("dc-mix", "bc-mixstart", "realizable", "the mixture DC's loop against its start"),
    ("dc-mix-coin", "bc-mixstart-coin", "hidden coin", "the mixture DC's loop against its start"),
    ("dc-mix", "dc", "realizable", "the whole mixture recipe (starts differ too)"),
    ("dc-mix-coin", "dc-coin", "hidden coin", "the whole mixture recipe (starts differ too)"),
)



def comparisons(rec: dict) -> list[tuple]:
    """:data:`COMPARISONS` as the grid ``rec`` has them (module docstring): the loop measured
    against ``bc-mix`` where the grid records no ``bc-mixstart``; those whose rows are not in
    the grid (:func:`table_one.in_grid`) left out."""
    out = []
    for a, b, demos, what in COMPARISONS:
        if b.startswith("bc-mixstart") and not in_grid(rec, b):
            b = b.replace("bc-mixstart", "bc-mix")
            what = "the mixture DC's loop against the mixture BC it starts from"
        if in_grid(rec, a) and in_grid(rec, b):
            out.append((a, b, demos, what))
    return out


# measure, label, +1 when higher is better, -1 when lower is
MEASURES = (("mode_tv", "mode TV", -1), ("scaled_return", "scaled return", +1),
            ("emd", "EMD", -1))


def words(rec: dict, a: str, b: str, actions: str = "mean",
          competence: dict | str | None = "stored") -> dict:
    """``{measure: {task: word}}`` of one comparison: per measure, "is the mixture row ``a``
    better than ``b``?" over :data:`TASKS` as one Holm family (the rule of :mod:`verdicts`,
    :func:`table_one.judge_entries`); ``not judged: not run yet`` where a task has no pairs."""
    entries = {t: paired(rec, a, b, t, actions) for t in TASKS}
    out = {}
    for m, _, direction in MEASURES:
        got = judge_entries(entries, m, rec, actions, direction, competence)
        out[m] = {t: got[t].word if t in got else f"{_verdicts.NOT_JUDGED}: not run yet"
                  for t in TASKS}
    return out


def table(rec: dict, actions: str = "mean", digits: int = 3) -> list[dict]:
    """One dict per (comparison, task): the rows, paired seeds, and per measure ``a - b`` as
    ``mean [lo, hi]`` with its word (:func:`words`: Holm across the tasks)."""
    out = []
    for a, b, demos, what in comparisons(rec):
        said = words(rec, a, b, actions)
        for task in TASKS:
            e = paired(rec, a, b, task, actions)
            row = {"demonstrations": demos, "a - b": f"{a} - {b}", "task": task,
                   "isolates": what, "seeds": e["n_seeds"] if e else 0}
            for m, label, _ in MEASURES:
                row[label] = fmt_entry(e, m, digits) if e and m in e else ""
                row[f"{label}: word"] = said[m][task]
            out.append(row)
    return out


def tally(rec: dict, actions: str = "mean") -> dict:
    """``{(a, b): {measure: {verdict: [tasks]}}}`` over :data:`TASKS`."""
    out: dict = {}
    for a, b, *_ in comparisons(rec):
        per = out.setdefault((a, b), {})
        for m, said in words(rec, a, b, actions).items():
            for task in TASKS:
                per.setdefault(m, {}).setdefault(said[task], []).append(task)
    return out


def count_words(by_verdict: dict) -> str:
    """``{word: [tasks]}`` in words: ``reproduced on every task`` or ``reproduced on 2
    (reacher2, reacher4); contradicted on 1 (halfcheetah2)``, in the vocabulary's order."""
    by_verdict = {v: ts for v, ts in by_verdict.items() if ts}
    if len(by_verdict) == 1:
        return f"{next(iter(by_verdict))} on every task"
    order = sorted(by_verdict, key=lambda w: (_verdicts.WORDS.index(_verdicts.kind(w)), w))
    parts = [f"{v} on {len(by_verdict[v])} ({', '.join(by_verdict[v])})" for v in order]
    return "; ".join(parts)


def lines(rec: dict, actions: str = "mean") -> list[str]:
    """One rendered Markdown line per comparison: per measure, on how many tasks the mixture
    row came out better (*reproduced*), worse (*contradicted*), equal or undecided, naming the
    tasks."""
    t = tally(rec, actions)
    out = []
    for a, b, demos, what in comparisons(rec):
        per = t[(a, b)]
        said = {m: count_words(per[m]) for m, _, _ in MEASURES}
        bits = ([f"every measure: {said[MEASURES[0][0]]}"] if len(set(said.values())) == 1
                else [f"{label}: {said[m]}" for m, label, _ in MEASURES])
        out.append(f"* **`{a}` against `{b}`** ({demos} demonstrations; {what}): "
                   + " · ".join(bits) + ".")
    return out


def shares(rec: dict, task: str, row: str, actions: str = "mean") -> dict:
    """``row``'s mode shares on ``task`` under ``actions``, the mean over its seeds, in the
    expert's mode order with ``none`` last (``row="expert"``: the expert scored like a
    learner; its one evaluation is its mean action); ``{}`` when the row has not run."""
    part = rec[actions]
    found = [r for r in part["expert" if row == "expert" else "table"]
             if r["task"] == task and r["row"] == row]
    order = [k for r in part["expert"] if r["task"] == task
             for k in r.get("mode_shares_mean", {}) if k != "none"]
    if not found or not found[0].get("mode_shares_mean"):
        return {}
    got = found[0]["mode_shares_mean"]
    return {k: got.get(k, 0.0) for k in [*order, "none"]}


__all__ = ["COMPARISONS", "MEASURES", "comparisons", "count_words", "lines", "shares", "table", "tally",
           "words"]
