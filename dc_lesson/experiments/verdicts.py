"""The one place where results become words: the rule, the vocabulary and the counter.

**The test.**  A comparison is the per-seed differences ``a - b`` of two rows that share their
seeds (and so their warm start).  Its interval is the paired **t** interval at 95% and its
p-value the two-sided paired t-test of a zero mean.  Chosen by simulation
(``tests/test_verdicts.py``, :func:`false_positive_rate`): under a true null the t-test
declared a difference at most 0.06 of the time on normal, t(2) and bimodal nulls at 5 and 10
seeds, where the former rule (a 95% BCa bootstrap interval) did 0.10-0.25 of the time (the
bootstrap under-covers with few values).  An exact sign-flip test cannot reject at all with 5
seeds (its smallest two-sided p is 2/32), so it is not used.  Two samples that share no
seed (another library's runs against ours; a learner against the expert) are compared by
:func:`word_unpaired`: the same rule with Welch's t, calibrated by the same simulation.

**The smallest effect of interest** (:data:`SMALLEST`, declared before any result was read
with this rule): 0.05 scaled return (a twentieth of the expert's return over random's), and
as stated there for the other measures; for EMD, KL and RKL, whose scale differs per task, the
expert-vs-expert floor on the task (two samples of the expert differ by that much).

**The words** (:data:`WORDS`), for a claim that ``a - b`` has the paper's sign:

* *reproduced*: the difference is on the paper's side, with Holm-adjusted p < 0.05, and its
  mean is at least the smallest effect;
* *contradicted*: the same on the other side;
* *equal within B*: the whole 95% interval lies inside +-B (B the smallest effect: TOST at
  2.5% each side, Holm-adjusted); this is what a "comparable" claim asks for;
* *inconclusive*: neither;
* *not judged: reason*: fewer than :data:`MIN_SEEDS` paired seeds, a row whose learner has
  not passed the competence gate (an optional ``competence`` mapping learner -> phrase; the
  book's entry points read the stored gate, :mod:`dc_lesson.experiments.competence`), or, on a return
  measure, a start at the ceiling (within :data:`LEVEL_GAP` of the expert's 1) or at the
  floor (within it of random's 0), where the comparison cannot show what the claim asks.

**Multiplicity.**  A claim judged over several tasks (or demonstration counts) is one family:
its p-values are adjusted by Holm's step-down method across the judged members, and the
count says over how many.  :func:`count` is the one counter.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import stats as _stats

from dc_lesson.experiments import limits as _limits

ALPHA = 0.05
LEVEL = 0.95
MIN_SEEDS = 5           # fewer paired seeds than this: not judged
LEVEL_GAP = 0.05        # a start within this of the expert's 1 or random's 0 leaves no room
# The smallest effect of interest per measure (absolute, on the measure's own axis).
SMALLEST = {"scaled_return": 0.05, "early_return": 0.05, "worst_lr_return": 0.05,
            "curve_mean": 0.05, "late_spread": 0.05, "curve_spread": 0.05,
            "mode_tv": 0.05, "largest_share": 0.05, "beyond_largest": 0.05,            # shares of episodes
            "log_gap_ratio": 0.1, "log_change_ratio": 0.1}     # log ratios: a 10% change
DIVERGENCES = ("emd", "kl", "rkl")      # bound: the expert-vs-expert floor on the task
FALLBACK = 0.05                         # a divergence whose floor is unknown
RETURN_MEASURES = ("scaled_return", "early_return", "worst_lr_return", "curve_mean")
BETTER = {"scaled_return": +1, "emd": -1, "kl": -1, "rkl": -1, "mode_tv": -1}

REPRODUCED, CONTRADICTED, INCONCLUSIVE = "reproduced", "contradicted", "inconclusive"
EQUAL, NOT_JUDGED = "equal within", "not judged"
WORDS = (REPRODUCED, CONTRADICTED, EQUAL, INCONCLUSIVE, NOT_JUDGED)
CEILING, FLOOR = "start at the ceiling", "start at the floor"


def kind(word: str) -> str:
    """The vocabulary entry a rendered word belongs to (``equal within 0.05`` -> ``equal
    within``, ``not judged: ...`` -> ``not judged``)."""
    return next(w for w in WORDS if word.startswith(w))


def bound_for(measure: str, floor: float | None = None) -> float:
    if measure in DIVERGENCES:
        return float(floor) if floor is not None and floor > 0 else FALLBACK
    return SMALLEST.get(measure, FALLBACK)


# -- the test --------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Test:
    """A paired t-test: mean difference, 95% interval, p of a zero mean, p of equivalence."""
    mean: float
    lo: float
    hi: float
    n: int
    p: float          # two-sided, H0: mean 0
    p_equal: float    # TOST against +-bound, each side at half of 1 - LEVEL


def _t_test(m: float, se: float, df: float, n: int, bound: float) -> Test:
    """The t-test of a mean difference ``m`` with standard error ``se`` on ``df`` degrees of
    freedom: the 95% interval, the two-sided p of a zero mean, and TOST against +-``bound``."""
    if se == 0:         # every seed the same difference: the interval is that point
        return Test(m, m, m, n, 1.0 if m == 0 else 0.0, 0.0 if abs(m) < bound else 1.0)
    t = _stats.t(df)
    half = float(t.ppf(0.5 + LEVEL / 2)) * se
    p = float(2 * t.sf(abs(m) / se))
    # TOST: both one-sided tests must reject; doubling keeps it the 95% interval's test
    p_eq = float(min(1.0, 2 * max(t.sf((m + bound) / se), t.sf((bound - m) / se))))
    return Test(m, m - half, m + half, n, p, p_eq)


def paired_t(diffs, bound: float = 0.0) -> Test:
    d = np.asarray(diffs, np.float64).ravel()
    n, m = d.size, float(d.mean()) if d.size else float("nan")
    if n < 2:
        return Test(m, float("nan"), float("nan"), n, 1.0, 1.0)
    return _t_test(m, float(d.std(ddof=1)) / np.sqrt(n), n - 1, n, bound)


def welch_t(a, b, bound: float = 0.0) -> Test:
    """Welch's t-test of ``mean(a) - mean(b)`` for two samples that share nothing (no seed,
    no start): unequal variances, Welch-Satterthwaite degrees of freedom; ``n`` is the
    smaller sample's size.  Used only by :func:`word_unpaired`."""
    a, b = (np.asarray(x, np.float64).ravel() for x in (a, b))
    n = int(min(a.size, b.size))
    m = float(a.mean() - b.mean()) if n else float("nan")
    if n < 2:
        return Test(m, float("nan"), float("nan"), n, 1.0, 1.0)
    va, vb = a.var(ddof=1) / a.size, b.var(ddof=1) / b.size
    se = float(np.sqrt(va + vb))
    df = (va + vb) ** 2 / (va ** 2 / (a.size - 1) + vb ** 2 / (b.size - 1)) if se else 1.0
    return _t_test(m, se, float(df), n, bound)


