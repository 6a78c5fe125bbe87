"""Chapter 04's Table I, read from the ``table1`` study's aggregate (``data/results/table1.json``,
``dc-lesson sweep table1`` then ``dc-lesson aggregate table1``): the table with intervals for
either evaluation, the paired comparisons, the mode-coverage summary, the paper's values beside
ours, and the one rule that turns a control's paired interval into a word.

A control arm answers a question the paper did not ask ("what does the SoftFlow reward add?");
each is asked as "is ``a`` better than ``b`` on the measure?" (lower is better on EMD and mode
TV, higher on scaled return) and answered in :mod:`verdicts`' words by its one rule:
*reproduced* (yes), *contradicted* (``a`` is worse), *equal within B*, *inconclusive*, or
*not judged: reason*; one control over the three tasks is one Holm family.
"""

from __future__ import annotations

import statistics

import numpy as np

from dc_lesson.evaluation import stats
from dc_lesson.experiments import claims, report, verdicts as _verdicts
from dc_lesson.experiments.report import fmt, fmt_entry

RESULT = "table1.json"
TASKS = ("reacher2", "reacher4", "halfcheetah2")

# Row, what it is (the order of the chapter's table).
ROWS = {
    "expert": "expert vs expert (the floor)",
    "bc": "BC, 70/30 split (the paper's), as every RL row's start: its log-std reset to "
          "-0.5 for exploration, so its sampled evaluation acts with that std",
    "bc-all": "BC on all 18, early stop on other expert episodes",
    "bc-full": "BC on all 18, trained to a fixed budget (no early stop)",
    "bc-lib": "BC on all 18 as imitation 1.0.1 trains it (32-32, no normaliser, 50k x 32)",
    "gail": "GAIL, D(s, a)",
    "gail-state": "GAIL, state-only D(s)",
    "gail-noisy": "GAIL exploring with the warm start's log-std -0.5 (untuned)",
    "dc": "DC (scaled log P reward)",
    "dc-lib": "DC from bc-lib, its spread reset by the gate's rule (the best BC as start)",
    "dc-raw": "DC, the paper's raw log P reward",
    "dc-noppo": "DC without its PPO step (BC continuation)",
    "dc-gailreward": "Algorithm 2 with GAIL's reward for log P",
    "dril": "DRIL", "pwil": "PWIL", "ndi": "NDI", "gpril": "GPRIL",
    "bc-mix": "mixture BC (4 components), all 18",
    "bc-mixstart": "mixture BC, spreads reset to e^-0.5 (dc-mix's start)",
    "dc-mix": "DC from the mixture BC",
    "bc-coin": "BC 70/30, hidden-coin demonstrations",
    "dc-coin": "DC, hidden-coin demonstrations",
    "bc-full-coin": "BC on all 18 to a fixed budget, hidden-coin demonstrations",
    "bc-mix-coin": "mixture BC, hidden-coin demonstrations",
    "bc-mixstart-coin": "mixture BC with spreads reset, hidden-coin demonstrations",
    "dc-mix-coin": "mixture DC, hidden-coin demonstrations",
}

# The paper's Table I (EMD, KL, RKL); its GPRIL row is omitted ("no meaningful results").
PAPER_TABLE_I = {
    "reacher2": {"bc": (1.01, 2.60, 4.38), "gail": (0.84, 2.47, 4.51),
                 "dril": (1.00, 2.51, 4.25), "pwil": (0.67, 2.47, 3.46),
                 "ndi": (0.68, 2.49, 3.54), "dc": (0.58, 2.47, 3.35)},
    "reacher4": {"bc": (0.81, 4.23, 6.33), "gail": (0.41, 4.49, 6.22),
                 "dril": (0.55, 5.16, 6.16), "pwil": (0.52, 5.13, 5.95),
                 "ndi": (0.54, 5.15, 6.02), "dc": (0.40, 4.04, 5.77)},
    "halfcheetah2": {"bc": (1.81, 6.74, 12.78), "gail": (1.75, 4.52, 18.13),
                     "dril": (1.83, 6.90, 12.76), "pwil": (1.56, 4.23, 12.56),
                     "ndi": (1.60, 4.26, 12.63), "dc": (1.52, 4.06, 12.43)},
}

