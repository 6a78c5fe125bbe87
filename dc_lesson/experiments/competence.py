"""The competence gate in the book: ``data/results/competence.json`` (``dc-lesson sweep
competence``, then ``dc-lesson aggregate competence``, with ``--partial`` while it
accumulates) as chapter 5's table, curves and sentences.

The study, its thresholds and the gate's rule are :mod:`dc_lesson.experiments.studies.competence`;
this module only reads its aggregate.  Every number it shows is a stored observation; every
word comes from the study's :func:`~dc_lesson.experiments.studies.competence.keeps` and
:func:`~dc_lesson.experiments.studies.competence.learns`, applied to the seeds on record, so
a part that has not run says so instead of passing.
"""

from __future__ import annotations

import numpy as np

from dc_lesson.experiments import report
from dc_lesson.experiments.studies import competence as _study

RESULT = "competence.json"
NAMES = {"ppo": "PPO (task reward)", "gail": "GAIL", "dril": "DRIL", "pwil": "PWIL",
         "ndi": "NDI", "gpril": "GPRIL", "dc": "DC", "dc-mix": "DC (mixture policy)"}


def load(name: str = RESULT) -> dict | None:
    """The aggregate, or None while the study has not been aggregated."""
    return report.stored(name)


STORED = "stored"    # the default of every verdict entry point: read the stored gate


def mapping(rec: dict | None = None) -> dict[str, str]:
    """The gate as verdicts read it: learner -> the phrase after its name in a "not judged"
    verdict, for every learner of the study that has not passed ("failed the competence gate
    — why", "has not yet shown competence — why" or, held back only by a part no seed can
    decide, "cannot show competence on our ports — why"), and ``""`` for a variant that passed
    (so that its rows never read their learner's word).  From the stored aggregate (``rec``
    None), re-judged by today's rules; with no aggregate on record no learner has shown
    competence, so none is judged."""
    rec = load() if rec is None else rec
    if rec is None:
        return {k: "has not yet shown competence — no competence study on record ("
                   "dc-lesson sweep competence)" for k in _study.LEARNERS}
    return _study.competence(rec, _study.stored_knife_edge(),
                             _study.stored_references(rec.get("observations", [])))


# A grid aggregate made under the gate's settings carries ``GRID_MARK: RULES``: its cells ran
# each learner as the competence study ran it (``studies.competence.learner_config``: the
# start's exploration noise, hopper's fall, the learners' fixes) at interactions the study's
# curves chose.  The gate vouches for a learner only on such a grid: a grid made before
# (every grid on record until issue 41's rerun) ran other settings and budgets, so there a
# learner that passed is still "not judged".
GRID_MARK = "competence_rules"
RULES = "issue-38"
PRE_GATE = ("passed the competence gate, but this grid ran before the gate's settings (the "
            "start's exploration noise, hopper's fall, the learners' fixes, the interactions) "
            "and waits for its rerun under them")


def brief(text: str) -> str:
    """A verdict's reason cut to its head for a table cell: a passed learner's
    :data:`PRE_GATE` becomes "ran before the gate's settings", the reason of a learner that
    failed, or cannot show competence on our ports, stops before its " — " details; any
    other text is returned unchanged (the prose states the full reasons once)."""
    text = text.replace(PRE_GATE, "ran before the gate's settings")
    if (("failed the competence gate" not in text
         and "cannot show competence" not in text) or " — " not in text):
        return text
    head = text.split(" — ")[0]
    return head + ")" * (head.count("(") - head.count(")"))   # close what the cut left open


def under_gate(*grids: dict | None) -> bool:
    """Whether every one of ``grids`` (aggregates) was made under the gate's settings."""
    return bool(grids) and all(g is not None and g.get(GRID_MARK) == RULES for g in grids)