def holm(ps) -> list[float]:
    """Holm's step-down adjusted p-values (monotone, capped at 1), in the input order."""
    ps = np.asarray(ps, float)
    order = np.argsort(ps, kind="stable")
    adj, run = np.empty_like(ps), 0.0
    for rank, i in enumerate(order):
        run = max(run, min(1.0, (len(ps) - rank) * ps[i]))
        adj[i] = run
    return adj.tolist()


def decide(test: Test, direction: int, bound: float, p: float | None = None,
           p_equal: float | None = None) -> str:
    """The word for one test (``p``, ``p_equal``: its Holm-adjusted p-values, if in a
    family)."""
    p = test.p if p is None else p
    p_equal = test.p_equal if p_equal is None else p_equal
    if p < ALPHA and abs(test.mean) >= bound:
        return REPRODUCED if np.sign(test.mean) == direction else CONTRADICTED
    if p_equal < ALPHA:
        return f"{EQUAL} {bound:.2g}"
    return INCONCLUSIVE


def word_of_diffs(diffs, measure: str, direction: int, floor: float | None = None) -> str:
    """One comparison on its own (no family): the word, or ``not judged`` with few seeds."""
    if len(diffs) < MIN_SEEDS:
        return f"{NOT_JUDGED}: fewer than {MIN_SEEDS} paired seeds"
    b = bound_for(measure, floor)
    return decide(paired_t(diffs, b), direction, b)