# The controls: (a, b, measure, the question it answers).
CONTROLS = (
    ("bc-all", "bc", "scaled_return", "does BC trained on all 18 demonstrations beat the 70/30 BC?"),
    ("bc-full", "bc-all", "scaled_return", "does training BC to a fixed budget beat early stopping?"),
    ("bc-lib", "bc-full", "scaled_return", "does the standard library's recipe beat ours?"),
    ("dc", "bc-lib", "emd", "does DC beat the standard library's BC?"),
    ("gail", "bc-lib", "scaled_return", "does GAIL beat the standard library's BC?"),
    ("dc", "dc-noppo", "emd", "what does DC's PPO step on log P add to BC continuation?"),
    ("dc", "dc-raw", "emd", "does our scaled reward beat the paper's raw log P?"),
    ("dc", "dc-gailreward", "emd", "does the SoftFlow density beat a discriminator in Alg. 2?"),
    ("gail", "gail-state", "emd", "does GAIL's (s, a) discriminator beat a state-only one?"),
    ("gail", "gail-noisy", "scaled_return", "does GAIL's quieter start (log-std -2) help it?"),
    ("dc-mix", "dc", "emd", "does the mixture policy help DC?"),
    ("bc-mix", "bc-full", "emd", "does the mixture policy help BC?"),
    ("dc-coin", "bc-coin", "emd", "on the hidden-coin demonstrations, does DC move its start "
     "towards the expert?"),
    ("gail-coin", "bc-coin", "emd", "on the hidden-coin demonstrations, does GAIL?"),
    ("bc-mix-coin", "bc-full-coin", "emd", "can a mixture BC follow the hidden coin better?"),
    ("dc-mix-coin", "dc-coin", "emd", "does the mixture help DC on the hidden coin?"),
    ("dc-lib", "bc-lib", "emd", "does DC move the standard library's BC towards the expert?"),
    ("dc-lib", "dc", "emd", "does DC from the library's BC beat DC from the 70/30 start?"),
)

# Rows every Table I grid has: the floor and the warm starts its RL rows begin from.
BASE_ROWS = ("expert", "bc", "bc-coin")


def in_grid(rec: dict, row: str) -> bool:
    """Whether ``row`` belongs to the grid ``rec`` aggregates: a row of its design (the
    aggregate's ``rows``; a row's ``(unmatched)`` form counts as the row), one of
    :data:`BASE_ROWS`, or a row observed in it.  An aggregate without a design record keeps
    every row, so that a row it lacks reads "not run yet" rather than vanishing."""
    if "rows" not in rec:
        return True
    base = row.split(" (")[0]
    return (base in BASE_ROWS or base in rec["rows"]
            or any(o["row"].split(" (")[0] == base for o in rec["mean"].get("observations", [])))


def load(name: str = RESULT) -> dict | None:
    """The aggregate, or None while the study has not been aggregated."""
    return report.stored(name)


def status(rec: dict) -> str:
    """``N of M cells (complete|still accumulating), budget, revision``."""
    c = rec["cells"]
    done = "complete" if rec.get("complete", True) else "still accumulating"
    from dc_lesson.experiments import aggregate
    stale = aggregate.freshness(rec)
    return (f"{c['n']} of {c.get('of', c['n'])} cells ({done}), budget {rec['budget']}, "
            f"{c['wall_seconds'] / 3600:.1f} CPU-hours of cells; {rec['command']}"
            + (f"\n{stale}" if stale else ""))


def tv_band(m: dict) -> tuple[float, float, float]:
    """A row's mode TV over its seeds as ``(mean, lo, hi)``: the 95% t interval of its
    per-seed ``tv`` values (the stored bootstrap ``tv_ci`` when they are missing)."""
    if m.get("tv"):
        return report.t_interval(m["tv"])
    return m["tv_ci"]["mean"], m["tv_ci"]["lo"], m["tv_ci"]["hi"]


def fmt_tv(band: tuple[float, float, float]) -> str:
    """A mode TV ``(mean, lo, hi)`` as ``mean [lo, hi]``, the interval clipped to the TV's
    limits [0, 1] for display (:func:`report.fmt`)."""
    return fmt(*band, 2, report.bounds("mode_tv"))


def _order(row: str) -> int:
    keys = list(ROWS)
    return keys.index(row) if row in keys else len(keys)


def arrival(observations) -> dict | None:
    """Over the seeds of one row's observations: the mean share of episodes that arrive at a
    mode (1 - "none") and, among the seeds whose episodes arrive anywhere, the mean share of
    the arrivals that go to the seed's largest mode, and how many of those seeds put at least
    ``claims.COLLAPSE_SHARE`` of their arrivals in one mode.  A row whose episodes mostly
    arrive nowhere has not collapsed, nor does it cover the modes: the numbers side by side
    say which it is.  None without mode shares."""
    shares = [o["mode_shares"] for o in observations if o.get("mode_shares")]
    if not shares:
        return None
    arrived = [1.0 - s.get("none", 0.0) for s in shares]
    largest = [max(v for k, v in s.items() if k != "none") / a
               for s, a in zip(shares, arrived) if a > 0]
    return {"arrived": float(np.mean(arrived)),
            "largest_of_arrivals": float(np.mean(largest)) if largest else None,
            "collapsed_among_arrivals": sum(x >= claims.COLLAPSE_SHARE for x in largest),
            "seeds_arriving": len(largest)}


