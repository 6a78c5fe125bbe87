"""The GAIL and DC cells the hopper studies are made of (``gail_lr``, ``dc_lr``, ``dc_ablation``):
how a cell's config is built from the budget and what running one does.

A cell is the seed's BC warm start (trained once per worker and shared by every cell of that
seed: :func:`_imitation.worker_cache`), the learner from it, both evaluated against the fresh
reference.  ``gail_cell`` / ``dc_cell`` give the config (learner settings without the seed, so
every seed of a row runs the same config, checked again at run time), ``run_gail`` /
``run_dc`` run it.  Table I's and Table III's rows have their own runners (``table1``,
``table3``): they carry more learners and both evaluations.
"""

from __future__ import annotations

import dataclasses
import json

from dc_lesson.algorithms.dc import preset as dc_config
from dc_lesson.algorithms.gail import sized as gail_config
from dc_lesson.experiments import dc as _dc_runs, gail as _gail_runs
from dc_lesson.experiments.studies import _common, _imitation as _im


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
    row, feats = _gail_runs.run_one(cell.task, cell.seed, n_demos=c["n_demos"], steps=c["steps"],
                                eval_episodes=c["eval_episodes"],
                                reference=_common.reference(needs),
                                bc_max_epochs=c["bc_max_epochs"], config=cfg,
                                eval_seed=c["eval_seed"], curve=c.get("curve"),
                                bc_cache=_im.worker_cache(
                                    ("gail", c["n_demos"], c["bc_max_epochs"],
                                     c["eval_episodes"], c["eval_seed"])))
    result = {"start": row.pop("BC"), "final": row.pop("GAIL"), **row}
    return result, _common.features(feats, cell.seed)


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
    row = _dc_runs.run_one(cell.task, cell.seed, b, _common.reference(needs),
                         config_overrides=c["overrides"] or None, features=feats,
                         bc_cache=starts, curve=c.get("curve"))
    named = {("BC" if "__BC__" in k else "DC"): v for k, v in feats.items()}
    start, final = row.pop("bc"), row.pop("dc")
    return {"start": {k: start[k] for k in start if k != "seconds"},
            "final": {k: final[k] for k in final if k in _im.protocol.MEASURED},
            "start_seconds": start["seconds"],
            **{k: final[k] for k in final if k not in _im.protocol.MEASURED}, **row}, named


__all__ = ["dc_cell", "gail_cell", "run_dc", "run_gail"]