def word_unpaired(a, b, measure: str, direction: int, floor: float | None = None) -> str:
    """The word for ``mean(a) - mean(b)`` when the two samples are **unpaired** (their seeds
    share no warm start and draw different random numbers: another library's runs against
    ours, a learner against the expert scored on its own episodes).  The one rule with
    Welch's t in place of the paired t: the same smallest effect (:func:`bound_for`), the
    same words, TOST for *equal within B*, and *not judged* with fewer than
    :data:`MIN_SEEDS` values on either side.

    Why Welch and not "not judged: unpaired seeds": by the same simulation that chose the
    paired rule (:func:`false_positive_rate` with :func:`welch_rule`,
    ``tests/test_verdicts.py``), Welch's test declares a difference under a true null at
    most 0.06 of the time on the normal, t(2) and bimodal nulls at 5, 6 and 10 values a
    side, and on a null where one side spreads five times more than the other (0.027-0.054
    measured over 20,000 samples), so its words mean what the paired rule's mean.  What it
    gives up is power: without the pairing, the seed's own effect stays in the spread, so
    an unpaired comparison is *inconclusive* more often than a paired one would be."""
    if min(len(a), len(b)) < MIN_SEEDS:
        return f"{NOT_JUDGED}: fewer than {MIN_SEEDS} seeds on a side"
    bound = bound_for(measure, floor)
    return decide(welch_t(a, b, bound), direction, bound)


# -- claims, judged in families ----------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Claim:
    """A claim and its rule, declared in advance: ``a - b`` on ``measure`` has sign
    ``direction``; ``comparable``: the claim is "a is at least comparable to b"; ``start``:
    the row whose scaled return sets the start's level (None: no level gate)."""
    name: str
    source: str
    measure: str
    a: str
    b: str
    direction: int
    reason: str
    comparable: bool = False
    start: str | None = "bc"
    gates: tuple = (CEILING, FLOOR)

    @property
    def rule(self) -> str:
        side = "above" if self.direction > 0 else "below"
        what = (f"reproduced if a - b is {side} zero" + (
            " (a comparable claim: 'equal within' the bound answers it too)"
            if self.comparable else ""))
        return (f"{self.measure}: paired t-test of ({self.a} - {self.b}) per seed, Holm "
                f"across the claim's tasks; {what} (p < {ALPHA}, mean beyond the smallest "
                f"effect {bound_for(self.measure)}{' or the expert floor' if self.measure in DIVERGENCES else ''}); "
                f"equal within it if the 95% interval lies inside it; not judged with fewer "
                f"than {MIN_SEEDS} seeds, a learner not shown competent"
                + (", or a start at the ceiling or floor" if self.gated else ""))

    @property
    def gated(self) -> bool:
        return self.start is not None and self.measure in RETURN_MEASURES


class Entry(tuple):
    """One member of a claim's family: ``(key, word, mean, lo, hi, n, p_holm, bound)``."""
    __slots__ = ()
    fields = ("key", "word", "mean", "lo", "hi", "n", "p_holm", "bound")

    def __new__(cls, *values):
        return tuple.__new__(cls, values)

    def __getattr__(self, name):
        return self[self.fields.index(name)]


@dataclasses.dataclass(frozen=True)
class Verdict:
    claim: str
    source: str
    rule: str
    verdict: str          # the count over the family (:func:`count`)
    evidence: str
    reason: str = ""
    per_task: tuple = ()  # Entry per member
    across: Entry | None = None   # the claim across tasks (:func:`judge_across`), if asked