def table(rec: dict, actions: str = "mean", digits: int = 3) -> list[dict]:
    """One dict per (task, row): n seeds, EMD / KL / RKL / scaled return as ``mean [lo, hi]``
    (95% t intervals over seeds), the TV of mode shares from the reference's (the same), the
    mean shares, and (:func:`arrival`) the share of episodes arriving at a mode beside the
    share of the arrivals in the largest mode."""
    part = rec[actions]
    tv = {(m["task"], m["row"]): m for m in part["modes"]}
    by_row: dict = {}
    for o in part.get("observations", []):
        by_row.setdefault((o["task"], o["row"]), []).append(o)
    out = []
    for r in sorted(part["expert"] + part["table"],
                    key=lambda r: (TASKS.index(r["task"]) if r["task"] in TASKS else 9,
                                   _order(r["row"]))):
        m = tv.get((r["task"], r["row"]))
        out.append({"task": r["task"], "row": r["row"], "seeds": r["n_seeds"],
                    **{label: fmt_entry(r, key, digits) for label, key in
                       (("EMD", "emd"), ("KL", "kl"), ("RKL", "rkl"),
                        ("scaled return", "scaled_return")) if f"{key}_mean" in r},
                    "mode TV": fmt_tv(tv_band(m)) if m else "",
                    "collapsed seeds": (f"{round(m['collapsed_share'] * m['n_seeds'])}/"
                                        f"{m['n_seeds']}") if m else "",
                    "modes": ", ".join(f"{k} {v:.2f}" for k, v in
                                       r.get("mode_shares_mean", {}).items()),
                    **_arrival_columns(arrival(by_row.get((r["task"], r["row"]), [])))})
    return out


def arrival_lines(rec: dict, rows, actions: str = "mean") -> list[str]:
    """Per task, one Markdown line: for each of ``rows``, the share of episodes arriving at a
    mode and the share of the arrivals in the largest one (:func:`arrival`, means over
    seeds), and in how many seeds that share is at least ``claims.COLLAPSE_SHARE``.
    Descriptive: the claims' verdicts are judged elsewhere."""
    by_row: dict = {}
    for o in rec[actions].get("observations", []):
        by_row.setdefault((o["task"], o["row"]), []).append(o)
    out = []
    for task in TASKS:
        bits = []
        for row in rows:
            a = arrival(by_row.get((task, row), []))
            if a is None:
                continue
            big = a["largest_of_arrivals"]
            bits.append(f"`{row}` arrives at a mode in {a['arrived']:.2f} of its episodes"
                        + ("" if big is None else
                           f", {big:.2f} of those at its largest mode, "
                           f"{a['collapsed_among_arrivals']} of the {a['seeds_arriving']} "
                           f"seeds that arrive anywhere with at least "
                           f"{claims.COLLAPSE_SHARE:.0%} of their arrivals at one mode"))
        if bits:
            out.append(f"* `{task}`: " + "; ".join(bits) + ".")
    return out


def collapse_words(rec: dict, rows, actions: str = "mean") -> str:
    """Which of ``rows`` collapses, in words, by a fixed rule: a row collapses on a task when
    more than half of its seeds did (``claims.collapsed``: at most 1 - COLLAPSE_SHARE of a
    seed's episodes reach a mode other than its largest, episodes arriving nowhere
    included); per row, the tasks where it does and where it does not, with the counts.
    Descriptive: which row's collapse a claim judges, and against what, is the verdicts'."""
    obs = rec[actions].get("observations", [])
    out = []
    for row in rows:
        did, didnt = [], []
        for task in TASKS:
            mine = [claims.collapsed(o) for o in obs if o["task"] == task and o["row"] == row]
            mine = [m for m in mine if m is not None]
            if mine:
                (did if sum(mine) > len(mine) / 2 else didnt).append(
                    f"`{task}` ({sum(mine)} of {len(mine)} seeds)")
        if did or didnt:
            out.append(f"`{row}` collapses on " + (", ".join(did) if did else "no task")
                       + ("" if not didnt else "; not on " + ", ".join(didnt)))
    return ("; ".join(out) + ".") if out else ""