def resolve(competence, *grids: dict | None) -> dict[str, str] | None:
    """A verdict entry point's ``competence`` argument: :data:`STORED` -> :func:`mapping`
    when every one of ``grids`` (the aggregates the verdict reads) was made under the gate's
    settings (:func:`under_gate`); otherwise (or with none named) every RL learner is held
    back, a failed one with its gate's reason, a passed one with :data:`PRE_GATE`.  A
    mapping (``{}``: judge every learner, for rules on constructed records) is used as
    given."""
    if competence != STORED:
        return competence
    gate = mapping()
    if under_gate(*grids):
        return gate
    return {**{k: PRE_GATE for k in _study.LEARNERS}, **{k: v for k, v in gate.items() if v}}


def status(rec: dict) -> str:
    """``N of M cells (complete|still accumulating), budget, interactions, CPU-hours``."""
    c = rec["cells"]
    done = "complete" if rec.get("complete", True) else "still accumulating"
    steps = rec["steps"]
    from dc_lesson.experiments import aggregate
    stale = aggregate.freshness(rec)   # today's settings may have given new cells
    return (f"{c['n']} of {c.get('of', c['n'])} cells ({done}), budget {rec['budget']}, "
            f"{steps['keep']:,} interactions to keep a start, {steps['learn']:,} to learn; "
            f"{c['wall_seconds'] / 3600:.1f} CPU-hours of cells" + (f"\n{stale}" if stale else ""))


def _runs(rec: dict, learner: str, part: str, task: str) -> list[dict]:
    return sorted((o for o in rec["observations"] if o["row"] == learner
                   and o["part"] == part and o["task"] == task), key=lambda o: o["seed"])


def rows(rec: dict) -> list[dict]:
    """One row per (learner, part, task) with seeds on record: the seeds, the mean start and
    final scaled return, the worst checkpoint's fall below the start, whether that fall is
    gated (not on a knife-edge task, :func:`~dc_lesson.experiments.studies.competence.knife_edge`
    of the stored ``start_noise.json``), and the study's word for that part on those seeds."""
    out = []
    knife = _study.stored_knife_edge()
    refs = _study.stored_references(rec.get("observations", []))
    needed = _study.budget_seeds(rec) or {}
    judged = _study.judge_starts(rec["observations"])
    for learner in _study.LEARNERS:
        for part, tasks in (("keep", _study.KEEP_TASKS), ("learn", _study.LEARN_TASKS)):
            for task in tasks:
                runs = _runs({"observations": judged}, learner, part, task)
                gated = ("" if part == "learn" else
                         "not gated: knife-edge start" if task in knife else "gated")
                if not runs:
                    out.append({"learner": NAMES[learner], "part": part, "task": task,
                                "seeds": 0, "start": None, "final": None, "worst dip": None,
                                "dip": gated, "word": "not run yet"})
                    continue
                ok, why, open_, by_ref = _study.judge_part(
                    part, task, [{k: r.get(k) for k in ("start", "final", "curve", "matched")}
                                 for r in runs],
                    knife, refs.get((learner, part, task)), needed.get(part))
                dip = max(r["start"] - min(r["curve"] or [r["final"]]) for r in runs)
                word = (AS_REFERENCE + why if by_ref else
                        {True: "passes", False: "fails: " + why,
                         None: (NOT_DECIDED if open_ else NOT_INFORMATIVE) + why}[ok])
                out.append({"learner": NAMES[learner], "part": part, "task": task,
                            "seeds": len(runs),
                            "start": float(np.mean([r["start"] for r in runs])),
                            "final": float(np.mean([r["final"] for r in runs])),
                            "worst dip": float(dip), "dip": gated, "word": word})
    return out


AS_REFERENCE = "as the reference: "   # a failed part a standard library's run matches
NOT_DECIDED = "not decided yet: "     # a part with seeds still to run (studies.competence.so_far)
NOT_INFORMATIVE = "not informative: "  # a part no seed to come can decide
CANNOT = "cannot be shown: "           # a learner whose open parts are all not informative


