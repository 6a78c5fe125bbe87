"""The paper's hopper ablations (Figures 3-6) on a start with headroom (issue 41, item 5;
``dc-lesson sweep ablations``, ``ablations.json``).

The first runs (``dc_ablation``, ``dc_lr``, ``gail_lr``) started from BC on 11 whole hopper
demonstrations, which is already at the expert (0.999 on 5 of 5 seeds): every DC row could
only end below it, so "more loops help" measured recovery from damage DC did.  Here every
cell starts from the benchmark's hopper start (``studies.benchmark``: BC on the fewest
count of the headroom study's protocol, GAIL's subsampled demonstrations, the very policy
of the benchmark's BC row of that seed, about 0.47 scaled return at 11) and DC runs as the
competence gate ran it (``competence.gated_config``) at the benchmark's hopper interactions.

Cells, per seed of ``budget.benchmark_seeds`` (variant, what changes):

* ``loops=L``, L = 1..4: L loops of a fixed number of iterations, the iterations one loop
  of the 4-loop run has at the budget, so loops=4 spends the budget and loops=1 a quarter
  (the paper's Figure 3: more loops, more interactions);
* ``loops=1-long``: one loop with as many interactions as loops=4 spends, its refit
  rollouts included (so a few more PPO iterations), the equal-budget control, on every
  seed: does a loop's refit of the flow help, or only the interactions it comes with?
* ``update=admm``: consensus ADMM (a dual variable per copy) in place of the paper's
  averaging, otherwise the default;
* ``lr=X`` for the budget's ``lr_sweep_lrs`` other than DC's own 3e-4: DC's learning-rate
  sweep (Figure 4); DC's default is the ``""`` variant;
* ``""``: DC at its defaults (the benchmark's own DC cell, run again here so that every
  variant pairs with it inside one aggregate).

Every cell keeps its start's and final policy's measures, the mean-action checkpoint curve
(``benchmark_curve_points`` of ``benchmark_curve_episodes`` episodes, spread over the run's
whole interactions, the refit rollouts included: Figure 5 and the
stability question) and DC's per-iteration log (the pi-pi' distance before averaging, the
parameter change, ADMM's residuals: Figure 6).  GAIL's learning-rate sweep is not rerun:
GAIL failed the competence gate, so the book does not judge a claim with it.
"""

from __future__ import annotations

import dataclasses
import json

from dc_lesson import budget as _budget
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies import _common, _imitation as _im
from dc_lesson.experiments.studies import benchmark as _bench
from dc_lesson.experiments.studies import competence as _competence

NAME = "ablations"
TASK = "hopper"
LOOPS = (1, 2, 3, 4)


def config(b, seed: int, overrides: dict):
    """DC as the gate runs it at the benchmark's hopper interactions, with ``overrides``."""
    cfg = _competence.gated_config("dc", b, b.benchmark_steps_for(TASK), seed, TASK)
    return dataclasses.replace(cfg, **overrides)


def variants(b) -> dict[str, dict]:
    """Variant -> DC config overrides (module docstring)."""
    base = config(b, 0, {})
    per_loop = max(1, b.benchmark_steps_for(TASK) // (max(LOOPS) * base.batch_size))
    out = {f"loops={L}": {"loops": L, "iterations": per_loop} for L in LOOPS}
    # the equal-budget control: one loop with as many interactions as the 4 loops spend,
    # their refit rollouts included (DCConfig.env_steps), so a few more PPO iterations
    most = config(b, 0, out[f"loops={max(LOOPS)}"]).env_steps(TASK)
    out["loops=1-long"] = {"loops": 1, "iterations": -(-most // base.batch_size)}
    out["update=admm"] = {"update": "admm"}
    out.update({f"lr={lr:g}": {"lr": float(lr)} for lr in b.lr_sweep_lrs
                if abs(lr - base.lr) > 1e-12})
    out[""] = {}
    return out


def cells_at(b) -> list[cells.Cell]:
    d = _bench.design(TASK)
    if not d["counts"]:
        return []
    n = d["counts"][0]
    out = []
    for seed in range(b.benchmark_seeds):
        for variant, overrides in variants(b).items():
            cfg = config(b, seed, overrides)
            out.append(cells.make_cell(
                NAME, "dc", TASK, n, seed,
                {"budget": b.name, "protocol": d["protocol"], "subsample_every": d["every"],
                 "bc": _bench.bc_settings(n, d["every"], b), "overrides": overrides,
                 "steps": cfg.loops * cfg.iterations * cfg.batch_size,
                 "curve_total": _bench.curve_total(cfg, TASK, 0),
                 "eval_episodes": b.benchmark_eval_episodes,
                 "eval_seed": protocol.expert_eval_seed(0),
                 "curve_points": b.benchmark_curve_points,
                 "curve_episodes": b.benchmark_curve_episodes,
                 "demos": cells.demos_identity(TASK),
                 "dc": _im.without_seed(json.loads(cfg.to_json()))},
                variant=variant, needs=(protocol.reference_cell(TASK),)))
    return out + _common.expert_rows(NAME, [TASK], _bench._with_seeds(b),
                                     b.benchmark_eval_episodes)


def run_cell(cell, needs):
    from dc_lesson.experiments.dc import _curve
    c = cell.config
    b = _budget.get(c["budget"])
    if _bench.bc_settings(cell.n_demos, c["subsample_every"], b) != c["bc"]:
        raise cells.CellError(f"{cell.name}: BCConfig's defaults changed since the cell was "
                              f"listed; list the study again")
    cfg = config(b, cell.seed, c["overrides"])
    _im.check_config(cell, json.loads(cfg.to_json()))
    reference = _common.reference(needs)
    demos = _bench.demonstrations(cell.task, cell.n_demos, c["subsample_every"], cell.seed)
    start = _bench.cached_start(cell, c)
    return _im.train_from_start(cell, cfg, demos, start,
                                _bench.evaluator(cell, c, reference), log=_curve,
                                checkpoint=_bench.evaluator(cell, c, None)), None


def aggregate(records, b) -> dict:
    from dc_lesson.experiments import aggregate as _agg
    from dc_lesson.experiments import competence as _gate
    obs = _bench.observations(records)
    rows = [o for o in obs if o["row"] != "expert"]
    pairs = [(f"dc-loops={max(LOOPS)}", "dc-loops=1"),
             ("dc-loops=1-long", f"dc-loops={max(LOOPS)}"), ("dc-update=admm", "dc")]
    pairs += [(f"dc-{v}", "dc") for v in variants(b) if v.startswith("lr=")]
    return {"table": _agg.table(rows), "expert": _agg.table([o for o in obs
                                                             if o["row"] == "expert"]),
            "paired": [p for a, x in pairs for p in _agg.paired(rows, a, x)],
            "variants": variants(b), "design": _bench.design(TASK),
            "steps": {f"dc-{v}" if v else "dc": config(b, 0, o).env_steps(TASK)
                      for v, o in variants(b).items()},
            "interval": "95% bootstrap (BCa) over seeds; paired: of the per-seed differences",
            _gate.GRID_MARK: _gate.RULES, "observations": obs}


STUDY = cells.Study(NAME, "DC's loops, its equal-budget control, consensus ADMM and its "
                    "learning rate on the benchmark's hopper start (Figures 3-6)",
                    cells=cells_at, run_cell=lambda c, n: _common.run_expert_or(c, n, run_cell),
                    aggregate=aggregate, result_file="ablations.json")

__all__ = ["LOOPS", "NAME", "STUDY", "TASK", "cells_at", "config", "run_cell", "variants"]
