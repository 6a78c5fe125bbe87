"""What a chapter calls to put a stored result into prose: the number, its interval, the
verdict, always rendered from an aggregate (``data/results/STUDY.json``), never typed.

    from dc_lesson.experiments import report
    report.value("bc_demos", "scaled_return", task="reacher4", n_demos=25)  # 'MEAN [LO, HI]'
    report.fmt(mean, lo, hi, digits=3)       # the same from numbers already read
    (every interval the 95% t interval over seeds, the one the verdict rule reads; a measure
    with known limits is printed clipped to them, :data:`BOUNDS`)
    report.verdict(v)                        # 'VERDICT: task: dc - bc = D [LO, HI] over N ...'
"""

from __future__ import annotations

import math

from dc_lesson.experiments.limits import BOUNDS, INF, NOISE, bounds, clip  # noqa: F401 (re-exported)
from dc_lesson.storage import read_result


class ReportError(KeyError):
    """No row of the aggregate matches what a chapter asked for."""


def fmt(mean: float, lo: float | None = None, hi: float | None = None, digits: int = 2,
        limits: tuple[float, float] | None = None) -> str:
    """``mean [lo, hi]``; the mean alone when there is no interval (one seed) or when the
    interval rounds to one number (every seed the same: no ``1.10 [1.10, 1.10]``).
    ``limits``: the measure's (:func:`bounds`); an interval end beyond them is printed at
    the limit (a t interval of shares near 1 is printed ``0.99 [0.98, 1.00]``, not
    ``[0.98, 1.01]``).  Only the printed interval is clipped: every word is decided on the
    t interval as computed."""
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return _num(mean, digits)
    lo, hi = clip(lo, hi, limits)
    if f"{lo:.{digits}f}" == f"{hi:.{digits}f}":
        return _num(mean, digits)
    return f"{_num(mean, digits)} [{lo:.{digits}f}, {hi:.{digits}f}]"


def _num(x: float, digits: int) -> str:
    """``x`` at ``digits`` decimals, or in two significant digits where that would print a
    nonzero value as 0 (a mean difference is never printed ``-0.00`` or ``0.00`` unless it
    is zero; the interval's ends keep the fixed decimals).  Below :data:`NOISE` a value is
    float rounding (the mean of +0.5 and -0.5 can come out 5.6e-17) and prints as 0."""
    if abs(x) < NOISE:
        x = 0.0
    s = f"{x:.{digits}f}"
    return f"{x:.1e}" if x != 0 and math.isfinite(x) and float(s) == 0 else s


def stored(name: str) -> dict | None:
    """A study's stored aggregate ``data/results/NAME``, or None while it has not been made
    (a chapter then says which command makes it)."""
    try:
        return read_result(name)
    except FileNotFoundError:
        return None


def t_interval(values) -> tuple[float, float, float]:
    """``(mean, lo, hi)``: the 95% t interval of the mean of ``values`` (per-seed values of a
    row, or per-seed paired differences): the interval :mod:`verdicts`' rule uses."""
    from dc_lesson.experiments.verdicts import paired_t
    t = paired_t(values)
    return t.mean, t.lo, t.hi


def band(entry: dict, measure: str) -> tuple[float, float, float]:
    """``(mean, lo, hi)`` of one measure of an aggregate table row or of a paired entry: the
    95% t interval over seeds (:func:`t_interval`) of the row's ``{m}_values`` or the paired
    entry's ``{m}_diffs``, the interval the verdict rule reads.  An entry without its per-seed
    values falls back to the stored ``{m}_lo``, ``{m}_hi`` (or ``{m}: {lo, hi}``)."""
    per_seed = entry.get(f"{measure}_diffs", entry.get(f"{measure}_values"))
    if per_seed is not None and len(per_seed):
        return t_interval(per_seed)
    if isinstance(entry.get(measure), dict):
        d = entry[measure]
        return d["mean"], d["lo"], d["hi"]
    return entry[f"{measure}_mean"], entry.get(f"{measure}_lo"), entry.get(f"{measure}_hi")


def fmt_entry(entry: dict, measure: str, digits: int = 2) -> str:
    """:func:`band` as ``mean [lo, hi]``, clipped to the measure's limits (:func:`bounds`; a
    paired entry's to the limits of a difference)."""
    paired = f"{measure}_diffs" in entry or ("a" in entry and "b" in entry)
    return fmt(*band(entry, measure), digits, bounds(measure, difference=paired))


