"""How cheap can DC's density fit be: ``dc-lesson perf flow-fit`` (issue 14, item 3).

DC fits a SoftFlow ``P_w`` to expert states at the start of every run (and refits it in later
loops); in a DC cell that fit is a fifth of the time.  This benchmark fits DC's first flow
(the budget's DC preset: its states, iterations, widths and learning rate) on a task's
demonstration states under cheaper training settings, and scores each fit by its held-out
negative log-likelihood on other expert states, twice: with the flow's own evaluation solver
(what DC's reward uses) and with the reference solver (dopri5 at tolerances 1e-5, the trace
integrated jointly), so that a coarse training solver cannot look good by exploiting a coarse
evaluation.

It also asks the reward's question (issue 14: "the log P reward ... with the fast solver at
the accuracy the reward needs"): for the fit DC now makes (its defaults) of each seed,
:func:`eval_accuracy` times log P_w of the held-out states under each reward setting of
:data:`EVAL_SETTINGS` (the largest rk4 step, the Gauss-Legendre nodes of the trace integral,
the tanh kernel) and scores it against the reference solver (dopri5 at 1e-5, the trace
integrated jointly, torch's tanh): the mean and largest absolute error in nats and the rank
correlation, since DC's scaled reward reads log P_w through its quantiles, so the order of the
states is what it uses.  (Held-out expert states; a learner's states off the expert's manifold
may fare worse.)

Variants (:data:`VARIANTS`), as changes to the fit every stored DC run made
(``dc.STORED_NUMERICS``: rk4 at step 0.25, four steps of the ODE, torch's tanh): rk4 at step
0.5 (two steps), Euler at step 0.25, half the iterations, and DC's defaults today (step 0.5,
NumPy's tanh).  Per variant and seed: fit seconds, both held-out NLLs; the table gives the
time ratio to the stored fit and the reference NLL's change (positive: worse), and
:func:`cheapest_within` names the cheapest variant whose reference NLL is no worse than the
stored fit's by more than ``TOLERANCE`` nats on every seed.  Times are one torch thread; they
drift with the machine's load, the ratios less so.
"""

from __future__ import annotations

import dataclasses
import platform
import time

import numpy as np
import torch

from dc_lesson import budget as _budget, data
from dc_lesson.algorithms import dc as _dc
from dc_lesson.density import softflow as _sf
from dc_lesson.nn import fast
from dc_lesson.storage import check_writable, write_result

TOLERANCE = 0.1   # nats of held-out NLL (reference solver) a cheaper fit may lose

# name -> changes to the stored runs' flow config (the first: no change)
VARIANTS = {
    "stored: rk4, step 0.25": {},
    "rk4, step 0.5": {"step_size": 0.5},
    "euler, step 0.25": {"solver": "euler"},
    "rk4, step 0.25, half the iterations": {"iterations": "half"},
    "DC's defaults: rk4, step 0.5, NumPy's tanh": {"step_size": 0.5, "tanh": "numpy"},
}
DEFAULTS = "DC's defaults: rk4, step 0.5, NumPy's tanh"   # the fit the reward is scored on

# The reward's settings scored: (largest rk4 step, Gauss-Legendre nodes, tanh kernel); the
# stored runs' first, DC's defaults marked.
EVAL_SETTINGS = ((0.25, 4, "torch"), (0.5, 4, "torch"), (0.5, 3, "torch"), (0.5, 3, "numpy"),
                 (0.5, 2, "numpy"))
REWARD_DEFAULT = (0.5, 3, "numpy")


def _ranks(x: np.ndarray) -> np.ndarray:
    return np.argsort(np.argsort(x)).astype(float)


