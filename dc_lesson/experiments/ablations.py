"""The paper's ablations on Hopper (Figures 3-6), read from their cell aggregates.

The book reads the rerun on the benchmark's hopper start (``ablations.json``,
``studies.ablations``: BC on 11 subsampled demonstrations, a start with room, DC as the
competence gate runs it, no GAIL rows since GAIL failed the gate) through :func:`from_rerun`,
which :func:`load` returns by default once it is stored.  ``load("first")`` gives the first
run, kept as its record (chapter 02 draws its GAIL sweep): three studies, each a grid of cells
on ``hopper`` with 11 whole demonstrations (the paper's setting) and the seeds of
``budget.seeds_for("hopper")``, every RL run from the seed's BC warm start:

* ``dc_ablation.json``: rows ``dc-loops=L`` (L = 1..4 loops of one fixed number of
  iterations), ``dc-loops=1-long`` (one loop as long as L = 4: the same interactions),
  ``dc-update=admm`` (consensus ADMM) and ``dc`` (the defaults: two loops, averaging);
* ``dc_lr.json`` and ``gail_lr.json``: rows ``dc-lr=X`` and ``gail-lr=X``, one learning rate
  for every optimiser of the learner, ``budget.lr_sweep_steps`` interactions each.  GAIL here
  is chapter 02's (``gail.sized``: it explores at the warm start's log-std -0.5, as DC does),
  not Table I's tuned start of -2.

Every cell keeps a deterministic evaluation curve (``eval_curve``: mean-action episodes at
evenly spaced checkpoints) and DC's cells their per-iteration log (``curve``: the L1 distance
between pi and pi' before averaging, the change of pi's parameters, ADMM's residuals).

The claims are declared in :mod:`claims` (:data:`claims.ABLATIONS`), each with one measure per
seed and one paired comparison, and judged here by the one rule of :mod:`verdicts`.  Where the
paper's comparison is confounded we judge the confound too: Figure 3 compares L = 4 with L = 1
at four times the interactions, so ``claims.EQUAL_BUDGET`` asks whether the loops or the
interactions did it.
"""

from __future__ import annotations

import numpy as np

from dc_lesson.experiments import claims as _claims, verdicts as _verdicts
from dc_lesson.storage import read_result

TASK = "hopper"
FILES = {"ablation": "dc_ablation.json", "dc_lr": "dc_lr.json", "gail_lr": "gail_lr.json"}
DEFAULT_LR = 3e-4        # DC's and GAIL's own rate: the pair Figure 5 compares
FAILING_LR = 1e-3        # the paper: GAIL "tends to fail/crash" at this rate and higher
EARLY = 0.5              # Figure 5: the first half of the interactions
LOOP_ROWS = ("dc-loops=1", "dc-loops=2", "dc-loops=3", "dc-loops=4", "dc-loops=1-long")
CLAIMS = _claims.ABLATIONS
RERUN = "ablations.json"   # the rerun on the benchmark's hopper start (issue 41, item 5)


def load(which: str = "rerun") -> dict:
    """The ablations' aggregates: ``"rerun"`` (the default) the rerun on the benchmark's
    hopper start (``ablations.json``, :func:`from_rerun`) once it is stored, else the first
    three studies; ``"first"`` the first three studies (``dc_ablation``, ``dc_lr``,
    ``gail_lr``: chapter 02 still draws GAIL's learning-rate sweep from them).  ``{}`` when
    none is stored in the cell format."""
    if which not in ("rerun", "first"):
        raise ValueError(f"ablations.load: which={which!r}; use 'rerun' or 'first'")
    if which == "rerun":
        try:
            rec = read_result(RERUN)
        except FileNotFoundError:
            rec = None
        if rec and rec.get("observations"):
            return from_rerun(rec)
    out = {}
    for key, name in FILES.items():
        try:
            rec = read_result(name)
        except FileNotFoundError:
            continue
        if "observations" in rec and "cells" in rec:    # not a pre-cell whole-grid file
            out[key] = rec
    return out


def observations(recs: dict) -> list[dict]:
    """All learner observations of the aggregates in ``recs`` (:func:`load`; the BC starts
    once per seed)."""
    obs, starts = [], set()
    for rec in recs.values():
        for o in rec["observations"]:
            if o["row"] == "expert":
                continue
            if o["row"] == "bc":
                if o["seed"] in starts:
                    continue
                starts.add(o["seed"])
            obs.append(o)
    return obs


