"""Does a cheaper density fit change what DC learns: ``dc-lesson perf dc-fit`` (issue 14).

Fitting SoftFlow is the largest part of a DC run (about a third of a lesson run on reacher4),
and ``perf flow-fit`` finds a fit at rk4 step 0.5 (two solver steps instead of four) about
twice as cheap with a held-out likelihood no worse.  A cheaper fit still changes every
number of a DC run, so the question before making it the default is the issue's own: does a
whole DC run at the lesson budget stay within its seed spread?  This benchmark answers it
without touching a stored grid: per seed, one BC warm start (as every study's), then DC
twice from it, today's fit and the cheaper one (the order alternating with the seed), each
timed and evaluated on the same fresh episodes (mean action, returns only).

The rule, declared here before the benchmark first ran: the change keeps learning if the 95%
interval of the paired difference (cheaper - today's, per seed) of the scaled return lies
within +- the seed spread of today's runs (their standard deviation over seeds); otherwise it
is "not shown" (an interval wider than the spread is too few seeds, not a verdict against).
"Today's" arm is DC with the flow's numerics of every run before 2026-12-04
(:data:`~dc_lesson.algorithms.dc.STORED_NUMERICS`: steps 0.25, 4 nodes, torch's tanh).  The
variants (``--variant``): ``fit`` changes the training solver only (``flow.step_size`` 0.5; the
reward still evaluates log P_w at step 0.25), ``fit+reward`` the reward's solver as well
(``flow.eval_step_size`` 0.5), both with torch's tanh as they were measured; ``defaults`` is DC as it
now is by default (steps 0.5, 3 nodes, NumPy's tanh in the flow), the change's own check.
"""

from __future__ import annotations

import copy
import time

import numpy as np
import torch

from dc_lesson import algorithms, budget as _budget, data
from dc_lesson.algorithms import dc as _dc
from dc_lesson.evaluation import evaluate, stats
from dc_lesson.nn import fast
from dc_lesson.storage import check_writable, write_result

# The variants, as changes to the stored numerics (dc.STORED_NUMERICS, torch's tanh);
# "defaults": DC's defaults as they are (None: the preset unchanged).
VARIANTS = {"fit": {"step_size": 0.5},                             # the training solver only
            "fit+reward": {"step_size": 0.5, "eval_step_size": 0.5},   # and the reward's too
            "defaults": None}                                      # today's defaults


def arms(b: _budget.Budget, seed: int, variant: str) -> dict:
    """``{"today": config, "cheaper": config}`` of a seed (see the module's docstring)."""
    stored = _dc.preset(b, seed).with_flow(**_dc.STORED_NUMERICS)
    change = VARIANTS[variant]
    cheaper = _dc.preset(b, seed) if change is None else stored.with_flow(**change)
    return {"today": stored, "cheaper": cheaper}


def _run(task, demos, config, start, n_episodes: int) -> dict:
    t0 = time.perf_counter()
    policy = algorithms.get("dc").train(task, demos, config, policy=copy.deepcopy(start),
                                        progress=False).policy
    seconds = time.perf_counter() - t0
    ev = evaluate.evaluate_policy(task, policy, n_episodes=n_episodes, divergences=False)
    return {"seconds": seconds, "scaled_return": float(ev["scaled_return"])}


@fast.on()   # as the stored runs (dc_lesson.nn.fast)
def run(task: str = "reacher4", seeds=range(5), b: _budget.Budget | None = None,
        n_episodes: int = 20, log=print, variant: str = "fit") -> dict:
    """Today's settings and the ``variant``'s on every seed:
    ``{"rows": [...], "summary": {...}}``."""
    if variant not in VARIANTS:
        raise ValueError(f"perf dc-fit compares the variants {', '.join(VARIANTS)}; not "
                         f"{variant!r}")
    b = b or _budget.current()
    demos = data.load_demos(task, n_trajectories=b.il_demos)
    rows = []
    for seed in seeds:
        start = algorithms.bc.warm_start_policy(demos, seed, max_epochs=b.bc_max_epochs)
        order = list(arms(b, seed, variant).items())
        row = {"seed": int(seed)}
        for name, cfg in (order if seed % 2 == 0 else order[::-1]):
            row[name] = _run(task, demos, cfg, start, n_episodes)
        rows.append(row)
        log(f"seed {seed}: today {row['today']['seconds']:.1f} s, scaled return "
            f"{row['today']['scaled_return']:.3f}; cheaper ({variant}) "
            f"{row['cheaper']['seconds']:.1f} s, {row['cheaper']['scaled_return']:.3f}")
    return {"task": task, "budget": b.name, "variant": variant, "change": VARIANTS[variant],
            "n_episodes": n_episodes, "rows": rows, "summary": summarise(rows)}


def summarise(rows: list[dict]) -> dict:
    """Time ratio (today / cheaper, median over seeds), the paired difference of the scaled
    return with its 95% interval, today's seed spread, and the rule's answer."""
    today = np.array([r["today"]["scaled_return"] for r in rows])
    cheaper = np.array([r["cheaper"]["scaled_return"] for r in rows])
    ratio = float(np.median([r["today"]["seconds"] / r["cheaper"]["seconds"] for r in rows]))
    spread = float(today.std(ddof=1)) if len(rows) > 1 else float("nan")
    diff = stats.paired_diff(cheaper, today) if len(rows) > 1 else None
    kept = diff is not None and -spread <= diff.lo and diff.hi <= spread
    return {"seconds_today": float(np.median([r["today"]["seconds"] for r in rows])),
            "seconds_cheaper": float(np.median([r["cheaper"]["seconds"] for r in rows])),
            "time_ratio": ratio, "seed_spread": spread,
            "difference": None if diff is None else
            {"mean": diff.mean, "lo": diff.lo, "hi": diff.hi},
            "answer": "learning kept (within the seed spread)" if kept else
                      "not shown (the interval reaches beyond the seed spread)"}


def format_summary(result: dict) -> str:
    s = result["summary"]
    d = s["difference"]
    diff = "n/a" if d is None else f"{d['mean']:+.3f} [{d['lo']:+.3f}, {d['hi']:+.3f}]"
    return (f"DC on {result['task']} ({result['budget']}), {len(result['rows'])} seeds: a run "
            f"takes {s['seconds_today']:.1f} s today, {s['seconds_cheaper']:.1f} s with the "
            f"cheaper {result.get('variant', 'fit')} (x{s['time_ratio']:.2f}); scaled return "
            f"cheaper - today = {diff}, "
            f"today's seed spread {s['seed_spread']:.3f}: {s['answer']}")


def main(tasks=None, seeds=range(5), out=None, command: str = "dc-lesson perf dc-fit",
         variant: str = "fit") -> dict:
    if out:
        check_writable(out)
    torch.set_num_threads(1)
    result = run((tasks or ["reacher4"])[0], seeds, variant=variant)
    print(format_summary(result))
    if out:
        write_result(out, {"benchmark": "dc-fit", "threads": 1, **result}, command=command,
                     seeds=list(seeds))
        print(f"wrote {out}")
    return result


__all__ = ["VARIANTS", "arms", "format_summary", "main", "run", "summarise"]