def eval_accuracy(flow, states: torch.Tensor, settings=EVAL_SETTINGS) -> list[dict]:
    """log P_w of ``states`` under each (rk4 step, nodes, tanh kernel) against the reference
    solver (dopri5 at 1e-5, the trace integrated jointly, torch's tanh): seconds, mean and
    largest absolute error (nats), Spearman's rank correlation."""
    own = flow.net.tanh_kernel
    try:
        with torch.no_grad():
            flow.net.tanh_kernel = "torch"
            ref = flow.log_prob(states, solver="dopri5", rtol=1e-5, atol=1e-5,
                                quadrature=None).numpy().astype(float)
            rows = []
            for step, nodes, kernel in settings:
                flow.net.tanh_kernel = kernel
                flow.log_prob(states[:16], solver="rk4", step_size=step, quadrature=nodes)
                t0 = time.perf_counter()
                lp = flow.log_prob(states, solver="rk4", step_size=step,
                                   quadrature=nodes).numpy().astype(float)
                seconds = time.perf_counter() - t0
                err = np.abs(lp - ref)
                rows.append({"eval_step_size": float(step), "nodes": int(nodes),
                             "tanh": kernel, "seconds": seconds,
                             "mean_abs_error": float(err.mean()),
                             "max_abs_error": float(err.max()),
                             "rank_correlation": float(np.corrcoef(_ranks(lp),
                                                                   _ranks(ref))[0, 1])})
    finally:
        flow.net.tanh_kernel = own
    return rows


def _states(task: str, n_train: int, n_test: int, seed: int = 0):
    demos = data.load_demos(task)
    obs = np.concatenate([t.observations for t in demos.trajectories]).astype(np.float32)
    if n_train + n_test > len(obs):
        n_test = len(obs) - n_train
    idx = np.random.default_rng(seed).permutation(len(obs))
    return obs[idx[:n_train]], torch.as_tensor(obs[idx[n_train:n_train + n_test]])


