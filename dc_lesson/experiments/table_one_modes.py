"""Chapter 04's answer to its own question, *does DC keep the expert's modes?*, read from the
``table1`` aggregate and put into words by rules fixed before the numbers.

One measure: the total-variation distance of a seed's mode shares from the expert's
(``mode_tv``; 0 is the expert's mix, lower is better), paired by seed and warm start with the
95% paired t interval the verdict rule reads.  Several comparators, because "keeps the modes" only means something
against an alternative (:data:`COMPARATORS`):

* ``bc``: DC's own start, the paper's 70/30 BC (the paper's claim is judged against it);
* the *better-trained BC* on the same 18 demonstrations DC's BC term sees: per task, whichever
  of ``bc-full`` (our net, a fixed budget) and ``bc-lib`` (the standard library's recipe) has
  the lower mean mode TV.  Choosing the comparator after seeing the means favours BC, on
  purpose: DC has to beat the best BC a user could have had, not the weaker one;
* ``dc-noppo`` (DC with its PPO step off: what the density reward's RL term adds),
  ``dc-gailreward`` (Algorithm 2 with a discriminator for log P: whether the density is what
  matters) and ``gail``.

Each comparison's word is :mod:`verdicts`' for "DC's mode TV is lower": *reproduced* (better),
*contradicted* (worse), *equal within 0.05*, *inconclusive* or *not judged: reason*
(:func:`table_one_mixture.verdict` with lower-is-better).  And the floor: the expert scored like
a learner on disjoint episodes has a mode TV of its own (finite episodes); DC is *above the
expert's* on a task when DC's 95% t interval lies wholly above the expert's (unpaired, so
cautious),
else *not distinguished from the expert's*.  A comparator most of whose episodes arrive at no
mode (``none`` >= :data:`LOW_BAR` on a task: an exploring start's sampled actions, say) is
flagged beside its word: a lower mode TV than a policy that reaches nothing is a low bar.

:func:`conclusion` turns the words into the chapter's one-sentence answer by a fixed rule
(tested on constructed aggregates in ``tests/test_table1.py``).
"""

from __future__ import annotations

from dc_lesson.experiments.report import fmt, fmt_entry
from dc_lesson.experiments.table_one import TASKS, paired, tv_band
from dc_lesson.experiments import verdicts as V
from dc_lesson.experiments.table_one_mixture import count_words, verdict

BEST_BC = "best-bc"       # the stand-in name of the better-trained BC, resolved per task
BCS = ("bc-full", "bc-lib")
COMPARATORS = (
    ("bc", "its own start (the paper's 70/30 BC)"),
    (BEST_BC, "the better-trained BC on the same 18 demonstrations (bc-full or bc-lib, "
              "whichever has the lower mode TV on the task)"),
    ("dc-noppo", "DC without its PPO step (what the density reward adds)"),
    ("dc-gailreward", "Algorithm 2 with a discriminator in place of log P"),
    ("gail", "GAIL"),
)
LOW_BAR = 0.5   # a comparator whose episodes mostly arrive nowhere is flagged as a low bar


def _tv(rec: dict, task: str, row: str, actions: str) -> dict | None:
    """The row's mode-TV summary (``tv_ci``: mean, lo, hi) on the task, or None."""
    for m in rec[actions].get("modes", []):
        if m["task"] == task and m["row"] == row:
            return m
    return None


def _none(rec: dict, task: str, row: str, actions: str) -> float:
    """The share of ``row``'s episodes on ``task`` that arrive at no mode (0 if unknown)."""
    for r in rec[actions].get("table", []):
        if r["task"] == task and r["row"] == row:
            return float(r.get("mode_shares_mean", {}).get("none", 0.0))
    return 0.0


def best_bc(rec: dict, task: str, actions: str = "mean") -> str | None:
    """Of :data:`BCS`, the row with the lower mean mode TV on ``task`` (None if neither ran)."""
    got = {r: _tv(rec, task, r, actions) for r in BCS}
    got = {r: tv_band(m)[0] for r, m in got.items() if m}
    return min(got, key=got.get) if got else None


