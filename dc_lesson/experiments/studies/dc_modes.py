"""BC and DC on the multi-mode tasks, as cells (chapter 04; ``dc_modes.json``).

Cells: per task of ``reacher4, reacher2, halfcheetah2`` and seed of ``budget.seeds_for(task)``,
the BC warm start (the same as GAIL's cell of that seed) and DC from it
(:func:`experiments.dc.run_one`, ``DC_DEFAULTS`` and the budget's interactions), both evaluated
against the fresh reference; and the expert row.  The aggregate pairs DC with its own start
(DC - BC) and, when ``gail_modes`` has run at the same budget, with GAIL of the same seed
(DC - GAIL: the two share the warm start).  Features: ``BC`` and ``DC``.
"""

from __future__ import annotations

import dataclasses
import json

from dc_lesson.algorithms.dc import preset as dc_config
from dc_lesson.experiments import cells, dc as _runs
from dc_lesson.experiments.studies import _common, _imitation as _im

NAME = "dc_modes"


def _dc_json(b, seed, overrides) -> dict:
    return _im.without_seed(json.loads(dc_config(b, seed=seed, **overrides).to_json()))


def dc_cell(study, task, seed, b, *, overrides=None, steps=None, variant="", n_demos=None,
            **extra):
    sized = dataclasses.replace(b, il_steps=int(steps or b.il_steps),
                                il_demos=int(n_demos or b.il_demos))
    return _im.learner_cell(study, "dc", task, seed, sized, _dc_json(sized, seed, overrides or {}),
                            variant=variant, steps=steps, overrides=overrides or {}, **extra)


def run_dc(cell, needs):
    """One DC cell: warm start, DC, both evaluated (any DC study's cells).  The seed's start
    and its evaluation are trained once per worker (:func:`_imitation.worker_cache`); a cell
    whose config has ``curve = [points, episodes]`` also keeps ``eval_curve``."""
    c = cell.config
    b = _im.sized_budget(c)
    _im.check_config(cell, _dc_json(b, cell.seed, c["overrides"]))
    feats: dict = {}
    starts = _im.worker_cache(("dc", b.il_demos, b.bc_max_epochs, b.il_eval_episodes))
    row = _runs.run_one(cell.task, cell.seed, b, _common.reference(needs),
                         config_overrides=c["overrides"] or None, features=feats,
                         bc_cache=starts, curve=c.get("curve"))
    named = {("BC" if "__BC__" in k else "DC"): v for k, v in feats.items()}
    start, final = row.pop("bc"), row.pop("dc")
    return {"start": {k: start[k] for k in start if k != "seconds"},
            "final": {k: final[k] for k in final if k in _im.protocol.MEASURED},
            "start_seconds": start["seconds"],
            **{k: final[k] for k in final if k not in _im.protocol.MEASURED}, **row}, named


def cells_at(b):
    return ([dc_cell(NAME, t, s, b) for t in _im.TASKS for s in b.seeds_for(t)]
            + _im.expert_rows(NAME, _im.TASKS, b))


def aggregate(recs, b):
    from dc_lesson.experiments import aggregate as _agg
    from dc_lesson.experiments import studies
    out = _im.standard_aggregate(recs, b, [("dc", "bc")])
    gail = studies.get("gail_modes")
    try:
        g = _agg.grid_records(gail, b)
    except _agg.AggregateError:
        out["paired_gail"] = "gail_modes has not run at this budget"
        return out
    obs = out["observations"] + [o for o in _im.observations(g) if o["row"] == "gail"]
    out["paired"] += _agg.paired(obs, "dc", "gail")
    return out


STUDY = cells.Study(NAME, "BC and DC on the multi-mode tasks (chapter 04)", cells=cells_at,
                    run_cell=lambda c, n: _common.run_expert_or(c, n, run_dc),
                    aggregate=aggregate, result_file="dc_modes.json")