def fmt_num(x: float) -> str:
    """A difference with digits enough not to print a nonzero value as -0.000 (below
    ``limits.NOISE``, float rounding, it is 0)."""
    if not np.isfinite(x):
        return "nan"
    if abs(x) < _limits.NOISE:
        x = 0.0
    return f"{x:+.1e}" if x != 0 and abs(x) < 5e-4 else f"{x:+.3f}"


def start_gate(level: float | None, gates=(CEILING, FLOOR)) -> str | None:
    """The start's mean scaled return -> CEILING / FLOOR / None."""
    if level is None:
        return None
    if CEILING in gates and level >= 1 - LEVEL_GAP:
        return CEILING
    if FLOOR in gates and level <= LEVEL_GAP:
        return FLOOR
    return None


def competence_gate(claim: Claim, competence: dict | None) -> str | None:
    """Why ``claim`` is not judged for its rows' competence, or None.  ``competence`` maps a
    learner (``"gail"``; a row ``"gail-coin"`` or ``"dc@lr"`` is its learner's) to the phrase
    that follows its name: ``"failed the competence gate — why"``, ``"has not yet shown
    competence — why"``, ``"cannot show competence on our ports — why"``
    (:func:`dc_lesson.experiments.competence.mapping`)."""
    # a family whose rows differ by task names them "a/b" (table_one.judge_entries)
    return rows_gate(tuple(r for x in (claim.b, claim.a) for r in x.split("/")), competence)


def rows_gate(rows, competence: dict | None) -> str | None:
    """:func:`competence_gate` for a comparison given by its rows (a paired entry's ``a`` and
    ``b``): the first row whose learner is in ``competence``, with its phrase.  A row's
    learner is the row itself or its longest leading hyphen-part that the mapping names
    (``dc-mix-coin``: ``dc-mix``, a gated variant, before ``dc``; ``dc@lr``, ``gail (x)``:
    ``dc``, ``gail``).  A name mapped to ``""`` passed (a variant, named so that its rows
    never read their learner's word): the row is judged."""
    for row in rows:
        parts = row.split("@")[0].split(" ")[0].split("-")
        names = [row] + ["-".join(parts[:i]) for i in range(len(parts), 0, -1)]
        for name in names:
            if competence and name in competence:
                if competence[name]:
                    return f"{row} {competence[name]}"
                break
    return None


def judge_family(claim: Claim, members, competence: dict | None = None) -> tuple:
    """``members``: ``(key, diffs, start level or None, floor or None)`` each; the entries,
    the judged ones adjusted together by Holm."""
    gate = competence_gate(claim, competence)
    tests, reasons = [], []
    for key, diffs, level, floor in members:
        b = bound_for(claim.measure, floor)
        tests.append((key, paired_t(diffs, b), b))
        why = gate or (f"fewer than {MIN_SEEDS} paired seeds" if len(diffs) < MIN_SEEDS
                       else start_gate(level, claim.gates) if claim.gated else None)
        reasons.append(why)
    judged = [i for i, r in enumerate(reasons) if r is None]
    p = dict(zip(judged, holm([tests[i][1].p for i in judged]))) if judged else {}
    pe = dict(zip(judged, holm([tests[i][1].p_equal for i in judged]))) if judged else {}
    out = []
    for i, (key, t, b) in enumerate(tests):
        w = (f"{NOT_JUDGED}: {reasons[i]}" if reasons[i] else
             decide(t, claim.direction, b, p[i], pe[i]))
        out.append(Entry(key, w, t.mean, t.lo, t.hi, t.n, p.get(i, float("nan")), b))
    return tuple(out)