def _passes(word: str) -> bool:
    return word == "passes" or word.startswith(AS_REFERENCE)


def gate_words(rec: dict) -> dict[str, str]:
    """Per learner, the gate's word on the seeds on record: "passed" (every part passes),
    "failed: why" (a part on record fails), "not yet shown: why" (a part not run or not
    decided on the seeds on record; none failing), or "cannot be shown: why" (none failing
    or to run, but a part not informative: a mixture start that never matched plain BC, or
    a weak start that was not weak; no seed to come changes it)."""
    out: dict[str, list] = {}
    for r in rows(rec):
        out.setdefault(r["learner"], []).append(r)
    words = {}
    for learner, parts in out.items():
        failed = [f"{r['part']} on {r['task']}: {r['word'][len('fails: '):]}" for r in parts
                  if r["word"].startswith("fails")]
        open_ = [f"{r['part']} on {r['task']}" for r in parts if not _passes(r["word"])
                 and not r["word"].startswith(("fails", NOT_INFORMATIVE))]
        unasked = [f"{r['part']} on {r['task']}" for r in parts
                   if r["word"].startswith(NOT_INFORMATIVE)]
        words[learner] = ("failed: " + "; ".join(failed) if failed else
                          "not yet shown: " + ", ".join(open_) + " to run" if open_ else
                          CANNOT + ", ".join(unasked) + " not informative" if unasked else
                          "passed")
    return words


def overview(rec: dict) -> dict[str, dict[str, str]]:
    """Learner -> {"part: task": "passes" | "fails" | "not run" | "not decided" |
    "not informative"}: the table's shape at a glance."""
    out: dict[str, dict[str, str]] = {}
    for r in rows(rec):
        w = r["word"]
        short = ("passes" if w == "passes" else "as the reference" if _passes(w) else
                 "fails" if w.startswith("fails") else
                 "not run" if w == "not run yet" else
                 "not decided" if w.startswith(NOT_DECIDED) else "not informative")
        out.setdefault(r["learner"], {})[f"{r['part']}: {r['task']}"] = (
            short + (f" ({r['seeds']})" if r["seeds"] else ""))
    return out


def curves(rec: dict, part: str, task: str) -> dict[str, dict]:
    """Per learner with seeds on record, its mean-action checkpoint curve: ``steps``, the
    mean over seeds and the 95% t interval (``lo``, ``hi``; equal to the mean with one seed),
    and ``seeds``.  Checkpoints are compared where every seed has one."""
    out = {}
    for learner in _study.LEARNERS:
        runs = _runs(rec, learner, part, task)
        if not runs:
            continue
        n = min(len(r["curve"]) for r in runs)
        if n == 0:
            continue
        bands = [report.t_interval([r["curve"][i] for r in runs]) if len(runs) > 1
                 else (runs[0]["curve"][i],) * 3 for i in range(n)]
        out[NAMES[learner]] = {"steps": runs[0]["curve_steps"][:n],
                               "mean": [b[0] for b in bands], "lo": [b[1] for b in bands],
                               "hi": [b[2] for b in bands], "seeds": len(runs),
                               "start": float(np.mean([r["start"] for r in runs]))}
    return out