def across_tasks(by: dict, rows, target: str = "dc", better: int = +1, seed: int = 0,
                 digits: int = 2) -> list[dict]:
    """rliable's headline (Agarwal et al. 2021) over the strata every row ran on.  ``by``:
    ``{row: {stratum: [one score per run]}}`` (a stratum is a task, or a task and a
    demonstration count).  Per row of ``rows`` found in ``by``, in that order: ``IQM``, the
    interquartile mean over strata and runs with its stratified bootstrap interval
    (:func:`stats.iqm_tasks`), and ``P``, the probability that a ``target`` run is better
    than a run of the row on the same stratum (:func:`stats.probability_of_improvement`,
    ties half; ``better=-1``: lower scores are better, so it counts ``target < row``) with
    its interval, ``""`` on the target's own row; ``strata`` and ``runs`` say what it rests
    on.  ``[]`` when the target did not run or the rows share no stratum.  Descriptive
    across tasks: no word is decided here (the verdicts are per task, :mod:`verdicts`)."""
    from dc_lesson.evaluation import stats
    present = [r for r in rows if r in by]
    strata = sorted(set.intersection(*(set(by[r]) for r in present))) if present else []
    if target not in present or not strata:
        return []
    sign = 1.0 if better > 0 else -1.0
    mine = [[sign * v for v in by[target][k]] for k in strata]
    out = []
    for r in present:
        x = [by[r][k] for k in strata]
        iqm = stats.iqm_tasks(x, seed=seed)
        poi = (stats.probability_of_improvement(mine, [[sign * v for v in s] for s in x],
                                                seed=seed) if r != target else None)
        out.append({"row": r, "IQM": fmt(iqm.mean, iqm.lo, iqm.hi, digits),
                    "P": fmt(poi.mean, poi.lo, poi.hi, digits, BOUNDS["probability"])
                    if poi else "", "strata": len(strata), "runs": sum(len(v) for v in x)})
    return out


def row(aggregate: dict | str, table: str = "summary", **match) -> dict:
    """The one row of ``aggregate[table]`` whose fields equal ``match``."""
    agg = read_result(aggregate) if isinstance(aggregate, str) else aggregate
    rows = [r for r in agg.get(table, []) if all(r.get(k) == v for k, v in match.items())]
    if len(rows) != 1:
        raise ReportError(f"{len(rows)} rows of {table!r} match {match}; a chapter must name "
                          f"exactly one")
    return rows[0]


def value(study: str, measure: str, *, table: str = "summary", digits: int = 2,
          **match) -> str:
    """``fmt`` of one measure of one row of ``data/results/STUDY.json``."""
    name = study if study.endswith(".json") else f"{study}.json"
    return fmt_entry(row(name, table, **match), measure, digits)


def trend(values) -> str:
    """The shape of a sequence of means, in words: ``rises at every step`` (each above the
    last), ``falls at every step``, or ``has no steady trend``.  Only the shape: whether a
    difference is real is the paired interval's business, not this word's."""
    v = [float(x) for x in values]
    if len(v) < 2:
        raise ValueError(f"a trend needs at least two values, got {len(v)}")
    if all(a < b for a, b in zip(v, v[1:])):
        return "rises at every step"
    if all(a > b for a, b in zip(v, v[1:])):
        return "falls at every step"
    return "has no steady trend"


def favourites(names) -> str:
    """The favourite mode of each seed, in words: ``"every seed favours red"`` when they agree,
    else ``"the favourite differs between seeds: red (6), blue (3), green (1)"`` (most first,
    ties in first-seen order)."""
    names = list(names)
    if not names:
        raise ValueError("no seeds to name a favourite of")
    counts = {n: names.count(n) for n in dict.fromkeys(names)}
    if len(counts) == 1:
        return f"every seed favours {names[0]}" if len(names) > 1 else \
            f"its one seed favours {names[0]}"
    order = sorted(counts, key=lambda n: -counts[n])
    return "the favourite differs between seeds: " + ", ".join(f"{n} ({counts[n]})"
                                                                  for n in order)


def live_tag(b) -> str:
    """What a live result's title or caption carries: ``smoke budget: numbers meaningless`` at
    the smoke budget, else the budget's name (``lesson budget``).  ``b``: a ``budget.Budget``."""
    return "smoke budget: numbers meaningless" if b.is_smoke else f"{b.name} budget"


def verdict(v) -> str:
    """A :class:`claims.Verdict` as one line: the verdict, then its intervals."""
    return f"{v.verdict}: {v.evidence}"


__all__ = ["BOUNDS", "ReportError", "across_tasks", "band", "bounds", "clip", "fmt", "favourites", "fmt_entry",
           "live_tag", "row", "t_interval", "trend", "value", "verdict"]