def from_rerun(rec: dict) -> dict:
    """The ``ablations`` aggregate (the rerun on the benchmark's start: ``studies.ablations``)
    in the form :func:`verdicts` and the figures read, as ``{"ablation": ...}``: each cell's
    checkpoint curve as ``eval_curve``, DC's iteration log as ``curve`` with its iterations
    per loop, the seed's start as a ``bc`` row once, and DC's default row also as
    ``dc-lr=3e-4`` (the rerun runs DC's own rate once, not again in the sweep).  No GAIL rows:
    GAIL failed the gate, so its claims say "not judged"."""
    from dc_lesson.experiments import competence as _gate
    obs, seen = [], set()
    for o in rec["observations"]:
        if o["row"] == "expert":
            continue
        if o.get("start") and o["seed"] not in seen:
            seen.add(o["seed"])
            obs.append({"row": "bc", "task": o["task"], "n_demos": o["n_demos"],
                        "seed": o["seed"], **o["start"]})
        new = {k: v for k, v in o.items() if k not in ("curve", "log", "start")}
        new["eval_curve"], new["curve"] = o.get("curve"), o.get("log")
        obs.append(new)
        if o["row"] == "dc":
            obs.append({**new, "row": f"dc-lr={DEFAULT_LR:g}"})
    table = list(rec.get("table", []))
    table += [{**r, "row": f"dc-lr={DEFAULT_LR:g}"} for r in table if r["row"] == "dc"]
    keep = ("benchmark", "budget", "seeds", "complete", "cells", "revision", "time",
            "command", "steps", "design", "paired", "variants", _gate.GRID_MARK)
    return {"ablation": {**{k: rec[k] for k in keep if k in rec}, "observations": obs,
                         "table": table}}


def lr_of(row: str) -> float | None:
    return float(row.split("-lr=")[1]) if "-lr=" in row else None


# -- per-seed measures --------------------------------------------------------------------------

def _curve_points(o) -> tuple[np.ndarray, np.ndarray] | None:
    pts = o.get("eval_curve") or []
    if not pts:
        return None
    return (np.array([p["steps"] for p in pts], float),
            np.array([p["scaled_return"] for p in pts], float))


def early_return(o) -> float | None:
    c = _curve_points(o)
    if c is None:
        return None
    steps, ret = c
    keep = steps <= EARLY * steps.max()
    return float(ret[keep].mean()) if keep.any() else None


def late_spread(o) -> float | None:
    c = _curve_points(o)
    if c is None:
        return None
    steps, ret = c
    keep = steps > EARLY * steps.max()
    return float(ret[keep].std()) if keep.sum() >= 2 else None