def against(rec: dict, actions: str = "mean") -> dict:
    """``{comparator: {task: (row compared, verdict, paired entry)}}``: DC's mode TV against
    each comparator, by the lower-is-better rule."""
    out: dict = {}
    for comp, _ in COMPARATORS:
        for task in TASKS:
            row = best_bc(rec, task, actions) if comp == BEST_BC else comp
            e = paired(rec, "dc", row, task, actions) if row else None
            out.setdefault(comp, {})[task] = (row, verdict(e, "mode_tv", -1, rec, actions), e)
    return out


def floor(rec: dict, actions: str = "mean") -> dict:
    """``{task: (word, dc's (mean, lo, hi), the expert's)}`` for the tasks where both ran
    (:func:`table_one.tv_band`)."""
    out = {}
    for task in TASKS:
        dc, ex = _tv(rec, task, "dc", actions), _tv(rec, task, "expert", actions)
        if not dc or not ex:
            continue
        d, x = tv_band(dc), tv_band(ex)     # (mean, lo, hi): 95% t intervals over seeds
        above = d[1] is not None and x[2] is not None and d[1] > x[2]
        out[task] = ("above the expert's" if above else "not distinguished from the expert's",
                     d, x)
    return out


def _tasks(by_task: dict, wanted: str) -> list[str]:
    return [t for t, (_, v, _) in by_task.items() if v == wanted]


def _words(by_task: dict) -> str:
    """The per-task verdicts of one comparator in words (:func:`table_one_mixture.count_words`)."""
    return count_words({v: _tasks(by_task, v) for _, v, _ in by_task.values()})


def lines(rec: dict, actions: str = "mean") -> list[str]:
    """Markdown lines: DC against each comparator (the words per task, each task's paired
    difference), then DC against the floor."""
    a = against(rec, actions)
    out = []
    for comp, what in COMPARATORS:
        per = a[comp]
        diffs = ", ".join(f"{t} {fmt_entry(e, 'mode_tv', 2)}"
                          + (f" vs `{row}`" if comp == BEST_BC else "")
                          for t, (row, _, e) in per.items() if e and "mode_tv" in e)
        if comp == "bc" and actions == "sampled":
            what += ", whose sampled row acts with the exploring spread e^-0.5 PPO starts from"
        nowhere = [f"{t} {_none(rec, t, row, actions):.2f}" for t, (row, _, e) in per.items()
                   if e and _none(rec, t, row, actions) >= LOW_BAR]
        out.append(f"* against **{what}**: {_words(per)}"
                   + (f" (DC minus it: {diffs})" if diffs else "")
                   + (f"; a low bar where most of its episodes arrive nowhere (none: "
                      f"{', '.join(nowhere)})" if nowhere else "") + ".")
    fl = floor(rec, actions)
    if fl:
        out.append("* against **the expert scored like a learner** (its own mode TV over "
                   "finite episodes): " + "; ".join(
                       f"{t} {w} (DC {fmt(*d, 2)}, expert {fmt(*x, 2)})"
                       for t, (w, d, x) in fl.items())
                   + ".")
    return out


