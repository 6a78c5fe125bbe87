"""Chapter 06's reading of the single-mode benchmark (``benchmark.json``; the first grid,
``table3.json``, in the same form) and of Figure 8.

Table III and Figure 9 (scaled return against demonstrations), Figure 11 (return against
interactions at the fewest demonstrations, from deterministic evaluations at checkpoints) and
the paper's Table III beside ours, compared by *ordering*: the paper's returns are on Gym's
reward scale, ours on the ports' (scaled returns: random 0, expert 1, on both).  Figure 8
(EMD against scaled return on the multi-mode tasks, one point per seed) reads ``table1.json``.

The paper's Table III (:data:`PAPER_TABLE_III`).  Its header is lost in our copy of the
paper, and the right-hand columns of several rows were shifted into a block at the side.  We
read the seven columns as ``PAPER_COLUMNS`` = BC, GAIL, GPRIL, DRIL, PWIL, NDI, DC: the order
in which the paper lists its baselines (Sec. V: BC, GAIL, GPRIL, DRIL, PWIL, NDI), DC last as
in its other tables; the values agree (the first column grows with the demonstrations on the
locomotion tasks, as the text says BC does; the third is the lowest in every entry but two,
as the text says GPRIL is).  The shifted block is read back by the cut-off digits that start
each of its pieces (".02 -6.97±3.30 -6.21±2.49" finishes Reacher at 18); entries read that
way, or whose standard deviation lost a digit, are listed in :data:`UNCERTAIN`.  CartPole's
rows and Reacher's first five columns at 4 and 11 are illegible and left out; the paper's
Reacher (one target) is our ``reacher1``, its Walker2d our ``walker``."""

from __future__ import annotations

import numpy as np

from dc_lesson.evaluation import stats
from dc_lesson.experiments import ablations as _ablations, claims as _claims
from dc_lesson.experiments import verdicts as _verdicts
from dc_lesson.experiments import report
from dc_lesson.experiments.report import band, fmt_entry

kendall_tau = stats.kendall_tau   # the chapter's name for it

RESULT = "table3.json"
LEARNERS = ("bc", "gail", "dril", "pwil", "ndi", "gpril", "dc")
PAPER_COLUMNS = ("bc", "gail", "gpril", "dril", "pwil", "ndi", "dc")

# (mean, std) per learner, in PAPER_COLUMNS order, per task and demonstration count.
PAPER_TABLE_III = {
    "reacher1": {
        18: ((-8.89, 3.83), (-7.34, 2.63), (-9.96, 5.01), (-6.93, 2.37), (-6.81, 2.02),
             (-6.97, 3.30), (-6.21, 2.49)),
        25: ((-9.63, 3.84), (-6.64, 2.47), (-11.87, 4.71), (-6.90, 2.65), (-5.98, 2.10),
             (-6.40, 2.66), (-5.82, 2.43)),
    },
    "hopper": {
        4: ((2352, 894), (3394, 37), (22, 1), (898, 132), (3331, 200), (3248, 53),
            (3378, 164)),
        11: ((2589, 635), (3599, 4), (407, 202), (3150, 184), (3452, 18), (3491, 24),
             (3310, 34)),
        18: ((3331, 66), (3631, 3), (1339, 1390), (3611, 3), (3577, 12), (3565, 17),
             (3686, 8)),
        25: ((3589, 56), (3476, 5), (1406, 844), (3580, 8), (3530, 9), (3512, 9), (3599, 8)),
    },
    "walker": {
        4: ((1233, 969), (4070, 1010), (557, 357), (555, 148), (4430, 90), (4393, 177),
            (4312, 918)),
        11: ((3456, 863), (5108, 410), (1042, 75), (4567, 1231), (6237, 54), (4953, 121),
             (6545, 461)),
        18: ((4477, 1329), (6671, 39), (1464, 637), (6886, 202), (6773, 63), (6294, 78),
             (6869, 65)),
        25: ((5294, 1860), (6815, 20), (2254, 1006), (6693, 130), (6973, 45), (6786, 55),
             (6920, 58)),
    },
    "ant": {
        4: ((4204, 289), (4218, 240), (2722, 36), (3837, 259), (4602, 151), (4523, 224),
            (4623, 150)),
        11: ((4577, 145), (4105, 223), (2510, 27), (4515, 239), (4342, 211), (4500, 189),
             (4541, 152)),
        18: ((4736, 75), (4690, 102), (2755, 183), (4703, 40), (4649, 101), (4713, 83),
             (4738, 82)),
        25: ((4682, 89), (4735, 54), (2656, 85), (4690, 75), (4733, 35), (4753, 64),
             (4805, 45)),
    },
    "halfcheetah": {
        4: ((2070, 528), (3254, 133), (558, 148), (359, 266), (3688, 400), (3625, 142),
            (3660, 406)),
        11: ((3979, 61), (4015, 344), (2655, 253), (4063, 50), (4021, 233), (3922, 173),
             (4043, 221)),
        18: ((3911, 416), (4393, 212), (2666, 186), (4185, 30), (4520, 53), (4496, 95),
             (4523, 65)),
        25: ((4027, 91), (4423, 104), (3619, 257), (4227, 26), (4532, 44), (4417, 90),
             (4436, 67)),
    },
    # the paper's Humanoid counts (80, 160, 240); ours are at most 25 (chapter's table)
    "humanoid": {
        80: ((6145, 1918), (8268, 1401), (2048, 1140), (8789, 639), (8810, 657), (8321, 822),
             (8504, 562)),
        160: ((6722, 1126), (9994, 1053), (6023, 1006), (9507, 832), (9677, 535),
              (9892, 753), (9774, 785)),
        240: ((8834, 998), (9430, 906), (8091, 878), (9185, 492), (9798, 281), (9381, 539),
              (9294, 385)),
    },
}


