"""DC's ablations, as cells (the paper's Figure 3; ``dc_ablation.json``).

Cells, on ``hopper`` with 11 demonstrations (the paper's setting): the loop ablation (variant ``loops=L`` for L = 1..4 loops of a fixed
number of iterations, and ``loops=1-long``: one loop with as many iterations as the longest),
on the first seed as before and now on every seed of ``budget.seeds_for``; and consensus ADMM
(``update=admm``, otherwise the defaults) on every seed, paired with the default averaging
cell of the same seed.  Every cell keeps a deterministic evaluation curve (Figure 5:
``budget.ablation_curve_points`` checkpoints of ``ablation_curve_episodes`` episodes) beside
DC's own per-iteration log (the distance between pi and pi' before averaging, the change of
pi's parameters, ADMM's residuals: Figure 6).
"""

from dc_lesson.algorithms.dc import preset as dc_config
from dc_lesson.experiments import cells
from dc_lesson.experiments.studies import _common, _imitation as _im
from dc_lesson.experiments.studies._learners import dc_cell, run_dc

NAME = "dc_ablation"
TASK = _im.ABLATION_TASK
LOOPS = (1, 2, 3, 4)


def cells_at(b):
    per_loop = dc_config(b, loops=4).iterations
    curve = _im.ablation_curve(b)
    out = []
    for s in b.seeds_for(TASK):
        for L in LOOPS:
            out.append(dc_cell(NAME, TASK, s, b, overrides={"loops": L, "iterations": per_loop},
                               variant=f"loops={L}", n_demos=_im.ABLATION_DEMOS, curve=curve))
        out.append(dc_cell(NAME, TASK, s, b, overrides={"loops": 1,
                                                        "iterations": per_loop * max(LOOPS)},
                           variant="loops=1-long", n_demos=_im.ABLATION_DEMOS, curve=curve))
        out.append(dc_cell(NAME, TASK, s, b, overrides={"update": "admm"},
                           variant="update=admm", n_demos=_im.ABLATION_DEMOS, curve=curve))
        out.append(dc_cell(NAME, TASK, s, b, n_demos=_im.ABLATION_DEMOS,
                           curve=curve))   # averaging
    return out


def aggregate(recs, b):
    out = _im.standard_aggregate(recs, b)
    from dc_lesson.experiments import aggregate as _agg
    obs = out["observations"]
    out["paired"] = (_agg.paired(obs, f"dc-loops={max(LOOPS)}", "dc-loops=1")
                     + _agg.paired(obs, "dc-update=admm", "dc")
                     + _agg.paired(obs, "dc-loops=1-long", f"dc-loops={max(LOOPS)}"))
    return out


STUDY = cells.Study(NAME, "DC's loops and consensus ADMM (Figure 3)", cells=cells_at,
                    run_cell=lambda c, n: _common.run_expert_or(c, n, run_dc),
                    aggregate=aggregate, result_file="dc_ablation.json")