def _config(b: _budget.Budget, changes: dict, seed: int) -> _sf.SoftFlowConfig:
    base = _dc.preset(b, seed).with_flow(**_dc.STORED_NUMERICS).flow
    changes = dict(changes)
    if changes.get("iterations") == "half":
        changes["iterations"] = max(1, base.iterations // 2)
    return dataclasses.replace(base, **changes, seed=seed)


@fast.on()   # as DC's fits in stored cells (dc_lesson.nn.fast)
def run(task: str = "reacher4", seeds=(0, 1), b: _budget.Budget | None = None,
        n_test: int = 1000) -> dict:
    """Every variant on every seed: ``{"rows": [...], "summary": [...]}``."""
    b = b or _budget.current()
    n_train = _dc.preset(b).flow_states
    train, test = _states(task, n_train, n_test)
    for changes in VARIANTS.values():   # untimed: first calls pay for imports and caches
        _sf.fit(train[:64], dataclasses.replace(_config(b, changes, 0), iterations=1),
                progress=False)
    rows, evals = [], []
    for name, changes in VARIANTS.items():
        for seed in seeds:
            cfg = _config(b, changes, seed)
            t0 = time.perf_counter()
            flow, _ = _sf.fit(train, cfg, progress=False)
            fit_s = time.perf_counter() - t0
            if name == DEFAULTS:     # DC's fit: how accurate is the reward at each setting
                evals += [{"seed": int(seed), **e} for e in eval_accuracy(flow, test)]
            with torch.no_grad():
                own = float(-flow.log_prob(test).mean())
                ref = float(-flow.log_prob(test, solver="dopri5", rtol=1e-5, atol=1e-5,
                                           quadrature=None).mean())
            rows.append({"variant": name, "seed": int(seed), "fit_seconds": fit_s,
                         "iterations": cfg.iterations, "solver": cfg.solver,
                         "step_size": cfg.step_size, "nll_own_solver": own,
                         "nll_reference": ref})
    return {"task": task, "train_states": int(len(train)), "test_states": int(len(test)),
            "rows": rows, "summary": summarise(rows), "tolerance": TOLERANCE,
            "reward_solver": evals}


def summarise(rows: list[dict]) -> list[dict]:
    """Per variant: mean fit seconds, time ratio today / variant, and the per-seed change of
    the reference NLL against today's same seed (positive: worse), with its largest value."""
    today = next(iter(VARIANTS))
    base = {r["seed"]: r for r in rows if r["variant"] == today}
    out = []
    for name in VARIANTS:
        mine = [r for r in rows if r["variant"] == name]
        if not mine:
            continue
        delta = [r["nll_reference"] - base[r["seed"]]["nll_reference"] for r in mine
                 if r["seed"] in base]
        fit = float(np.mean([r["fit_seconds"] for r in mine]))
        out.append({"variant": name, "fit_seconds": fit,
                    "speedup": float(np.mean([base[r["seed"]]["fit_seconds"] for r in mine])
                                     / fit),
                    "nll_reference": float(np.mean([r["nll_reference"] for r in mine])),
                    "nll_change": delta, "worst_nll_change": max(delta) if delta else None})
    return out


def cheapest_within(summary: list[dict], tolerance: float = TOLERANCE) -> str | None:
    """The fastest variant whose reference NLL is no worse than today's by more than
    ``tolerance`` nats on any seed (today's itself qualifies)."""
    ok = [s for s in summary if s["worst_nll_change"] is not None
          and s["worst_nll_change"] <= tolerance]
    return max(ok, key=lambda s: s["speedup"])["variant"] if ok else None


def format_table(result: dict) -> str:
    lines = [f"DC's first SoftFlow fit on {result['task']}: {result['train_states']} states, "
             f"held-out NLL on {result['test_states']} others (nats; reference: dopri5 1e-5)",
             f"{'variant':<38}{'fit s':>8}{'speed-up':>10}{'NLL ref':>10}{'worst change':>14}"]
    for s in result["summary"]:
        lines.append(f"{s['variant']:<38}{s['fit_seconds']:>8.1f}{s['speedup']:>9.2f}x"
                     f"{s['nll_reference']:>10.3f}{s['worst_nll_change']:>+14.3f}")
    best = cheapest_within(result["summary"], result["tolerance"])
    lines.append(f"cheapest within {result['tolerance']} nats of the stored fit on every "
                 f"seed: {best}")
    lines.append("the reward's log P_w of DC's fit, by setting, against the reference "
                 "(means over seeds):")
    lines.append(f"{'step':>6}{'nodes':>6}{'tanh':>7}{'seconds':>9}{'mean |error|':>14}"
                 f"{'max |error|':>13}{'rank corr.':>12}")
    for m in reward_table(result):
        lines.append(f"{m['eval_step_size']:>6.2f}{m['nodes']:>6}{m['tanh']:>7}"
                     f"{m['seconds']:>9.3f}{m['mean_abs_error']:>14.4f}"
                     f"{m['max_abs_error']:>13.4f}{m['rank_correlation']:>12.5f}")
    return "\n".join(lines)


def reward_table(result: dict) -> list[dict]:
    """The reward's accuracy per setting, means over seeds, in :data:`EVAL_SETTINGS`' order
    (records from before the nodes and kernel were scored count as 4 nodes, torch's tanh)."""
    keys = ("seconds", "mean_abs_error", "max_abs_error", "rank_correlation")
    groups: dict = {}
    for e in result.get("reward_solver", []):
        k = (e["eval_step_size"], e.get("nodes", 4), e.get("tanh", "torch"))
        groups.setdefault(k, []).append(e)
    return [{"eval_step_size": k[0], "nodes": k[1], "tanh": k[2],
             "default": k == REWARD_DEFAULT,
             **{x: float(np.mean([e[x] for e in es])) for x in keys}}
            for k, es in groups.items()]


def main(tasks=None, seeds=(0, 1), out=None, command: str = "dc-lesson perf flow-fit") -> dict:
    if out:
        check_writable(out)
    torch.set_num_threads(1)
    task = (tasks or ["reacher4"])[0]
    result = run(task, seeds)
    print(format_table(result))
    if out:
        write_result(out, {"benchmark": "flow-fit", "threads": 1, "machine": platform.node(),
                           **result}, command=command, seeds=list(seeds))
        print(f"wrote {out}")
    return result


__all__ = ["DEFAULTS", "EVAL_SETTINGS", "REWARD_DEFAULT", "TOLERANCE", "VARIANTS",
           "cheapest_within", "eval_accuracy", "format_table", "main", "reward_table", "run",
           "summarise"]