def reference_table(rec: dict) -> list[dict]:
    """Our learner beside a standard library's implementation of its algorithm
    (:data:`~dc_lesson.experiments.studies.competence.REFERENCES`, e.g. imitation 1.0.1's
    GAIL by ``perf.imitation_gail``), seed by seed from the same start: each side's start,
    final and worst checkpoint (scaled return) and seconds per million interactions of
    training (ours: the cell's; theirs: its run's, both one thread)."""
    out = []
    for learner in _study.REFERENCES:
        for part, tasks in (("keep", _study.KEEP_TASKS), ("learn", _study.LEARN_TASKS)):
            for task in tasks:
                ours = {r["seed"]: r for r in _runs(rec, learner, part, task)}
                for ref in _study.reference_records(learner, part, task):
                    for r in ref["rows"]:
                        o = ours.get(r["seed"])
                        curve = [p["scaled_return"] for p in r.get("curve", ())]
                        row = {"learner": NAMES[learner], "part": part, "task": task,
                               "seed": r["seed"], "reference start": r["start"],
                               "reference final": r["final"],
                               "reference worst": min(curve or [r["final"]]),
                               "reference s / 1M": r["seconds_per_10k"] * 100}
                        if o is not None:
                            row.update({"ours start": o["start"], "ours final": o["final"],
                                        "ours worst": min(o["curve"] or [o["final"]]),
                                        "ours s / 1M": (o["train_seconds"] * 1e6
                                                        / rec["steps"][part]
                                                        if o.get("train_seconds") else None)})
                        out.append(row)
    return out


PLATEAU_TOLERANCE = 0.05   # scaled return: the smallest effect of the book's verdicts
PLATEAU_TAIL = 3           # checkpoints whose mean is a curve's final level


def plateau(steps, mean, tol: float = PLATEAU_TOLERANCE) -> int | None:
    """Where a mean learning curve has flattened: the interactions of the first checkpoint
    from which no later checkpoint's mean lies more than ``tol`` below the curve's final level
    (the mean of its last :data:`PLATEAU_TAIL` checkpoints), so that more interactions would
    raise the mean by less than the book's smallest effect.  One-sided on purpose: a curve
    that got there early and then wobbles above its level has learned (the wobble is the
    gate's "keep" question, not the budget's).  None with fewer than ``PLATEAU_TAIL + 1``
    checkpoints (no level to compare with)."""
    if len(mean) <= PLATEAU_TAIL:
        return None
    level = float(np.mean(mean[-PLATEAU_TAIL:]))
    first = len(mean) - 1
    while first > 0 and mean[first - 1] >= level - tol:
        first -= 1
    return int(steps[first])


def budgets(rec: dict) -> list[dict]:
    """The interactions the next grids use, from the "learns" curves (issue 41, item 2): per
    learn task and learner with seeds on record, where its mean curve flattens
    (:func:`plateau`) and its final level; then per task the budget, the latest plateau
    among the learners that pass the learn part there and have not failed the gate (the
    grids run no failed learner, so its slower curve would buy interactions no row uses; a
    curve that never rose flattens at once and would say nothing), None while none does.  The
    keep part is not asked: it judges stability, the budget asks how long learning takes.  The
    control (PPO on the task's own reward, ``studies.competence.CONTROL``) is shown but does
    not set the budget: no later grid runs it (decided in the sixth week, after its hopper
    curve, whose late dips on two seeds had set hopper's budget, was on record; the chapter
    says so)."""
    out = []
    failed = {k for k, g in rec.get("gate", {}).items() if g["passed"] is False}
    for task in _study.LEARN_TASKS:
        curves_ = curves(rec, "learn", task)
        rows_ = {r["learner"]: r for r in rows(rec) if r["part"] == "learn"
                 and r["task"] == task}
        learned = []
        for name, c in curves_.items():
            at = plateau(c["steps"], c["mean"])
            passes = rows_[name]["word"] == "passes"
            gated_out = any(NAMES[k] == name for k in failed)
            if passes and at is not None and name != NAMES[_study.CONTROL] and not gated_out:
                learned.append(at)
            out.append({"task": task, "learner": name, "seeds": c["seeds"],
                        "final level": float(np.mean(c["mean"][-PLATEAU_TAIL:])),
                        "flattens at": at, "learns": rows_[name]["word"]})
        out.append({"task": task, "learner": "budget", "seeds": None, "final level": None,
                    "flattens at": max(learned) if learned else None,
                    "learns": f"the latest plateau of {len(learned)} learner(s) that learn "
                              f"and have not failed the gate"
                    if learned else "no learner passes the learn part here yet"})
    return out