def _arrival_columns(a: dict | None) -> dict:
    if a is None:
        return {"arrived": "", "largest mode of arrivals": ""}
    big = a["largest_of_arrivals"]
    return {"arrived": f"{a['arrived']:.2f}",
            "largest mode of arrivals": "" if big is None else f"{big:.2f}"}


def paired(rec: dict, a: str, b: str, task: str, actions: str = "mean") -> dict | None:
    """The paired entry ``a - b`` on ``task`` (None if the two rows share no seed yet)."""
    for p in rec[actions]["paired"]:
        if p["a"] == a and p["b"] == b and p["task"] == task:
            return p
    return None


def word(entry: dict | None, measure: str, rec: dict | None = None,
         actions: str = "mean", direction: int | None = None,
         floor: float | None = None, competence: dict | str | None = "stored") -> str:
    """The control rule (module docstring) on one paired entry alone: is ``a`` better than
    ``b`` on ``measure``?  ``rec``: the aggregate whose expert rows bound the divergences;
    ``direction``: the sign of ``a - b`` that counts as better, for a measure
    ``verdicts.BETTER`` does not know (+1: higher); ``floor``: a divergence's expert-vs-expert
    value when ``rec`` is not a Table I aggregate; ``competence``: the stored gate by default
    (a row whose learner has not shown competence is not judged)."""
    if not entry or f"{measure}_diffs" not in entry:
        return f"{_verdicts.NOT_JUDGED}: not run yet"
    why = _verdicts.rows_gate((entry.get("a", ""), entry.get("b", "")),
                              claims.competence_of(competence, rec))
    if why:
        return f"{_verdicts.NOT_JUDGED}: {why}"
    if floor is None:
        floor = claims.floors(rec, actions).get(entry["task"], {}).get(measure)
    return _verdicts.word_of_diffs(entry[f"{measure}_diffs"], measure,
                                   direction or _verdicts.BETTER[measure], floor)


def said(entry: dict | None, measure: str, rec: dict | None = None,
         actions: str = "mean", direction: int | None = None,
         better: str = "better", worse: str = "worse", floor: float | None = None,
         decided: str | None = None) -> str:
    """``a - b`` on ``measure`` as ``mean [lo, hi], *word*`` (the rule's t interval and its
    word, with which row is ``better`` or ``worse`` when it is decisive).  ``decided``: the
    word its family gave (:func:`family`), in place of the entry's word on its own."""
    if not entry or f"{measure}_diffs" not in entry:
        return f"*{word(entry, measure)}*"
    t = _verdicts.paired_t(entry[f"{measure}_diffs"])
    band = (f" [{_verdicts.fmt_num(t.lo)}, {_verdicts.fmt_num(t.hi)}]"
            if t.n >= 2 and t.lo != t.hi else "")
    w = decided or word(entry, measure, rec, actions, direction, floor)
    side = {_verdicts.REPRODUCED: f" ({entry['a']} {better})",
            _verdicts.CONTRADICTED: f" ({entry['a']} {worse})"}.get(w, "")
    return f"{_verdicts.fmt_num(t.mean)}{band}, *{w}*{side}"


def family(rec: dict, a: str, b: str, measure: str, actions: str = "mean",
           competence: dict | str | None = "stored", question: str = "") -> dict:
    """``{task: verdicts.Entry}``: "is ``a`` better than ``b`` on ``measure``?" over Table I's
    tasks as one Holm family (the one rule; a divergence's bound the task's expert floor; no
    start gate: a control asks which row is better, not whether a start improved)."""
    return judge_entries({t: paired(rec, a, b, t, actions) for t in TASKS}, measure, rec,
                         actions, competence=competence, question=question)


def judge_entries(entries: dict, measure: str, rec: dict | None, actions: str = "mean",
                  direction: int | None = None, competence: dict | str | None = "stored",
                  question: str = "") -> dict:
    """``{task: verdicts.Entry}`` of paired entries (``{task: entry or None}``, each ``a - b``
    with its per-seed differences; the compared rows may differ from task to task) judged as
    one Holm family: "is ``a`` better than ``b`` on ``measure``?" by ``direction`` (default
    ``verdicts.BETTER``), a divergence's bound the task's expert floor, no start gate."""
    got = {t: e for t, e in entries.items() if e and f"{measure}_diffs" in e}
    if not got:
        return {}
    a = "/".join(dict.fromkeys(e["a"] for e in got.values()))
    b = "/".join(dict.fromkeys(e["b"] for e in got.values()))
    question = question or f"{a} better than {b} on {measure}"
    c = _verdicts.Claim(question, "control", measure, a, b,
                        direction or _verdicts.BETTER[measure], question, start=None)
    floor = claims.floors(rec, actions)
    members = [(t, np.asarray(e[f"{measure}_diffs"], float), None,
                floor.get(t, {}).get(measure)) for t, e in got.items()]
    gate = claims.competence_of(competence, rec)
    return {e.key: e for e in _verdicts.judge_family(c, members, gate)}