def judge_across(claim: Claim, members, competence: dict | None = None) -> Entry:
    """The claim **across tasks**, for a grid whose seeds are too few for per-task words:
    each member (``(key, diffs, start level or None, floor or None)``, as
    :func:`judge_family`'s) that is not held back by its start gives the mean of its
    per-seed differences, however few its seeds, and each task one unit, the mean of its
    members' (a key ``(task, count)`` is its task's: counts of one task share its expert and
    are not independent); the one rule (paired t, the smallest effect, the same words) runs
    over those units, so it needs :data:`MIN_SEEDS` tasks.  What it answers is "across tasks, is ``a - b`` on the claim's
    side?", the question of the rliable headline, with the verdict rule's calibration: the
    task means are the sample (``tests/test_verdicts.py`` checks its false positives).  A
    divergence's bound is the median of the tasks' floors."""
    gate = competence_gate(claim, competence)
    if gate:
        return Entry("across tasks", f"{NOT_JUDGED}: {gate}", float("nan"), float("nan"),
                     float("nan"), 0, float("nan"), float("nan"))
    per_task: dict = {}
    floors = []
    for key, diffs, level, floor in members:
        if len(diffs) and not (claim.gated and start_gate(level, claim.gates)):
            task = key[0] if isinstance(key, tuple) else key
            per_task.setdefault(task, []).append(float(np.mean(diffs)))
            floors += [floor] if floor is not None else []
    kept = [float(np.mean(m)) for m in per_task.values()]
    b = bound_for(claim.measure, float(np.median(floors)) if floors else None)
    t = paired_t(kept, b)
    w = (f"{NOT_JUDGED}: fewer than {MIN_SEEDS} tasks" if len(kept) < MIN_SEEDS
         else decide(t, claim.direction, b))
    return Entry("across tasks", w, t.mean, t.lo, t.hi, t.n, t.p, b)


def label(key) -> str:
    return f"{key[0]} ({key[1]})" if isinstance(key, tuple) else str(key)


def count(entries, unit: str = "tasks") -> str:
    """The one counter: ``reproduced`` (``(all n tasks)``) when every judged member agrees,
    else ``reproduced on k of n tasks, ...``; the members not judged named apart with their
    reasons; with Holm over n: said."""
    if len(entries) == 1:
        return entries[0][1]
    judged = [e for e in entries if kind(e[1]) != NOT_JUDGED]
    n = len(judged)
    head = INCONCLUSIVE if not entries else ""
    if judged:
        words = [e[1] for e in judged]
        if len(set(words)) == 1:
            head = words[0] + (f" (all {n} {unit}, Holm over {n})" if n > 1 else "")
        else:
            order = sorted(set(words), key=lambda w: (WORDS.index(kind(w)), w))
            head = ", ".join(f"{w} on {words.count(w)} of {n} {unit}" for w in order) + \
                f" (Holm over {n})"
    apart: dict = {}
    for e in entries:
        if kind(e[1]) == NOT_JUDGED:
            apart.setdefault(e[1].split(": ", 1)[1], []).append(label(e[0]))
    if apart:
        head += ("; " if head else "") + "not judged on " + "; ".join(
            f"{', '.join(k)} ({why})" for why, k in apart.items())
    return head


def evidence(claim: Claim, entries, note: str = "") -> str:
    """Each entry's difference, interval, seeds, Holm p and word.  A difference of a bounded
    measure prints its interval clipped to the difference's limits (``limits.bounds``: a
    mode-TV difference lies in [-1, 1]); the word was decided on the unclipped interval.  A
    member not judged reads "not judged" here: its reason is said once, by :func:`count`."""
    limits = _limits.bounds(claim.measure, difference=True)
    parts = []
    for e in entries:
        lo, hi = _limits.clip(e[3], e[4], limits)
        band = (f"[{fmt_num(lo)}, {fmt_num(hi)}]" if np.isfinite(e[3]) and np.isfinite(e[4])
                else "(no interval)")
        p = f", p (Holm) {e[6]:.3f}" if np.isfinite(e[6]) else ""
        word = NOT_JUDGED if kind(e[1]) == NOT_JUDGED else e[1]
        parts.append(f"{label(e[0])}: {claim.a} - {claim.b} = {fmt_num(e[2])} {band} over "
                     f"{e[5]} seed{'s' if e[5] != 1 else ''}{p} -> {word}")
    return ("; ".join(parts) or "no paired results") + (f" ({note})" if note else "")