# The paper's Table II: (expert, random) returns per task, each (mean, std) over its
# evaluation trajectories, on Gym's scale: what its Table III is scaled by, as ours is by our
# experts and random policies.
PAPER_TABLE_II = {
    "cartpole": ((200, 0), (17, 4)), "reacher1": ((-4.5, 1.7), (-93.7, 4.8)),
    "hopper": ((3624, 19), (8, 6)), "walker": ((7002, 33), (-2, 3)),
    "ant": ((4838, 231), (8, 124)), "halfcheetah": ((4501, 111), (101, 80)),
    "humanoid": ((10400, 89), (101, 35)),
}


def paper_scaled(task: str, mean: float) -> float:
    """A return of the paper's Table III on the scaled axis (random 0, expert 1), by its own
    Table II."""
    (expert, _), (random, _) = PAPER_TABLE_II[task]
    return (mean - random) / (expert - random)


# Entries read from the shifted block or with a digit of the std lost: (task, n, learner).
UNCERTAIN = {
    ("reacher1", 18, "pwil"): "std's last digit from the shifted block",
    ("reacher1", 18, "ndi"): "from the shifted block", ("reacher1", 18, "dc"): "shifted block",
    ("reacher1", 25, "pwil"): "std's last digit from the shifted block",
    ("reacher1", 25, "ndi"): "from the shifted block", ("reacher1", 25, "dc"): "shifted block",
    ("hopper", 4, "pwil"): "std 20 or 200", ("hopper", 4, "ndi"): "from the shifted block",
    ("hopper", 4, "dc"): "from the shifted block",
    ("hopper", 11, "pwil"): "std 18 or 189", ("ant", 11, "pwil"): "std 211 or 21",
    ("halfcheetah", 4, "pwil"): "std 40 or 400", ("walker", 25, "pwil"): "std 4 or 45",
    ("humanoid", 80, "pwil"): "std 65 or 657", ("ant", 4, "pwil"): "std 15 or 151",
}


def load(name: str = RESULT) -> dict | None:
    """The aggregate, or None while the study has not been aggregated."""
    return report.stored(name)


def paper_rows() -> list[dict]:
    """The paper's Table III as long rows: task, n_demos, learner, mean, std, and the mean
    scaled by the paper's Table II (``paper_scaled``)."""
    return [{"task": t, "n_demos": n, "row": r, "paper_mean": m, "paper_std": s,
             "paper_scaled": paper_scaled(t, m), "uncertain": (t, n, r) in UNCERTAIN}
            for t, by_n in PAPER_TABLE_III.items() for n, cols in by_n.items()
            for r, (m, s) in zip(PAPER_COLUMNS, cols)]


def table(rec: dict, measure: str = "scaled_return") -> list[dict]:
    """Our Table III: per task and demonstration count, each learner's mean and 95% interval
    over seeds (and how many), the expert row's floor beside it."""
    out = []
    for r in rec["table"]:
        if f"{measure}_mean" not in r:
            continue
        out.append({"task": r["task"], "n_demos": r["n_demos"], "row": r["row"],
                    measure: fmt_entry(r, measure, 2),
                    "seeds": r["n_seeds"]})
    return out


def figure9(rec: dict, task: str, measure: str = "scaled_return") -> dict:
    """``{learner: (n_demos, mean, lo, hi)}`` on ``task``: Figure 9's lines with intervals."""
    lines: dict = {}
    for r in sorted(rec["table"], key=lambda r: r["n_demos"]):
        if r["task"] == task and f"{measure}_mean" in r:
            lines.setdefault(r["row"], []).append((r["n_demos"], *band(r, measure)))
    return {k: tuple(np.array(v, float).T) for k, v in lines.items()}