def controls(rec: dict, actions: str = "mean",
             competence: dict | str | None = "stored") -> list[dict]:
    """Every control of the grid on every task: the question, ``a - b`` with its interval, the
    word (Holm across the control's tasks) and, beside it, the reason it is not judged.  A
    control whose rows are not both in the grid's design (:func:`in_grid`: the rerun has no
    GAIL, the first grid no ``dc-lib``) is left out, not listed as "not run yet"."""
    out = []
    for a, b, measure, question in CONTROLS:
        if not (in_grid(rec, a) and in_grid(rec, b)):
            continue
        got = family(rec, a, b, measure, actions, competence, question)
        for task in TASKS:
            e = got.get(task)
            w = e.word if e else f"{_verdicts.NOT_JUDGED}: not run yet"
            out.append({"question": question, "task": task, "measure": measure,
                        "a - b": f"{a} - {b}",
                        "difference": (f"{_verdicts.fmt_num(e.mean)} [{_verdicts.fmt_num(e.lo)}"
                                       f", {_verdicts.fmt_num(e.hi)}]") if e and e.n >= 2
                        else "", "seeds": e.n if e else 0,
                        "word": _verdicts.kind(w),
                        "reason": w.split(": ", 1)[1] if ": " in w else w[len(_verdicts.kind(w)):].strip()})
    return out


# The rows of the headline across tasks: the floor, the paper's learners (BC: every RL row's
# start), DC last.
HEADLINE_ROWS = ("expert", "bc", "gail", "dril", "pwil", "ndi", "gpril", "dc")


def across_tasks(rec: dict, actions: str = "mean", target: str = "dc",
                 seed: int = 0) -> list[dict]:
    """Table I's headline over its three tasks, as Table III's (rliable, Agarwal et al. 2021;
    :func:`report.across_tasks`): per row of :data:`HEADLINE_ROWS`, on EMD and on scaled
    return, the interquartile mean over tasks and seeds with its stratified bootstrap
    interval, and the probability that a ``target`` run is better than a run of the row on
    the same task (lower EMD, higher scaled return), with its interval.

    EMD has each task's own scale (halfcheetah2's expert-vs-expert EMD is about 1.8, the
    reachers' 0.02-0.04), and an IQM pooled over tasks on raw EMD would be halfcheetah2's
    alone.  So its IQM is of EMD *in expert floors*: each run's EMD divided by the mean EMD
    of the expert row on its task (:func:`claims.floors`; 1 is as close as a second sample of
    the expert, and the floor is taken as known, not resampled).  A task without an expert
    row has no floor and is left out of the headline, on both measures, so that both rest on
    the same tasks.  The probability of improvement compares runs within a task, so it is
    the same on either scale.  The scaled return is on one scale already (random 0, expert
    1).  Tasks keep their seeds (10, 10 and 5 here): the IQM pools the runs, so a task
    weighs by its seeds, while the probability averages tasks equally.
    Descriptive: the per-task words are the claims' and the controls'."""
    floors = {t: f["emd"] for t, f in claims.floors(rec, actions).items()
              if (f.get("emd") or 0) > 0}
    measures = (("emd", -1, "EMD (in expert floors)", f"P({target} lower EMD)"),
                ("scaled_return", +1, "scaled return", f"P({target} higher return)"))
    out: dict = {}
    for measure, better, iqm_label, p_label in measures:
        by: dict = {}
        for o in rec[actions]["observations"]:
            if o["row"] in HEADLINE_ROWS and o["task"] in floors and o.get(measure) is not None:
                unit = floors[o["task"]] if measure == "emd" else 1.0
                by.setdefault(o["row"], {}).setdefault(o["task"], []).append(o[measure] / unit)
        for r in report.across_tasks(by, HEADLINE_ROWS, target, better, seed):
            got = out.setdefault(r["row"], {"row": r["row"]})
            got.update({iqm_label: r["IQM"], p_label: r["P"], "tasks": r["strata"],
                        "runs": r["runs"]})
    return [out[r] for r in HEADLINE_ROWS if r in out]


