"""The paper's claims about DC, judged one by one against our stored results.

Chapter 04 prints :func:`verdicts` and its prose quotes them; ``tests/test_claims_dc.py`` checks
that what the prose says still holds in the files.  Every verdict is computed here, from the
result files of ``dc-lesson bench dc | dc-ablation | dc-lr | gail | gail-lr``, by a rule stated
in the claim's ``rule``: nothing is typed in by hand.

Verdicts: ``reproduced`` (the rule holds everywhere it is tested), ``partly reproduced`` (in
some tasks or measures, not all), ``not reproduced``, or ``not tested`` (a file is missing).
With three seeds, a difference smaller than the spread over seeds is weak evidence; the
evidence strings give means and standard deviations so a reader can judge.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dc_lesson.storage import read_result

MEASURES = ("emd", "kl", "rkl")
COLLAPSE_SHARE = 0.8    # a policy with at least this share of episodes in one mode collapsed


@dataclasses.dataclass(frozen=True)
class Verdict:
    claim: str
    source: str        # where the paper makes it
    rule: str          # how we decide, from our files
    verdict: str
    evidence: str


def _load(name):
    try:
        return read_result(name)
    except FileNotFoundError:
        return None


def table_one(dc_record: dict | None = None, gail_record: dict | None = None) -> list[dict]:
    """The rows of our Table I: per task, BC (DC's start), GAIL and DC, with mean and std over
    seeds of the scaled return, EMD, KL and RKL, and the mean mode shares.

    BC's row comes from ``dc_modes.json`` (the start of the DC runs; GAIL's start is the same
    warm start, trained with the same seeds)."""
    dc_record = dc_record or _load("dc_modes.json")
    gail_record = gail_record or _load("gail_modes.json")
    rows = []
    for s in (dc_record or {}).get("summary", []):
        rows.append({**s, "method": s["method"].upper()})
    for s in (gail_record or {}).get("summary", []):
        if s["method"].upper() == "GAIL":
            rows.append({**s, "method": "GAIL"})
    order = {"BC": 0, "GAIL": 1, "DC": 2}
    tasks = list(dict.fromkeys(r["task"] for r in rows))
    return sorted(rows, key=lambda r: (tasks.index(r["task"]), order.get(r["method"], 9)))


def _by(rows, task, method):
    return next((r for r in rows if r["task"] == task and r["method"] == method), None)


def _grade(hits: int, total: int) -> str:
    if total == 0:
        return "not tested"
    return "reproduced" if hits == total else ("not reproduced" if hits == 0
                                               else "partly reproduced")


def claim_lowest_divergences(rows) -> Verdict:
    rule = ("for each multi-mode task and each of EMD, KL, RKL: DC's mean over seeds is the "
            "lowest of BC, GAIL and DC")
    hits, total, parts = 0, 0, []
    for task in dict.fromkeys(r["task"] for r in rows):
        trio = {m: _by(rows, task, m) for m in ("BC", "GAIL", "DC")}
        if any(v is None for v in trio.values()):
            continue
        won = [m for m in MEASURES
               if trio["DC"][f"{m}_mean"] <= min(trio["BC"][f"{m}_mean"],
                                                 trio["GAIL"][f"{m}_mean"])]
        hits, total = hits + len(won), total + len(MEASURES)
        parts.append(f"{task}: DC lowest in {', '.join(won) if won else 'none'}")
    return Verdict("DC obtains the lowest EMD, KL and RKL in all multi-mode tasks",
                   "Table I", rule, _grade(hits, total), "; ".join(parts) or "no results")


def claim_higher_return(rows) -> Verdict:
    rule = "for each multi-mode task: DC's mean scaled return is above BC's and GAIL's"
    hits, total, parts = 0, 0, []
    for task in dict.fromkeys(r["task"] for r in rows):
        trio = {m: _by(rows, task, m) for m in ("BC", "GAIL", "DC")}
        if any(v is None for v in trio.values()):
            continue
        total += 1
        v = {m: trio[m]["scaled_return_mean"] for m in trio}
        s = {m: trio[m]["scaled_return_std"] for m in trio}
        hits += v["DC"] > max(v["BC"], v["GAIL"])
        parts.append(f"{task}: " + ", ".join(f"{m} {v[m]:.2f} ± {s[m]:.2f}" for m in v))
    return Verdict("DC has a higher scaled return than the baselines on multi-mode tasks",
                   "Figure 8", rule, _grade(hits, total), "; ".join(parts) or "no results")


def claim_gail_collapses(rows) -> Verdict:
    rule = (f"for each multi-mode task: GAIL puts at least {COLLAPSE_SHARE:.0%} of its "
            f"evaluation episodes (mean over seeds) in one mode")
    hits, total, parts = 0, 0, []
    for task in dict.fromkeys(r["task"] for r in rows):
        g = _by(rows, task, "GAIL")
        if g is None or not g.get("mode_shares_mean"):
            continue
        total += 1
        top = max(g["mode_shares_mean"], key=g["mode_shares_mean"].get)
        share = g["mode_shares_mean"][top]
        hits += share >= COLLAPSE_SHARE
        parts.append(f"{task}: GAIL's largest mode {top} {share:.2f}")
    return Verdict("GAIL collapses onto one mode of the expert's behaviour", "Figures 1, 7, 10",
                   rule, _grade(hits, total), "; ".join(parts) or "no results")


def claim_dc_keeps_modes(rows) -> Verdict:
    rule = (f"for each multi-mode task: DC has no mode with {COLLAPSE_SHARE:.0%} or more of its "
            f"episodes, and visits every mode the expert visits in at least 5% of its episodes "
            f"(means over seeds)")
    hits, total, parts = 0, 0, []
    for task in dict.fromkeys(r["task"] for r in rows):
        d = _by(rows, task, "DC")
        if d is None or not d.get("mode_shares_mean"):
            continue
        total += 1
        shares = d["mode_shares_mean"]
        ok = max(shares.values()) < COLLAPSE_SHARE and min(shares.values()) >= 0.05
        hits += ok
        parts.append(f"{task}: " + ", ".join(f"{k} {v:.2f}" for k, v in shares.items()))
    return Verdict("DC preserves all of the expert's modes", "Figures 1, 7, 10", rule,
                   _grade(hits, total), "; ".join(parts) or "no results")


def claim_loops(ablation: dict | None) -> Verdict:
    rule = ("the scaled return with L = 4 loops is above L = 1, and one long loop is within "
            "0.1 of L = 4 in less wall time (one seed)")
    if not ablation:
        return Verdict("DC improves with more P_w loops; one long loop is a cheaper equal",
                       "Figure 3", rule, "not tested", "no dc_ablation.json")
    rows = {r["label"]: r for r in ablation["loops"]}
    loops = [r for r in ablation["loops"] if r["label"].startswith("L =")]
    long_ = next(r for r in ablation["loops"] if r["label"].startswith("1 loop"))
    first, last = loops[0], loops[-1]
    improves = last["dc"]["scaled_return"] > first["dc"]["scaled_return"]
    cheap = (abs(long_["dc"]["scaled_return"] - last["dc"]["scaled_return"]) <= 0.1
             and long_["dc"]["train_seconds"] < last["dc"]["train_seconds"])
    evidence = "; ".join(f"{r['label']}: {r['dc']['scaled_return']:.2f} in "
                         f"{r['dc']['train_seconds']:.0f} s" for r in rows.values())
    return Verdict("DC improves with more P_w loops; one long loop is a cheaper equal",
                   "Figure 3", rule, _grade(improves + cheap, 2), evidence)


def claim_lr(dc_lr: dict | None, gail_lr: dict | None) -> Verdict:
    rule = ("DC's worst mean scaled return over the learning rates is at least GAIL's worst, "
            "and GAIL's mean at lr >= 1e-3 is below its mean at lr < 1e-3")
    if not dc_lr or not gail_lr:
        return Verdict("DC is robust to the learning rate; GAIL fails at 1e-3 and above",
                       "Figure 4", rule, "not tested", "a learning-rate file is missing")
    d = {s["lr"]: s["scaled_return_mean"] for s in dc_lr["summary"]}
    g = {s["lr"]: s["scaled_return_mean"] for s in gail_lr["summary"]}
    robust = min(d.values()) >= min(g.values())
    high = [v for k, v in g.items() if k >= 1e-3]
    low = [v for k, v in g.items() if k < 1e-3]
    gail_fails = bool(high and low and np.mean(high) < np.mean(low))
    evidence = ("DC " + ", ".join(f"{k:g}: {v:.2f}" for k, v in sorted(d.items()))
                + "; GAIL " + ", ".join(f"{k:g}: {v:.2f}" for k, v in sorted(g.items())))
    return Verdict("DC is robust to the learning rate; GAIL fails at 1e-3 and above",
                   "Figure 4", rule, _grade(robust + gail_fails, 2), evidence)


def claim_convergence(dc_record: dict | None) -> Verdict:
    rule = ("in every DC run of bench dc, the mean L1 parameter change per iteration over the "
            "last quarter of a loop is below that over the loop's first quarter")
    if not dc_record:
        return Verdict("The ADMM update converges: pi's parameter change shrinks", "Figure 6",
                       rule, "not tested", "no dc_modes.json")
    hits, total, ratios = 0, 0, []
    for r in dc_record["runs"]:
        change = np.asarray(r["curve"]["param_change_l1"], np.float64)
        per_loop = r["config"]["iterations"]
        for start in range(0, len(change), per_loop):
            seg = change[start:start + per_loop]
            q = max(1, len(seg) // 4)
            total += 1
            ratios.append(seg[-q:].mean() / seg[:q].mean())
            hits += ratios[-1] < 1
    return Verdict("The ADMM update converges: pi's parameter change shrinks", "Figure 6",
                   rule, _grade(hits, total),
                   f"last/first quarter ratio: median {np.median(ratios):.2f}, range "
                   f"{min(ratios):.2f} to {max(ratios):.2f} over {total} loops")


def claim_faster_than_gail(dc_record: dict | None, gail_record: dict | None) -> Verdict:
    rule = ("for each multi-mode task: the mean training-episode return over the first third "
            "of the interactions is higher for DC than for GAIL (stochastic policies, means over "
            "seeds)")
    if not dc_record or not gail_record:
        return Verdict("DC reaches a higher return than GAIL with few environment interactions",
                       "Figure 5", rule, "not tested", "a file is missing")
    hits, total, parts = 0, 0, []
    for task in dc_record["tasks"]:
        d_runs = [r for r in dc_record["runs"] if r["task"] == task]
        g_runs = [r for r in gail_record["runs"] if r["task"] == task]
        if not d_runs or not g_runs:
            continue
        horizon = max(max(r["curve"]["env_steps"]) for r in d_runs) / 3
        d = [v for r in d_runs for s, v in zip(r["curve"]["env_steps"],
                                                r["curve"]["episode_return"])
             if v is not None and s <= horizon]
        g = [v for r in g_runs for s, v in zip(r["curve"]["steps"],
                                                r["curve"]["episode_return"])
             if s <= horizon]
        if not d or not g:
            continue
        total += 1
        hits += np.mean(d) > np.mean(g)
        parts.append(f"{task}: DC {np.mean(d):.0f}, GAIL {np.mean(g):.0f}")
    return Verdict("DC reaches a higher return than GAIL with few environment interactions",
                   "Figure 5", rule, _grade(hits, total), "; ".join(parts) or "no results")


def verdicts() -> list[Verdict]:
    """Every claim, judged against the stored result files."""
    dc_record, gail_record = _load("dc_modes.json"), _load("gail_modes.json")
    rows = table_one(dc_record, gail_record)
    return [claim_lowest_divergences(rows), claim_higher_return(rows),
            claim_gail_collapses(rows), claim_dc_keeps_modes(rows),
            claim_loops(_load("dc_ablation.json")),
            claim_lr(_load("dc_lr.json"), _load("gail_lr.json")),
            claim_faster_than_gail(dc_record, gail_record),
            claim_convergence(dc_record)]


__all__ = ["COLLAPSE_SHARE", "Verdict", "table_one", "verdicts"]