def paired_values(obs, key, a: str, b: str, measure, by=("task",)) -> tuple[list, list, list]:
    """Per seed both rows have at ``key`` (a value of the ``by`` fields): ``(seeds, a values,
    b values)``; ``measure`` is a field or a function of an observation."""
    get = measure if callable(measure) else (lambda o: o.get(measure))
    key = key if isinstance(key, tuple) else (key,)
    at = [o for o in obs if tuple(o.get(f) for f in by) == key]
    ra = {o["seed"]: get(o) for o in at if o["row"] == a}
    rb = {o["seed"]: get(o) for o in at if o["row"] == b}
    seeds = sorted(s for s in set(ra) & set(rb) if ra[s] is not None and rb[s] is not None)
    return seeds, [ra[s] for s in seeds], [rb[s] for s in seeds]


def start_level(obs, key, row: str | None, by=("task",)) -> float | None:
    key = key if isinstance(key, tuple) else (key,)
    v = [o["scaled_return"] for o in obs if row and o["row"] == row and
         tuple(o.get(f) for f in by) == key and o.get("scaled_return") is not None]
    return float(np.mean(v)) if v else None


def judge_claim(claim: Claim, obs, keys=None, measure=None, note: str = "", by=("task",),
                competence: dict | None = None, floors: dict | None = None,
                unit: str = "tasks", across: bool = False) -> Verdict:
    """The claim over every ``key`` (values of the ``by`` fields: a task, or (task, count))
    that has paired seeds: one Holm family, its entries, the count and the evidence.
    ``floors``: ``{task: {measure: expert-vs-expert value}}`` for the divergences' bound.
    ``across``: also judge it across the keys (:func:`judge_across`), the word for a grid
    whose keys have too few seeds each."""
    keys = list(keys or dict.fromkeys(tuple(o.get(f) for f in by) for o in obs))
    members = []
    for k in keys:
        k1 = k if isinstance(k, tuple) or len(by) > 1 else (k,)
        seeds, va, vb = paired_values(obs, k1, claim.a, claim.b, measure or claim.measure, by)
        if not seeds:
            continue
        floor = (floors or {}).get(k1[0], {}).get(claim.measure)
        members.append((k1[0] if len(by) == 1 else k1, np.subtract(va, vb),
                        start_level(obs, k1, claim.start, by), floor))
    entries = judge_family(claim, members, competence)
    gate = competence_gate(claim, competence)
    if not members and gate:   # a row the gate kept out of the grid: no pairs, and why
        return Verdict(claim.name, claim.source, claim.rule, f"{NOT_JUDGED}: {gate}",
                       evidence(claim, entries, note), claim.reason, entries, None)
    if not members:            # nothing paired yet: not a test that came out undecided
        return Verdict(claim.name, claim.source, claim.rule,
                       f"{NOT_JUDGED}: no paired seeds of {claim.a} and {claim.b} yet",
                       evidence(claim, entries, note), claim.reason, entries, None)
    return Verdict(claim.name, claim.source, claim.rule, count(entries, unit),
                   evidence(claim, entries, note), claim.reason, entries,
                   judge_across(claim, members, competence) if across else None)


# -- calibration: what the rule does under a true null, and its power --------------------------------

def _bimodal(rng, size):
    """Hopper-like differences: 0 w.p. 0.6, else +-0.9 (a seed that falls off, or not)."""
    return np.where(rng.random(size) < 0.6, 0.0, rng.choice([-0.9, 0.9], size))


NULLS = {"normal": lambda rng, size: rng.normal(0, 0.2, size),
         "t2": lambda rng, size: 0.1 * rng.standard_t(2, size),
         "bimodal": _bimodal}


def t_rule(samples: np.ndarray, bound: float = 0.0) -> np.ndarray:
    """Per row of ``samples`` (sims, n): whether the rule declares a difference (reproduced
    or contradicted), vectorised :func:`decide` without a family."""
    n = samples.shape[1]
    m = samples.mean(1)
    se = samples.std(1, ddof=1) / np.sqrt(n)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(se > 0, 2 * _stats.t(n - 1).sf(np.abs(m) / se), (m == 0) * 1.0)
    return (p < ALPHA) & (np.abs(m) >= bound)