def against_imitation(ref: dict, measure: str = "scaled_return",
                      floor: float | None = None) -> str:
    """Chapter 04's check of ``bc-lib`` against the imitation library itself
    (``data/results/imitation_reference.json``, ``python -m dc_lesson.perf.imitation_ref``):
    our BC with the library's recipe minus the library's own BC on ``measure``, as a
    rendered Markdown sentence with each side's mean and lowest seed, Welch's 95% interval
    and the word of :func:`verdicts.word_unpaired` for "ours is better".

    The comparison is **unpaired**: the two libraries' seeds draw different random numbers,
    so seed 0 of one shares nothing with seed 0 of the other and the paired rule does not
    apply.  The unpaired rule keeps the vocabulary and the smallest effect (0.05 scaled
    return): *equal within 0.05* is the answer "ours is as good as the library's";
    *inconclusive* says six seeds a side cannot tell.  ``floor``: a divergence's
    expert-vs-expert value on the task, its smallest effect."""
    by = {who: [r[measure] for r in ref["rows"] if r["library"] == who]
          for who in ("ours", "imitation")}
    direction = _verdicts.BETTER.get(measure, +1)
    t = _verdicts.welch_t(by["ours"], by["imitation"])
    w = _verdicts.word_unpaired(by["ours"], by["imitation"], measure, direction, floor)
    side = {_verdicts.REPRODUCED: " (ours better)",
            _verdicts.CONTRADICTED: " (ours worse)"}.get(w, "")
    band = (f" [{_verdicts.fmt_num(t.lo)}, {_verdicts.fmt_num(t.hi)}]" if t.n >= 2 else "")
    mean = statistics.mean
    return (f"On `{ref['task']}` ({ref['n_demos']} demonstrations, {ref['n_episodes']} "
            f"episodes, mean action), {measure.replace('_', ' ')}: imitation's BC "
            f"{mean(by['imitation']):.3f} over {len(by['imitation'])} seeds (lowest "
            f"{min(by['imitation']):.3f}), ours with its recipe {mean(by['ours']):.3f} over "
            f"{len(by['ours'])} (lowest {min(by['ours']):.3f}); ours minus imitation "
            f"{_verdicts.fmt_num(t.mean)}{band} (Welch's 95% interval, unpaired), "
            f"*{w}*{side}.")


def beside_paper(rec: dict, actions: str = "mean") -> list[dict]:
    """Our EMD / KL / RKL means beside the paper's, for the rows the paper has.  The scales
    differ (our states are the ports' observations, our EMD is on mode features): compare the
    orderings within a task, not the values."""
    ours = {(r["task"], r["row"]): r for r in rec[actions]["table"]}
    out = []
    for task, rows in PAPER_TABLE_I.items():
        for row, (emd, kl, rkl) in rows.items():
            r = ours.get((task, row))
            out.append({"task": task, "row": row, "paper EMD": emd, "paper KL": kl,
                        "paper RKL": rkl,
                        **({"our EMD": r["emd_mean"], "our KL": r["kl_mean"],
                            "our RKL": r["rkl_mean"], "our seeds": r["n_seeds"]} if r else {})})
    return out


def rank_agreement(rec: dict, task: str, measure: str = "emd", actions: str = "mean") -> dict:
    """Which learner is lowest on ``measure`` in the paper's table and in ours (the rows both
    have), whether they agree, both orderings (lowest first) and Kendall's tau between them
    (None with fewer than three shared rows)."""
    idx = {"emd": 0, "kl": 1, "rkl": 2}[measure]
    ours = {r["row"]: r[f"{measure}_mean"] for r in rec[actions]["table"]
            if r["task"] == task and r["row"] in PAPER_TABLE_I[task]}
    if not ours:
        return {"task": task, "paper_lowest": None, "our_lowest": None, "agree": None,
                "tau": None}
    paper = {k: v[idx] for k, v in PAPER_TABLE_I[task].items() if k in ours}
    lo_p, lo_o = min(paper, key=paper.get), min(ours, key=ours.get)
    shared = sorted(ours)
    return {"task": task, "paper_lowest": lo_p, "our_lowest": lo_o, "agree": lo_p == lo_o,
            "rows": shared, "paper_order": sorted(shared, key=paper.get),
            "our_order": sorted(shared, key=ours.get),
            "tau": stats.kendall_tau([paper[k] for k in shared], [ours[k] for k in shared])
            if len(shared) >= 3 else None}