def mechanism(rec: dict, actions: str = "mean") -> str:
    """What DC's parts do to the mode TV, by a fixed rule on :func:`against`: its PPO step
    against BC continuation (``dc-noppo``) and the SoftFlow density against a discriminator
    (``dc-gailreward``).  The toy predicts the RL step alone keeps no modes; the sentence says
    whether the grid agrees, and whether the density in particular is what helps."""
    a = against(rec, actions)
    rl_better, rl_worse = _tasks(a["dc-noppo"], V.REPRODUCED), _tasks(a["dc-noppo"], V.CONTRADICTED)
    d_better, d_worse = (_tasks(a["dc-gailreward"], V.REPRODUCED),
                         _tasks(a["dc-gailreward"], V.CONTRADICTED))
    judged = [t for t, (_, v, _) in a["dc-gailreward"].items()
              if V.kind(v) != V.NOT_JUDGED]
    if rl_better:
        s = f"DC's PPO step lowers the mode TV against BC continuation on {_n(rl_better)}"
        low = [t for t in rl_better if _none(rec, t, "dc-noppo", actions) >= LOW_BAR]
        if low:
            s += (f" (a low bar on {', '.join(low)}, where BC continuation's episodes mostly "
                  f"arrive nowhere)")
    elif rl_worse:
        s = f"DC's PPO step raises the mode TV against BC continuation on {_n(rl_worse)}"
    else:
        s = "DC's PPO step changes the mode TV detectably on no task"
    if d_better:
        s += f"; the SoftFlow density beats a discriminator reward there on {_n(d_better)}"
    elif d_worse:
        s += f"; a discriminator reward in its place keeps more modes on {_n(d_worse)}"
    elif judged:
        s += ("; a discriminator reward in place of the SoftFlow density changes nothing "
              "detectable on " + _n(judged))
        if rl_better:
            s += (", so what helps is the RL step on a learned reward, not the density in "
                  "particular")
    return f"Under the {actions} action: {s}."


def _n(tasks: list[str]) -> str:
    if not tasks:
        return "no task"
    if len(tasks) == len(TASKS):
        return "every task"
    return f"{len(tasks)} of {len(TASKS)} tasks: {', '.join(tasks)}"


def conclusion(rec: dict, actions: str = "mean") -> str:
    """The answer in one sentence, by a fixed rule on :func:`against` and :func:`floor`:

    * better than the better-trained BC on every task: DC keeps the modes better than BC can;
    * better than it on some tasks: DC keeps more modes than BC there only;
    * better than its start somewhere but nowhere better than the better-trained BC: what DC
      keeps beyond its start, BC trained well on the same demonstrations keeps too (*fewer*
      than that BC when it is worse on some task, *no more* otherwise);
    * too few paired seeds against the start on every task: no answer;
    * otherwise: DC keeps no more modes than the start it is given.

    Then whether DC's mode mix is above the expert's own on every task where both ran.
    """
    a = against(rec, actions)
    start, best = _tasks(a["bc"], V.REPRODUCED), _tasks(a[BEST_BC], V.REPRODUCED)
    if len(best) == len(TASKS):
        s = "DC keeps the modes better than BC can: lower mode TV than the better-trained BC "
        s += "on every task"
    elif best:
        s = f"DC keeps more modes than the better-trained BC on {_n(best)} only"
    elif start:
        low = [t for t in start if _none(rec, t, "bc", actions) >= LOW_BAR]
        worse = _tasks(a[BEST_BC], V.CONTRADICTED)
        s = (f"DC keeps more modes than the start it is given ({_n(start)}"
             + (f"; a low bar on {', '.join(low)}, where the start's episodes mostly arrive "
                f"nowhere" if low else "") + "), "
             + (f"but fewer than BC trained well on the same demonstrations (its mode TV is "
                f"higher than the better-trained BC's on {_n(worse)}, lower on none)" if worse
                else "but no more than BC trained well on the same demonstrations (on no "
                     "task is its mode TV lower than the better-trained BC's)"))
    elif all(V.kind(v) == V.NOT_JUDGED for _, v, _ in a["bc"].values()):
        s = "too few paired seeds to say whether DC keeps more modes than its start"
    else:
        s = "DC keeps no more modes than the start it is given (on no task is its mode TV lower)"
    fl = floor(rec, actions)
    above = [t for t, (w, _, _) in fl.items() if w == "above the expert's"]
    if fl:
        s += (f"; its mode mix stays further from the expert's than the expert's own does "
              f"({_n(above)})" if above else
              "; on no task is its mode TV distinguishable from the expert's own")
    return f"Under the {actions} action: {s}."


__all__ = ["BCS", "BEST_BC", "COMPARATORS", "against", "best_bc", "conclusion", "floor",
           "lines", "mechanism"]