def welch_rule(samples: np.ndarray, bound: float = 0.0) -> np.ndarray:
    """:func:`t_rule` for two unpaired samples: each row of ``samples`` (sims, 2n) is split
    into its first and second halves, ``a`` and ``b``, and judged by Welch's t (vectorised
    :func:`welch_t` and :func:`decide` without a family)."""
    half = samples.shape[1] // 2
    a, b = samples[:, :half], samples[:, half:]
    va, vb = a.var(1, ddof=1) / half, b.var(1, ddof=1) / (samples.shape[1] - half)
    se, m = np.sqrt(va + vb), a.mean(1) - b.mean(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        df = (va + vb) ** 2 / (va ** 2 / (half - 1) + vb ** 2 / (samples.shape[1] - half - 1))
        p = np.where(se > 0, 2 * _stats.t(np.where(se > 0, df, 1.0)).sf(np.abs(m) / se),
                     (m == 0) * 1.0)
    return (p < ALPHA) & (np.abs(m) >= bound)


def false_positive_rate(rule, null: str, n: int, sims: int = 4000, seed: int = 0) -> float:
    """The share of ``sims`` null samples of ``n`` paired differences (mean zero) on which
    ``rule`` (a function of a (sims, n) array -> bool per row) declares a difference."""
    x = NULLS[null](np.random.default_rng(seed), (sims, n))
    return float(np.mean(rule(x)))


# What each measure's smallest effect is on (the chapter's table of them, :func:`smallest_effects`).
UNITS = {"scaled_return": "scaled return (random 0, expert 1)",
         "early_return": "scaled return, mean over the first half of the interactions",
         "worst_lr_return": "scaled return, the worst over the learning rates",
         "curve_mean": "scaled return, mean over the checkpoints",
         "late_spread": "std of the scaled return over the second half of the interactions",
         "curve_spread": "std of the checkpoints' scaled return over the second half",
         "mode_tv": "share of episodes (total variation of the mode shares)",
         "largest_share": "share of episodes in the largest mode",
         "beyond_largest": "share of episodes beyond the largest mode",
         "log_gap_ratio": "log ratio (0.1: a change of about 10%)",
         "log_change_ratio": "log ratio (0.1: a change of about 10%)"}


def smallest_effects() -> list[dict]:
    """One row per measure: its smallest effect of interest (:data:`SMALLEST`; for EMD, KL and
    RKL the expert-vs-expert floor on the task, :data:`FALLBACK` where it is unknown) and what
    it is measured in; rendered by the chapters, never typed."""
    rows = [{"measure": m, "smallest effect": f"{b:g}", "on": UNITS.get(m, "")}
            for m, b in SMALLEST.items()]
    rows += [{"measure": m, "smallest effect": "the expert-vs-expert value on the task",
              "on": f"the divergence's own units (where unknown: {FALLBACK:g})"}
             for m in DIVERGENCES]
    return rows


def observed_spread(entries, measure: str = "scaled_return") -> tuple[float, int]:
    """``(sd, n)``: the median standard deviation of the per-seed differences
    (``{measure}_diffs``) over the paired ``entries`` of an aggregate that have two or more,
    and the most common number of seeds among them: the spread at which :func:`power` says
    what a grid can see."""
    diffs = [e[f"{measure}_diffs"] for e in entries if len(e.get(f"{measure}_diffs") or ()) >= 2]
    if not diffs:
        raise ValueError(f"no paired entry has two or more {measure} differences")
    sizes = [len(d) for d in diffs]
    n = max(set(sizes), key=lambda k: (sizes.count(k), k))
    return float(np.median([np.std(d, ddof=1) for d in diffs])), n


def power(effect: float, sd: float, n: int, bound: float = SMALLEST["scaled_return"],
          sims: int = 20000, seed: int = 0) -> float:
    """The share of normal samples (mean ``effect``, sd ``sd``, ``n`` seeds) the rule calls a
    difference on ``effect``'s side (a single test, no family)."""
    x = np.random.default_rng(seed).normal(effect, sd, (sims, n))
    return float(np.mean(t_rule(x, bound) & (np.sign(x.mean(1)) == np.sign(effect))))