# The learners that learn by PPO on a reward of their own: beside the control (PPO on the
# task's reward, from the very same weak starts) a failure to learn reads as the reward's or as
# PPO's at this budget.  GPRIL has no RL step, so the control says nothing about it.
ON_PPO = ("gail", "dril", "pwil", "ndi", "dc")


def beside_control(rec: dict) -> list[dict]:
    """Where a learner on PPO (:data:`ON_PPO`) fails the learn part on a task: its final scaled
    return beside the control's on the seeds both ran (the same weak starts), the paired
    difference with its 95% t interval, and what the control's own learn word says of the
    failure: the RL base learns there (the shortfall is the learner's reward), does not learn
    there either (the budget or the task, before any reward), or has not run yet."""
    words = {(r["learner"], r["task"]): r["word"] for r in rows(rec) if r["part"] == "learn"}
    control = _study.CONTROL
    out = []
    for learner in ON_PPO:
        for task in _study.LEARN_TASKS:
            if not words[(NAMES[learner], task)].startswith("fails"):
                continue
            ours = {r["seed"]: r["final"] for r in _runs(rec, learner, "learn", task)}
            base = {r["seed"]: r["final"] for r in _runs(rec, control, "learn", task)}
            seeds = sorted(set(ours) & set(base))
            word = words[(NAMES[control], task)]
            if not seeds:
                reading = "the control has not run these starts yet"
            elif word == "passes":
                reading = ("PPO learns this task from the same starts: the shortfall lies in "
                           "what the learner puts on PPO (its reward, its settings), not in "
                           "RL from this start")
            elif word.startswith("fails"):
                reading = ("PPO does not learn this task from these starts either: the "
                           "budget or the task fails first, before any reward")
            else:
                reading = "the control's own learn part is not decided yet"
            m, lo, hi = (report.t_interval([ours[s] - base[s] for s in seeds])
                         if seeds else (None, None, None))
            out.append({"learner": NAMES[learner], "task": task, "paired seeds": len(seeds),
                        "learner final": (float(np.mean([ours[s] for s in seeds]))
                                          if seeds else None),
                        "control final": (float(np.mean([base[s] for s in seeds]))
                                          if seeds else None),
                        "difference": m, "lo": lo, "hi": hi, "reading": reading})
    return out


def sentence(rec: dict) -> str:
    """What the gate says so far, in one paragraph rendered from the record."""
    words = gate_words(rec)
    passed = [k for k, w in words.items() if w == "passed"]
    failed = [k for k, w in words.items() if w.startswith("failed")]
    pending = [k for k, w in words.items() if w.startswith("not yet")]
    cannot = [k for k, w in words.items() if w.startswith(CANNOT)]
    parts: list[str] = []
    if passed:
        parts.append("passed the whole gate: " + ", ".join(passed))
    if failed:
        parts.append("failed a part already run (no verdict of the book judges a "
                     "comparison with them): " + ", ".join(failed))
    if pending:
        parts.append("not yet shown, with parts still to run (not judged either until "
                     "they pass): " + ", ".join(pending))
    if cannot:
        parts.append("failed no part but cannot pass, a part's question not being askable "
                     "of them on our ports (not judged either): " + ", ".join(cannot))
    return "On the cells on record, " + "; ".join(parts) + "."


__all__ = ["AS_REFERENCE", "CANNOT", "GRID_MARK", "NAMES", "NOT_DECIDED", "NOT_INFORMATIVE",
           "ON_PPO", "PLATEAU_TAIL", "PLATEAU_TOLERANCE", "PRE_GATE", "RESULT", "RULES",
           "STORED", "beside_control", "brief",
           "budgets", "curves", "gate_words", "load", "mapping", "overview", "plateau",
           "reference_table", "resolve", "rows", "sentence", "status", "under_gate"]