def features(rec: dict, task: str, row: str, which: str = "final",
             seed: int | None = None) -> "np.ndarray | None":
    """The mode features of ``row`` on ``task`` (mean action), pooled over the seeds that have
    run (or of one ``seed``), from the cells of the study's current grid at the aggregate's
    budget; ``row="expert"`` gives the fresh reference's.  ``which``: ``"final"`` or
    ``"start"`` (an RL row's BC start); ``row="ROW:start"`` says the same in the row.  None
    when no cell has them."""
    import numpy as np
    from dc_lesson import budget as _budget
    from dc_lesson.experiments import cells as _cells, protocol, studies
    if row == "expert":
        ref = protocol.reference_cell(task)
        return _cells.read_features(ref.path())["features"] if ref.path().exists() else None
    row, _, part = row.partition(":")
    which = part or which
    name = study_of(rec)
    grid = studies.get(name).grid(_budget.get(rec["budget"]))
    parts = [_cells.read_features(c.path())[which] for c in grid
             if c.study == name and c.task == task and c.row == row and c.path().exists()
             and (seed is None or c.seed == seed)]
    return np.concatenate(parts) if parts else None


def final_logs(rec: dict, row: str) -> list[dict]:
    """Per cell of ``row`` that has run: task, seed, its training log's last tenth averaged
    (``log_final``: a GAIL row's discriminator accuracies and reward, a DC row's ADMM terms)
    and the cell's wall seconds."""
    from dc_lesson import budget as _budget
    from dc_lesson.experiments import cells as _cells, studies
    out = []
    name = study_of(rec)
    for c in studies.get(name).grid(_budget.get(rec["budget"])):
        if c.study == name and c.row == row and c.path().exists():
            r = _cells.read_record(c.path())
            out.append({"task": c.task, "seed": c.seed, **r["result"].get("log_final", {}),
                        "wall_seconds": r["provenance"]["wall_seconds"]})
    return sorted(out, key=lambda d: (TASKS.index(d["task"]), d["seed"]))


def against_start(rec: dict, row: str, start: str, actions: str = "mean") -> list[str]:
    """One rendered Markdown line per task on which ``row`` has run: how many seeds of it and
    of its ``start`` collapsed (``claims.collapsed``: arriving nowhere counts), the
    share of episodes arriving at no mode, ``row - start`` paired on EMD and on scaled return
    with the control word, in how many seeds ``row`` ended below its own start, and the
    spread of its scaled return over seeds."""
    obs = rec[actions]["observations"]
    out = []
    for task in TASKS:
        a = {o["seed"]: o for o in obs if o["task"] == task and o["row"] == row}
        b = {o["seed"]: o for o in obs if o["task"] == task and o["row"] == start}
        seeds = sorted(set(a) & set(b))
        if not seeds:
            continue
        top = lambda rows: sum(bool(claims.collapsed(rows[s])) for s in seeds)
        none = lambda rows: statistics.mean((rows[s].get("mode_shares") or {}).get("none", 0)
                                            for s in seeds)
        ret = [a[s]["scaled_return"] for s in seeds]
        below = sum(a[s]["scaled_return"] < b[s]["scaled_return"] for s in seeds)
        n = f"{len(seeds)} seed" + ("s" if len(seeds) > 1 else "")
        bits = [f"**`{task}`** ({n}): collapsed seeds {row} {top(a)}, its start {top(b)}; "
                f"episodes arriving at no mode {none(a):.2f} against {none(b):.2f}"]
        e = paired(rec, row, start, task, actions)
        for m, label in (("emd", "EMD"), ("scaled_return", "scaled return")):
            if e and m in e:
                bits.append(f"{label} {row} - {start} {said(e, m, rec, actions)}")
        bits.append(f"{row} below its own start in {below} of {len(seeds)} seeds, its scaled "
                    f"return from {min(ret):.2f} to {max(ret):.2f} over seeds")
        out.append("* " + "; ".join(bits) + ".")
    return out


MODE_FEATURES = (("reacher4", 4), ("reacher2", 2), ("halfcheetah2", 0))   # (task, targets)