def figure11(rec: dict, task: str, n_demos: int | None = None) -> dict:
    """``{learner: [(steps, scaled_return), ...] per seed}``: the checkpoint curves at
    ``n_demos`` (default: the task's fewest count with curves), deterministic evaluations,
    not training-episode returns, each cut at the checkpoints every curve there reached
    (``_common_curves``, as the claims read them)."""
    obs = [o for o in rec["observations"] if o["task"] == task and o.get("curve")]
    if n_demos is None and obs:
        n_demos = min(o["n_demos"] for o in obs)
    out: dict = {}
    for o in _common_curves([o for o in obs if o["n_demos"] == n_demos]):
        out.setdefault(o["row"], []).append(
            [(p["steps"], p["scaled_return"]) for p in o["curve"]])
    return out


def rank_agreement(rec: dict, task: str, n_demos: int) -> dict:
    """Kendall's tau between the paper's ordering of the learners (its mean returns) and ours
    (mean scaled returns) on ``task`` at ``n_demos``, over the learners both have; None where
    fewer than three are shared.  Scales differ, orderings compare."""
    paper = dict(zip(PAPER_COLUMNS, (m for m, _ in PAPER_TABLE_III.get(task, {}).get(
        n_demos, ()))))
    ours = {r["row"]: r["scaled_return_mean"] for r in rec["table"]
            if r["task"] == task and r["n_demos"] == n_demos and "scaled_return_mean" in r}
    shared = sorted(set(paper) & set(ours))
    if len(shared) < 3:
        return {"task": task, "n_demos": n_demos, "learners": shared, "tau": None}
    return {"task": task, "n_demos": n_demos, "learners": shared,
            "tau": stats.kendall_tau([paper[k] for k in shared], [ours[k] for k in shared]),
            "paper_best": max(shared, key=paper.get), "our_best": max(shared, key=ours.get)}


# The paper's Table III / Figure 9 / Figure 11 claims are declared in ``claims``
# (:data:`claims.TABLE_THREE`) and judged here, each claim one Holm family over its (task,
# demonstration count) pairs.
CLAIMS = _claims.TABLE_THREE
FEWEST_ONLY = (_claims.DC_BEATS_DRIL_FEW, _claims.DC_FASTER, _claims.DC_STABLE,
               _claims.DC_STABLE_DRIL)


def _lowest_other(obs) -> list[dict]:
    """Per (task, n_demos, seed) with every learner present: the lowest return of the
    learners other than GPRIL, as a row of its own."""
    groups: dict = {}
    for o in obs:
        groups.setdefault((o["task"], o["n_demos"], o["seed"]), {})[o["row"]] = o
    out = []
    for (task, n, seed), rows in groups.items():
        others = [rows[r]["scaled_return"] for r in LEARNERS if r != "gpril" and r in rows]
        if "gpril" in rows and len(others) == len(LEARNERS) - 1:
            out.append({"task": task, "n_demos": n, "seed": seed, "row": "lowest-other",
                        "scaled_return": min(others)})
    return out


def _common_curves(obs: list[dict]) -> list[dict]:
    """The observations with each Figure 11 curve cut at the last checkpoint every curve of its
    (task, count) reached.  The marks are spaced over the grid's interactions, but the
    PPO-based learners run whole batches (98,304 of 100,000 interactions at the lesson
    budget) and so miss the last mark: uncut, DC's and GPRIL's curves would average and
    spread over one more, later checkpoint than GAIL's.  Declared when this was found, after
    the curves had run; it changes which points a claim reads, never a point."""
    fewest: dict = {}
    for o in obs:
        if o.get("curve"):
            key = (o["task"], o["n_demos"])
            fewest[key] = min(fewest.get(key, len(o["curve"])), len(o["curve"]))
    # the checkpoints are the same marks for every learner, each recorded at the step its
    # learner reached it: keep the first ones all curves have (as ablations.eval_curves)
    return [{**o, "curve": sorted(o["curve"], key=lambda p: p["steps"])[
                :fewest[(o["task"], o["n_demos"])]]}
            if o.get("curve") else o for o in obs]


def _curve_mean(o) -> float | None:
    c = o.get("curve")
    return float(np.mean([p["scaled_return"] for p in c])) if c else None


def _curve_spread(o) -> float | None:
    return _ablations.late_spread({"eval_curve": o.get("curve")})


