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
  matters) and ``gail``;
* ``dril``: DRIL, the RL baseline that passed the competence gate (the rerun's only other
  RL learner).

A comparator whose row is not in the grid's design (:func:`table_one.in_grid`: the rerun
under the gate has no GAIL and none of DC's diagnostics) is left out of :func:`against` and
:func:`lines`, not reported as "not run yet".

Each comparison's word is :mod:`verdicts`' for "DC's mode TV is lower" (DC keeps more of the
expert's modes): *reproduced* (better), *contradicted* (worse), *equal within 0.05*,
*inconclusive* or *not judged: reason* (:func:`table_one.judge_entries` with
lower-is-better: each comparator one Holm family over the tasks).  And the floor: the expert scored like a learner on disjoint episodes has a
mode TV of its own (finite episodes).  DC's seeds share nothing with the expert's, so that
comparison is unpaired: the same claim judged by :func:`verdicts.word_unpaired` (Welch's t,
the same smallest effect and words; *contradicted* there means DC's mix stays further from the
expert's than the expert's own does).  A comparator most of whose episodes arrive at no mode
(``none`` >= :data:`LOW_BAR` on a task: an exploring start's sampled actions, say) is flagged
beside its word: a lower mode TV than a policy that reaches nothing is a low bar.

:func:`conclusion` puts the words into the chapter's answer by a fixed rule, in the same
vocabulary (tested on constructed aggregates in ``tests/test_table1.py``).
"""

from __future__ import annotations

from dc_lesson.experiments.report import fmt_entry
from dc_lesson.experiments.table_one import (TASKS, fmt_tv, in_grid, judge_entries, paired,
                                             tv_band)
from dc_lesson.experiments import claims, verdicts as V
from dc_lesson.experiments.table_one_mixture import count_words

BEST_BC = "best-bc"       # the stand-in name of the better-trained BC, resolved per task
BCS = ("bc-full", "bc-lib")
COMPARATORS = (
    ("bc", "its own start (the paper's 70/30 BC)"),
    (BEST_BC, "the better-trained BC on the same 18 demonstrations (bc-full or bc-lib, "
              "whichever has the lower mode TV on the task)"),
    ("dc-noppo", "DC without its PPO step (what the density reward adds)"),
    ("dc-gailreward", "Algorithm 2 with a discriminator in place of log P"),
    ("gail", "GAIL"),
    ("dril", "DRIL (the RL baseline that passed the competence gate)"),
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
    each comparator of the grid (:func:`table_one.in_grid`), by the lower-is-better rule."""
    out: dict = {}
    for comp, _ in COMPARATORS:   # each comparator one Holm family over the tasks
        if comp != BEST_BC and not in_grid(rec, comp):
            continue
        rows = {t: best_bc(rec, t, actions) if comp == BEST_BC else comp for t in TASKS}
        entries = {t: paired(rec, "dc", r, t, actions) if r else None for t, r in rows.items()}
        got = judge_entries(entries, "mode_tv", rec, actions, -1)
        for task in TASKS:
            w = got[task].word if task in got else f"{V.NOT_JUDGED}: not run yet"
            out.setdefault(comp, {})[task] = (rows[task], w, entries[task])
    return out


def floor(rec: dict, actions: str = "mean", competence: dict | str | None = "stored") -> dict:
    """``{task: (word, dc's (mean, lo, hi), the expert's)}`` for the tasks where both ran: the
    word of :func:`verdicts.word_unpaired` for "DC's mode TV is lower than the expert's own"
    on their per-seed mode TVs (unpaired), beside each side's t interval
    (:func:`table_one.tv_band`); ``not judged`` when the aggregate has no per-seed values."""
    out, gate = {}, _held_back(competence, rec)
    for task in TASKS:
        dc, ex = _tv(rec, task, "dc", actions), _tv(rec, task, "expert", actions)
        if not dc or not ex:
            continue
        word = (f"{V.NOT_JUDGED}: {gate}" if gate else
                V.word_unpaired(dc["tv"], ex["tv"], "mode_tv", -1) if dc.get("tv") and
                ex.get("tv") else f"{V.NOT_JUDGED}: no per-seed mode TVs")
        out[task] = (word, tv_band(dc), tv_band(ex))
    return out


def _tasks(by_task: dict, wanted: str) -> list[str]:
    """The tasks whose word is of the vocabulary's kind ``wanted`` (``equal within`` takes
    ``equal within 0.05``)."""
    return [t for t, (_, v, _) in by_task.items() if V.kind(v) == wanted]


def _words(by_task: dict) -> str:
    """The per-task verdicts of one comparator in words (:func:`table_one_mixture.count_words`)."""
    grouped: dict = {}
    for t, (_, v, _) in by_task.items():
        grouped.setdefault(v, []).append(t)
    return count_words(grouped)


def lines(rec: dict, actions: str = "mean") -> list[str]:
    """Markdown lines: DC against each comparator (the words per task, each task's paired
    difference), then DC against the floor."""
    a = against(rec, actions)
    out = []
    for comp, what in COMPARATORS:
        if comp not in a:
            continue
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
                   "finite episodes; unpaired, Welch's t): " + "; ".join(
                       f"{t} *{w}* (DC {fmt_tv(d)}, expert {fmt_tv(x)})"
                       for t, (w, d, x) in fl.items())
                   + ".")
    return out


def _held_back(competence, rec: dict | None) -> str | None:
    """Why DC's mode comparisons on ``rec`` are not judged (its learner not shown competent
    at the grid's settings), or None."""
    return V.rows_gate(("dc",), claims.competence_of(competence, rec))


def mechanism(rec: dict, actions: str = "mean", competence: dict | str | None = "stored") -> str:
    """What DC's parts do to the mode TV, in the verdict vocabulary (:func:`against`): its
    PPO step against BC continuation (``dc-noppo``) and the SoftFlow density against a discriminator
    (``dc-gailreward``).  The toy predicts the RL step alone keeps no modes; the sentence says
    whether the grid agrees, and whether the density in particular is what helps; nothing
    while DC has not shown competence (every comparison here is DC against a part of it)."""
    why = _held_back(competence, rec)
    if why:
        return f"Under the {actions} action, what DC's parts do to the mode TV is " \
               f"{V.NOT_JUDGED}: {why}."
    a = against(rec, actions)
    if "dc-noppo" not in a or "dc-gailreward" not in a:
        return (f"Under the {actions} action, what DC's parts do to the mode TV is not asked "
                f"of this grid: it has no `dc-noppo` or `dc-gailreward` row.")
    rl_better = _tasks(a["dc-noppo"], V.REPRODUCED)
    d_better, d_worse = (_tasks(a["dc-gailreward"], V.REPRODUCED),
                         _tasks(a["dc-gailreward"], V.CONTRADICTED))
    judged = [t for t, (_, v, _) in a["dc-gailreward"].items()
              if V.kind(v) != V.NOT_JUDGED]
    s = ("*DC's PPO step keeps more modes than BC continuation* (DC's mode TV below "
         f"`dc-noppo`'s): {_words(a['dc-noppo'])}")
    low = [t for t in rl_better if _none(rec, t, "dc-noppo", actions) >= LOW_BAR]
    if low:
        s += (f" (a low bar on {', '.join(low)}, where BC continuation's episodes mostly "
              f"arrive nowhere)")
    s += ("; *the SoftFlow density keeps more modes than a discriminator reward in its "
          f"place* (below `dc-gailreward`'s): {_words(a['dc-gailreward'])}")
    if rl_better and judged and not d_better and not d_worse:
        s += ", so what helps is the RL step on a learned reward, not the density in particular"
    return f"Under the {actions} action: {s}."


def _n(tasks: list[str]) -> str:
    if not tasks:
        return "no task"
    if len(tasks) == len(TASKS):
        return "every task"
    return f"{len(tasks)} of {len(TASKS)} tasks: {', '.join(tasks)}"


def conclusion(rec: dict, actions: str = "mean", competence: dict | str | None = "stored") -> str:
    """The answer in a sentence and its evidence, in :mod:`verdicts`' words for the claim "DC keeps more of
    the expert's modes" (its mode TV is lower), by a fixed rule on :func:`against` and
    :func:`floor`.  The head, first that applies:

    * *reproduced* against the better-trained BC on every task (DC keeps the modes better
      than BC can);
    * *reproduced* against it on some tasks (there only);
    * *reproduced* against its start on some tasks, and against the better-trained BC on
      none (with where it is *contradicted* against that BC);
    * *not judged* against its start on every task (the reasons follow);
    * *contradicted* against its start on some task;
    * otherwise *reproduced against its start on no task*.

    Then each comparator's words per task (:func:`_words`): its start (a low bar flagged),
    the better-trained BC, and the expert scored like a learner (unpaired).  While DC has
    not shown competence (the stored gate by default) the sentence says only that.
    """
    why = _held_back(competence, rec)
    if why:
        return (f"Under the {actions} action, *DC keeps more of the expert's modes* is "
                f"{V.NOT_JUDGED}: {why}. The mode TVs above are our implementation's, shown "
                f"but not judged.")
    a = against(rec, actions)
    start, best = a["bc"], a[BEST_BC]
    s_rep, s_con = _tasks(start, V.REPRODUCED), _tasks(start, V.CONTRADICTED)
    b_rep, b_con = _tasks(best, V.REPRODUCED), _tasks(best, V.CONTRADICTED)
    if len(b_rep) == len(TASKS):
        head = (f"{V.REPRODUCED} against the better-trained BC on every task: DC keeps the "
                f"modes better than BC can")
    elif b_rep:
        head = f"{V.REPRODUCED} against the better-trained BC on {_on(b_rep)} only"
    elif s_rep:
        head = (f"{V.REPRODUCED} against its start on {_on(s_rep)}, and against the "
                f"better-trained BC on no task"
                + (f", where it is {V.CONTRADICTED} on {_on(b_con)}" if b_con else ""))
    elif all(V.kind(v) == V.NOT_JUDGED for _, v, _ in start.values()):
        head = f"{V.NOT_JUDGED} against its start on any task"
    elif s_con:
        head = f"{V.CONTRADICTED} against its start on {_on(s_con)}"
    else:
        head = f"{V.REPRODUCED} against its start on no task"
    low = [t for t in s_rep if _none(rec, t, "bc", actions) >= LOW_BAR]
    parts = [f"Against its start: {_words(start)}"
             + (f" (a low bar on {', '.join(low)}, where the start's episodes mostly arrive "
                f"nowhere)" if low else ""),
             f"Against the better-trained BC: {_words(best)}"]
    fl = floor(rec, actions)
    if fl:
        parts.append("Against the expert scored like a learner (unpaired): "
                     + _words({t: (None, w, None) for t, (w, _, _) in fl.items()}))
    return (f"Under the {actions} action, *DC keeps more of the expert's modes* (a lower mode "
            f"TV) is {head}. " + ". ".join(parts) + ".")


def _on(tasks: list[str]) -> str:
    """``every task`` or ``2 of 3 tasks (reacher2, reacher4)``."""
    if len(tasks) == len(TASKS):
        return "every task"
    return f"{len(tasks)} of {len(TASKS)} tasks ({', '.join(tasks)})"


__all__ = ["BCS", "BEST_BC", "COMPARATORS", "against", "best_bc", "conclusion", "floor",
           "lines", "mechanism"]