def log_gap_ratio(o, key: str = "pi_pi_prime_l1") -> float | None:
    """Mean over loops of log(last quarter / first quarter) of ``key`` per iteration."""
    c = (o.get("curve") or {}).get(key)
    per_loop = o.get("iterations")
    if not c or not per_loop:
        return None
    x = np.asarray([np.nan if v is None else v for v in c], np.float64)
    ratios = []
    for start in range(0, len(x), per_loop):
        seg = x[start:start + per_loop]
        q = max(1, len(seg) // 4)
        first, last = np.nanmean(seg[:q]), np.nanmean(seg[-q:])
        if np.isfinite(first) and np.isfinite(last) and first > 0 and last > 0:
            ratios.append(np.log(last / first))
    return float(np.mean(ratios)) if ratios else None


def worst_lr(obs, learner: str) -> list[dict]:
    """Per seed, the lowest final scaled return over ``learner``'s rates (all four needed)."""
    rows = [o for o in obs if o["row"].startswith(learner + "-lr=")]
    rates = {o["row"] for o in rows}
    by_seed: dict = {}
    for o in rows:
        by_seed.setdefault(o["seed"], []).append(o["scaled_return"])
    return [{"task": TASK, "seed": s, "row": learner, "worst_lr_return": float(min(v))}
            for s, v in by_seed.items() if len(v) == len(rates)]


def at_default_lr(obs) -> list[dict]:
    """The DC and GAIL cells at their default rate, renamed ``dc`` and ``gail``."""
    out = []
    for o in obs:
        lr = lr_of(o["row"])
        if lr is not None and np.isclose(lr, DEFAULT_LR):
            out.append({**o, "row": o["row"].split("-lr=")[0]})
    return out


def book_verdicts(actions: str = "mean", competence: dict | str | None = "stored") -> list:
    """Table I's claims on the stored aggregate (:func:`claims.verdicts`) followed by the
    hopper ablations' (:func:`verdicts`): every stored verdict of chapters 04 and 06."""
    return (_claims.verdicts(actions=actions, competence=competence)
            + verdicts(competence=competence))


def verdicts(recs: dict | None = None, competence: dict | str | None = "stored") -> list:
    """Each claim of :data:`claims.ABLATIONS`, judged on the stored aggregates (or ``recs``);
    one task, so each is its own family."""
    c = _claims
    recs = load() if recs is None else recs
    competence = _claims.competence_of(competence, *recs.values())
    obs = observations(recs)
    judge = lambda claim, o, **kw: _verdicts.judge_claim(claim, o, [TASK], competence=competence,
                                                        **kw)
    out = [judge(claim, obs) for claim in (c.LOOPS, c.EQUAL_BUDGET, c.LONG_LOOP)]
    starts = [o for o in obs if o["row"] == "bc"]    # the start's level for the gate
    out.append(judge(c.LR_ROBUST, worst_lr(obs, "dc") + worst_lr(obs, "gail") + starts))
    default = [o for o in obs if o["row"] == f"dc-lr={DEFAULT_LR:g}"]
    worst = {o["seed"]: o["worst_lr_return"] for o in worst_lr(obs, "dc")}
    out.append(judge(c.LR_WIDE, starts + [{**o, "row": "dc"} for o in default] + [
        {**o, "row": "dc-worst", "scaled_return": worst[o["seed"]]} for o in default
        if o["seed"] in worst]))
    default = at_default_lr(obs) + starts
    out.append(judge(c.FASTER, default, measure=early_return))
    out.append(judge(c.STABLE, default, measure=late_spread))
    dc = [o for o in obs if o["row"] == "dc"]
    zero = [{**o, "row": "zero"} for o in dc]
    out.append(judge(c.CONVERGES, dc + zero, measure=lambda o: (
        0.0 if o["row"] == "zero" else log_gap_ratio(o))))
    out.append(gail_against_start(recs, competence))
    return out


def gail_against_start(recs: dict, competence: dict | str | None = "stored"
                       ) -> _verdicts.Verdict:
    """:data:`claims.GAIL_LR_START`: per rate of the ``gail_lr`` sweep, GAIL's final scaled
    return against the seed's own BC start, one Holm family over the rates the paper says
    GAIL fails at (:data:`FAILING_LR` and up; the members are keyed by the rate; the start
    gates read the BC start's level).  ``recs``: the ablations' aggregates (:func:`load`)."""
    competence = _claims.competence_of(competence, *recs.values())
    obs = observations(recs)
    per_rate, starts = [], [o for o in obs if o["row"] == "bc"]
    rates = sorted({lr_of(o["row"]) for o in obs if o["row"].startswith("gail-lr=")
                    and lr_of(o["row"]) >= FAILING_LR * (1 - 1e-9)})
    for lr in rates:
        per_rate += [{**o, "row": "gail", "lr": f"{lr:g}"} for o in obs
                     if o["row"].startswith("gail-lr=") and np.isclose(lr_of(o["row"]), lr)]
        per_rate += [{**o, "lr": f"{lr:g}"} for o in starts]
    return _verdicts.judge_claim(_claims.GAIL_LR_START, per_rate, [f"{r:g}" for r in rates],
                                 by=("lr",), competence=competence, unit="rates")


# -- what the chapter draws ---------------------------------------------------------------------

def rows_table(recs: dict, rows=None) -> list[dict]:
    """Per row: seeds, final scaled return (mean and 95% interval), interactions per run and
    (DC's rows) iterations per loop."""
    from dc_lesson.experiments.report import fmt_entry
    out = []
    for rec in recs.values():
        steps, per_loop = {}, {}
        for o in rec["observations"]:
            c = o.get("curve") or {}
            s = c.get("env_steps") or c.get("steps")
            if s:
                steps.setdefault(o["row"], set()).add(int(s[-1]))
            if o.get("iterations"):
                per_loop[o["row"]] = int(o["iterations"])
        for r in rec["table"]:
            if r["task"] != TASK or (rows and r["row"] not in rows) or r["row"] == "expert":
                continue
            out.append({"row": r["row"], "seeds": r["n_seeds"],
                        "scaled return": fmt_entry(r, "scaled_return", 2),
                        "interactions": (f"{max(steps[r['row']]):,}" if r["row"] in steps
                                         else "-"),
                        "iterations per loop": per_loop.get(r["row"], "-")})
    seen, unique = set(), []
    for r in out:                       # the BC start appears in each study once
        if r["row"] not in seen:
            seen.add(r["row"])
            unique.append(r)
    return unique


def lr_lines(recs: dict) -> dict:
    """``{learner: (rates, mean, lo, hi)}`` of the final scaled return against the rate (the
    95% t interval over seeds, :func:`report.band`)."""
    from dc_lesson.experiments.report import band
    out = {}
    tables = [r for rec in recs.values() for r in rec.get("table", [])]
    for learner in ("dc", "gail"):
        rows = sorted(((lr_of(r["row"]), r) for r in tables
                       if r["row"].startswith(learner + "-lr=")), key=lambda x: x[0])
        if rows:
            out[learner] = tuple(np.array(v, float) for v in zip(*[
                (lr, *band(r, "scaled_return")) for lr, r in rows]))
    return out


def eval_curves(obs, row: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(steps, per-seed scaled returns) of ``row``'s deterministic evaluation curves, on the
    checkpoints all its seeds share (the same marks; steps rounded to whole batches)."""
    curves = [_curve_points(o) for o in obs if o["row"] == row]
    curves = [c for c in curves if c is not None]
    if not curves:
        return None
    n = min(len(c[0]) for c in curves)
    return curves[0][0][:n], np.array([c[1][:n] for c in curves])


def gap_traces(obs, row: str = "dc", key: str = "pi_pi_prime_l1") -> list[np.ndarray]:
    """Per seed, ``key`` per iteration (pi-pi' distance, or an ADMM residual)."""
    return [np.asarray([np.nan if v is None else v for v in o["curve"][key]], float)
            for o in obs if o["row"] == row and key in (o.get("curve") or {})]


__all__ = ["RERUN", "book_verdicts", "CLAIMS", "at_default_lr", "from_rerun", "early_return", "eval_curves", "gap_traces", "late_spread", "load",
           "log_gap_ratio", "lr_lines", "observations", "rows_table", "verdicts", "worst_lr"]