def verdicts(rec: dict, competence: dict | str | None = "stored") -> list:
    """Each claim of :data:`CLAIMS` (a :class:`verdicts.Verdict`), judged over the (task,
    count) pairs that have run: DRIL's and the curves' at each task's fewest demonstrations
    only, BC's growth once per task (its fewest against its most, keyed ``"F -> M"``; the
    benchmark's counts differ by task, the first grid's do not).  ``competence``:
    the stored competence gate by default (:func:`competence.mapping`: a learner not shown
    competent is not judged), or a mapping learner -> phrase, ``{}`` for none."""
    competence = _claims.competence_of(competence, rec)
    obs = [{**o, "curve_mean": _curve_mean(o), "curve_spread": _curve_spread(o)}
           for o in _common_curves([o for o in rec["observations"] if o["row"] != "expert"])]
    obs += _lowest_other(obs)
    # each task's own fewest and most demonstrations (the benchmark's counts differ by task):
    # the grid's design where the aggregate records it, so that a partial grid whose fewest
    # count has not run yet does not judge the fewest-only claims at its most
    counts: dict = {}
    for o in obs:
        counts.setdefault(o["task"], set()).add(o["n_demos"])
    for d in rec.get("design") or []:
        if d.get("counts") and d["task"] in counts:
            counts[d["task"]] = set(d["counts"])
    fewest = {t: min(c) for t, c in counts.items()}
    most = {t: max(c) for t, c in counts.items()}
    out = []
    if not counts:
        return out
    for claim in CLAIMS:
        if claim is _claims.BC_IMPROVES:
            if all(len(c) < 2 for c in counts.values()):
                continue
            group = [{**o, "n_demos": f"{fewest[o['task']]} -> {most[o['task']]}",
                      "row": "bc@fewest" if o["n_demos"] == fewest[o["task"]] else "bc@most"}
                     for o in obs if o["row"] == "bc" and len(counts[o["task"]]) > 1
                     and o["n_demos"] in (fewest[o["task"]], most[o["task"]])]
        else:
            group = [o for o in obs if claim not in FEWEST_ONLY
                     or o["n_demos"] == fewest[o["task"]]]
        out.append(_verdicts.judge_claim(claim, group, by=("task", "n_demos"),
                                         competence=competence, unit="task-count pairs",
                                         across=True))
    return out


def old_new(old: dict, new: dict | None, competence: dict | str | None = "stored") -> list:
    """Chapter 06's old -> new table: per claim of :data:`CLAIMS`, its verdict on the first
    grid (``old``: ``table3``, judged as it was published, every learner judged: it ran
    before the gate) beside its verdict on the benchmark with headroom (``new``, under the
    gate: a learner that failed it is not judged), or "not run yet"."""
    then = {v.claim: v for v in verdicts(old, competence={})}
    now = {v.claim: v for v in verdicts(new, competence)} if new else {}
    return [{"claim": c.name, "first grid": then[c.name].verdict if c.name in then else "",
             "benchmark with headroom": now[c.name].verdict if c.name in now
             else "not run yet"} for c in CLAIMS]


def across_tasks(rec: dict, n_demos=None, target: str = "dc", measure: str = "scaled_return",
                 seed: int = 0) -> list[dict]:
    """rliable's headline (Agarwal et al. 2021) over the (task, count) pairs where every
    learner ran (``n_demos``: one count, or all): per learner, the IQM over pairs and seeds
    with its stratified bootstrap interval, and the probability that a ``target`` run beats
    one of the learner's on the same pair (``P(dc > X)``) with its interval."""
    by: dict = {}
    for o in rec["observations"]:
        if o["row"] in LEARNERS and o.get(measure) is not None and (
                n_demos is None or o["n_demos"] == n_demos):
            by.setdefault(o["row"], {}).setdefault((o["task"], o["n_demos"]), []).append(
                o[measure])
    return [{"learner": r["row"], "IQM": r["IQM"], f"P({target} > learner)": r["P"],
             "pairs": r["strata"], "runs": r["runs"]}
            for r in report.across_tasks(by, LEARNERS, target, seed=seed)]


def figure8(rec1: dict, actions: str = "mean") -> dict:
    """Figure 8 from the Table I aggregate: per task, ``{row: (emd, scaled_return)}`` arrays
    with one point per seed, for the expert, the BC start and every learner that has run."""
    keep = ("expert", "bc") + LEARNERS
    out: dict = {}
    for o in rec1[actions]["observations"]:
        if o["row"] in keep and o.get("emd") is not None and o.get("scaled_return") is not None:
            out.setdefault(o["task"], {}).setdefault(o["row"], []).append(
                (o["emd"], o["scaled_return"]))
    return {t: {r: tuple(np.array(v, float).T) for r, v in rows.items()}
            for t, rows in out.items()}


__all__ = ["CLAIMS", "FEWEST_ONLY", "LEARNERS", "PAPER_COLUMNS", "PAPER_TABLE_II",
           "PAPER_TABLE_III", "RESULT", "UNCERTAIN", "across_tasks", "figure11", "figure8",
           "figure9", "kendall_tau", "load", "paper_rows", "paper_scaled", "rank_agreement",
           "table", "verdicts"]