def coverage_figures(rec: dict, names: dict, what: str, size: float = 3.0,
                     per_row: int = 4):
    """The paper's Figures 1 and 7 from the cells: for each multi-mode task, where each row of
    ``names`` (row -> label; ``"ROW:start"`` for a row's start) goes under its mean action,
    seeds pooled; the label ``"BC"`` shows the RL rows' common start (read from DC's cells).
    Yields each figure as it is drawn (a reacher's fingertip heat maps, at most ``per_row``
    panels a figure, so a figure stays readable at a page's width; halfcheetah2's velocity
    densities); tasks with fewer than two rows that have run are skipped.  ``what`` completes
    the title."""
    import matplotlib.pyplot as plt
    from dc_lesson.viz import plots
    for task, k in MODE_FEATURES:
        feats = {label: features(rec, task, row) for row, label in names.items()}
        if "BC" in feats:
            feats["BC"] = features(rec, task, "dc", which="start")
        feats = {n: f for n, f in feats.items() if f is not None}
        if len(feats) < 2:
            continue
        if not k:
            plots.coverage_velocity(feats, title=f"{task}: forward velocity, {what}")
            yield plt.gcf()
            continue
        items = list(feats.items())
        for first in range(0, len(items), per_row):
            plots.coverage_reacher(dict(items[first:first + per_row]), k, size=size)
            part = (f" ({first // per_row + 1} of {-(-len(items) // per_row)})"
                    if len(items) > per_row else "")
            plt.suptitle(f"{task}: {what}{part}", y=1.07 if size >= 3 else 1.1)
            yield plt.gcf()


def summary_lines(rec: dict, actions: str = "mean") -> list[str]:
    """One rendered Markdown line per task: DC against its BC start and against GAIL (EMD,
    paired), the mode TV of DC and of its start, and how many seeds of each collapsed; every
    number read from the aggregate, every word from the rules."""
    modes = {(m["task"], m["row"]): m for m in rec[actions]["modes"]}
    out = []
    for task in TASKS:
        e_bc, e_gail = paired(rec, "dc", "bc", task, actions), paired(rec, "dc", "gail", task,
                                                                         actions)
        if not e_bc or "emd" not in e_bc:
            continue
        m_dc, m_bc = modes.get((task, "dc")), modes.get((task, "bc"))
        bits = [f"`{task}` ({e_bc['n_seeds']} paired seeds): DC's EMD minus its start's "
                f"{said(e_bc, 'emd', rec, actions)}"]
        if e_gail and "emd" in e_gail:
            bits.append(f"minus GAIL's {said(e_gail, 'emd', rec, actions)}")
        if m_dc and m_bc:
            bits.append(f"mode TV from the expert's shares {fmt_tv(tv_band(m_dc))} "
                        f"against the start's {fmt_tv(tv_band(m_bc))} "
                        f"(multinomial floor {m_dc['tv_floor']['mean']:.2f}); collapsed seeds: "
                        f"DC {round(m_dc['collapsed_share'] * m_dc['n_seeds'])} of "
                        f"{m_dc['n_seeds']}, start {round(m_bc['collapsed_share'] * m_bc['n_seeds'])}"
                        f" of {m_bc['n_seeds']}")
        out.append("; ".join(bits) + ".")
    return out


def curves(rec: dict, task: str, row: str) -> list[dict]:
    """``{"seed", "steps", "episode_return", "param_change_l1", "iterations"}`` per seed of
    ``row`` on ``task`` that has run: its training log's curves (interactions on ``steps``)."""
    out = []
    for o in rec["mean"]["observations"]:
        c = o.get("curve")
        if o["task"] != task or o["row"] != row or not c:
            continue
        steps = c.get("env_steps") or c.get("steps")
        out.append({"seed": o["seed"], "steps": steps, "episode_return": c.get(
            "episode_return"), "param_change_l1": c.get("param_change_l1"),
            "iterations": o.get("iterations")})
    return sorted(out, key=lambda d: d["seed"])


def costs(rec: dict, since: str | None = None, until: str | None = None) -> list[dict]:
    """Per (task, row) of the cells of ``rec``'s study (:func:`study_of`) that have run, their
    cost (:func:`aggregate.costs`: minutes per cell, cells, training seconds per 100,000
    interactions), from the cells written between ``since`` and ``until`` (ISO times: cells
    of different machines must not be averaged into one cost)."""
    from dc_lesson.experiments import aggregate as _agg
    return _agg.costs(study_of(rec), rec["budget"], since, until)


def study_of(rec: dict) -> str:
    """The study whose cells ``rec`` aggregates (``table1``, or ``modes``: the rerun under
    the gate), so that every reader of cells (:func:`features`, :func:`final_logs`,
    :func:`costs`) reads that study's and no other's."""
    return rec.get("benchmark", "table1")


__all__ = ["study_of", "BASE_ROWS", "collapse_words", "CONTROLS", "in_grid", "HEADLINE_ROWS", "PAPER_TABLE_I", "RESULT", "ROWS", "TASKS",
           "across_tasks", "against_imitation", "beside_paper", "controls",
           "against_start", "costs", "coverage_figures", "curves", "features",
           "final_logs", "fmt_tv", "summary_lines", "tv_band",
           "load", "paired", "rank_agreement", "said", "status", "table", "word"]
