"""BC and GAIL on the multi-mode tasks, as cells (chapter 02; ``gail_modes.json``).

Cells: per task of ``reacher4, reacher2, halfcheetah2`` and seed of ``budget.seeds_for(task)``,
the BC warm start and GAIL from it (:func:`experiments.gail.run_one`, ``budget.il_steps``
interactions), both evaluated against the fresh reference; and the expert row.  The features
``.npz`` of a cell holds ``BC`` and ``GAIL`` (at most 2000 rows each).
"""

from __future__ import annotations

import dataclasses

from dc_lesson.algorithms.gail import sized as gail_config
from dc_lesson.experiments import cells, gail as _runs
from dc_lesson.experiments.studies import _common, _imitation as _im

NAME = "gail_modes"


def gail_cell(study, task, seed, b, *, lr=None, steps=None, variant="", n_demos=None,
              curve=None):
    cfg = _im.without_seed(gail_config(int(steps or b.il_steps), seed, lr=lr).to_dict())
    extra = {} if lr is None else {"lr": float(lr)}
    if curve is not None:
        extra["curve"] = [int(curve[0]), int(curve[1])]
    if n_demos is not None:
        b = dataclasses.replace(b, il_demos=int(n_demos))
    return _im.learner_cell(study, "gail", task, seed, b, cfg, variant=variant, steps=steps,
                            **extra)


def run_gail(cell, needs):
    """One GAIL cell: warm start, GAIL, both evaluated (any GAIL study's cells).  The seed's
    start and its evaluation are trained once per worker (:func:`_imitation.worker_cache`); a
    cell whose config has ``curve = [points, episodes]`` also keeps ``eval_curve``."""
    c = cell.config
    cfg = gail_config(c["steps"], cell.seed, lr=c.get("lr"))
    _im.check_config(cell, cfg.to_dict())
    row, feats = _runs.run_one(cell.task, cell.seed, n_demos=c["n_demos"], steps=c["steps"],
                                eval_episodes=c["eval_episodes"],
                                reference=_common.reference(needs),
                                bc_max_epochs=c["bc_max_epochs"], config=cfg,
                                eval_seed=c["eval_seed"], curve=c.get("curve"),
                                bc_cache=_im.worker_cache(
                                    ("gail", c["n_demos"], c["bc_max_epochs"],
                                     c["eval_episodes"], c["eval_seed"])))
    result = {"start": row.pop("BC"), "final": row.pop("GAIL"), **row}
    return result, _common.features(feats, cell.seed)


def cells_at(b):
    return ([gail_cell(NAME, t, s, b) for t in _im.TASKS for s in b.seeds_for(t)]
            + _im.expert_rows(NAME, _im.TASKS, b))


STUDY = cells.Study(NAME, "BC and GAIL on the multi-mode tasks (chapter 02)", cells=cells_at,
                    run_cell=lambda c, n: _common.run_expert_or(c, n, run_gail),
                    aggregate=lambda recs, b: _im.standard_aggregate(
                        recs, b, [("gail", "bc")]),
                    result_file="gail_modes.json")
