"""The imitation protocol's cells (GAIL and DC studies): BC warm start, learner from it, both
evaluated against the fresh expert reference; what their aggregates share.

Every cell of a GAIL or DC study trains the seed's BC warm start itself (deterministic: the same
seed gives the same start in every study, so DC's and GAIL's cells of one seed share it and
their differences can be paired), then the learner, and evaluates both on the same fresh
episodes.  Its result holds ``start`` (BC) and ``final`` (the learner) measures.
"""

from __future__ import annotations

import copy
import dataclasses
import json

from dc_lesson import budget as _budget
from dc_lesson.experiments import aggregate as _agg
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies import _common
from dc_lesson.evaluation import stats

TASKS = ("reacher4", "reacher2", "halfcheetah2")
# The paper's ablations (Figures 3-6) are on Hopper with 11 demonstrations; so are ours (the
# Gym hopper port, whose expert hops for the whole episode).
ABLATION_TASK = "hopper"
ABLATION_DEMOS = 11
LR_TASK = ABLATION_TASK


def ablation_curve(b: _budget.Budget) -> list[int]:
    """[points, episodes] of the ablation cells' deterministic evaluation curve (Figure 5)."""
    return [int(b.ablation_curve_points), int(b.ablation_curve_episodes)]
COLLAPSE_SHARE = 0.8


def protocol_config(b: _budget.Budget, steps: int | None = None) -> dict:
    return {"budget": b.name, "n_demos": b.il_demos, "steps": int(steps or b.il_steps),
            "eval_episodes": b.il_eval_episodes, "bc_max_epochs": b.bc_max_epochs,
            "eval_seed": protocol.expert_eval_seed(0)}


def sized_budget(cfg: dict) -> _budget.Budget:
    """The budget a cell was listed at, with the cell's interaction and demonstration counts."""
    return dataclasses.replace(_budget.get(cfg["budget"]), il_steps=cfg["steps"],
                               il_demos=cfg["n_demos"])


def learner_cell(study: str, learner: str, task: str, seed: int, b: _budget.Budget,
                 learner_config: dict, *, variant: str = "", steps: int | None = None,
                 **extra):
    return cells.make_cell(study, learner, task, b.il_demos, seed,
                           {**protocol_config(b, steps), learner: learner_config, **extra},
                           variant=variant, needs=(protocol.reference_cell(task),))


def without_seed(d):
    """A learner's config without its seeds (at any depth: GAIL's PPO has its own), so one
    seed's listing and another's run compare; the cell's seed is in its identity."""
    if isinstance(d, dict):
        return {k: without_seed(v) for k, v in d.items() if k != "seed"}
    return d


def check_config(cell, current: dict) -> None:
    """Refuses to run a cell whose learner config no longer matches the code's."""
    if without_seed(json.loads(json.dumps(current))) != cell.config[cell.learner]:
        raise cells.CellError(f"{cell.study}/{cell.task}/{cell.name}: the learner's config "
                              f"changed since the cell was listed; list the study again")


def train_from_start(cell, cfg, demos, start, evaluate, log=None, checkpoint=None,
                     algorithm: str | None = None) -> dict:
    """One RL cell's run from its seed's ``start`` (the competence, benchmark and ablations
    studies): the learner's ``cfg`` for the cell's ``steps``, mean-action checkpoints
    (``curve_points`` of ``curve_episodes`` episodes over ``curve_total`` interactions,
    else ``steps``) and the start's and the final
    policy's measures on ``eval_episodes`` episodes; ``evaluate(policy, n_episodes)``
    scores a policy as the study does (``checkpoint``, if given, at the checkpoints);
    ``log``: a function of the learner's training log whose value the result keeps as
    ``log``; ``algorithm``: the registered learner to run, when the cell's row is a variant
    of it (``competence``'s ``dc-mix``)."""
    import time
    from dc_lesson import algorithms as _algorithms
    from dc_lesson import evaluation as _evaluation
    c = cell.config
    t0 = time.perf_counter()
    at = checkpoint or evaluate
    curve = _evaluation.CheckpointCurve(lambda p: at(p, c["curve_episodes"]),
                                        c.get("curve_total", c["steps"]), c["curve_points"])
    result = _algorithms.get(algorithm or cell.learner).train(cell.task, demos, cfg,
                                                 policy=copy.deepcopy(start), progress=False,
                                                 callback=curve)
    return {"start": protocol.measures_of(evaluate(start, c["eval_episodes"])),
            "final": protocol.measures_of(evaluate(result.policy, c["eval_episodes"])),
            "curve": curve.points, "train_seconds": time.perf_counter() - t0,
            **({} if log is None else {"log": log(result.log)})}


_STARTS: dict = {}   # this worker's BC starts, by the key their study gives
_STARTS_KEPT = 8     # a few seeds' worth, oldest out


def cached_start(key: tuple, make):
    """A copy of the BC start ``make()`` returns, trained once per worker process for ``key``
    (which must name everything the start depends on: task, demonstrations, seed, epochs,
    policy kind).  BC is deterministic on one thread and every learner seeds its own
    generators, so a cached start is the very policy a fresh one would be and the cell's
    numbers do not change (``tests/test_table1.py`` checks it); a sweep runs the rows of one
    seed one after another, so most cells of a seed reuse the start instead of training it."""
    if key not in _STARTS:
        _STARTS[key] = make()
        while len(_STARTS) > _STARTS_KEPT:
            _STARTS.pop(next(iter(_STARTS)))
    return copy.deepcopy(_STARTS[key])


class _Kept(dict):
    """A dict that keeps its ``_STARTS_KEPT`` newest entries (a sweep runs a seed's rows one
    after another, so older seeds' starts are not asked for again)."""

    def __setitem__(self, key, value):
        super().__setitem__(key, value)
        while len(self) > _STARTS_KEPT:
            self.pop(next(iter(self)))


_CACHES: dict = {}


def worker_cache(key: tuple) -> dict:
    """:func:`cached_start`'s store for run functions that take a cache of starts themselves
    (``experiments.dc.run_one``, ``experiments.gail.run_one``, which also keep the start's
    evaluation): a dict kept for this worker under ``key`` (which must name everything its
    entries depend on beyond their own (task, seed) keys), bounded the same way."""
    return _CACHES.setdefault(key, _Kept())


def observations(records, start_row: str = "bc") -> list[dict]:
    """Each imitation cell gives two observations, its start (``start_row``) and its final
    policy (the cell's row); the expert row's cells give one.  Starts of one (task, seed) are
    the same policy in every cell; the first is kept."""
    obs, seen = [], set()
    for r in records:
        res = r["result"]
        if "measures" in res:
            obs.append(_agg.observation(r, res["measures"]))
            continue
        key = (r["cell"]["task"], r["cell"]["seed"])
        if key not in seen:
            seen.add(key)
            obs.append(_agg.observation(r, res["start"], row=start_row))
        extra = {"curve": res.get("curve")}
        if res.get("eval_curve") is not None:   # deterministic evaluations (Figure 5)
            extra["eval_curve"] = res["eval_curve"]
        if "config" in res:   # DC: the iterations per loop, for the convergence claim
            extra["iterations"] = res["config"]["iterations"]
        obs.append(_agg.observation(r, res["final"], **extra))
    return obs


def mode_summary(obs: list[dict], reference_shares: dict, eval_episodes: int) -> list[dict]:
    """Per (row, task): per seed the largest mode's share (episodes that arrive nowhere are no
    mode), the share beyond it (``claims.beyond_largest``) and the TV distance of the seed's
    mode shares from the reference's; the share of seeds collapsed (``claims.collapsed``: at
    most 1 - COLLAPSE_SHARE beyond the largest mode, arriving nowhere included); and the multinomial floor of TV for ``eval_episodes`` episodes."""
    out = []
    for (row, task, _), rows in _agg._groups(obs).items():
        shares = [o["mode_shares"] for o in sorted(rows, key=lambda o: o["seed"])
                  if o.get("mode_shares")]
        ref = reference_shares.get(task)
        if not shares or not ref:
            continue
        top = [max(v for k, v in s.items() if k != "none") for s in shares]   # "none": no mode
        beyond = [sum(v for k, v in s.items() if k != "none") - t for s, t in zip(shares, top)]
        tvs = [stats.tv(ref, s) for s in shares]
        floor = stats.multinomial_tv_floor(ref, eval_episodes)
        out.append({"row": row, "task": task, "n_seeds": len(shares),
                    "largest_share": top, "beyond_largest": beyond, "collapsed_share": float(
                        sum(b <= 1 - COLLAPSE_SHARE + 1e-12 for b in beyond) / len(beyond)),
                    "tv": tvs, "tv_ci": stats.mean_ci(tvs).to_dict(),
                    "tv_floor": floor, "above_floor": float(
                        sum(t > floor["quantile"] for t in tvs) / len(tvs)),
                    "collapse_threshold": COLLAPSE_SHARE})
    return out


def reference_shares(records) -> dict:
    """The reference's mode shares per task, from the expert row's cells' needs (read from the
    reference cells on disk)."""
    out = {}
    for r in records:
        task = r["cell"]["task"]
        if task in out:
            continue
        ref = protocol.reference_cell(task)
        if ref.path().exists():
            out[task] = cells.read_record(ref.path())["result"]["mode_shares"]
    return out


def standard_aggregate(records, b, rows_paired=()) -> dict:
    """Table, expert row, paired differences and mode summary of an imitation study."""
    obs = observations(records)
    learners = [o for o in obs if o["row"] != "expert"]
    eval_episodes = records[0]["config"].get("eval_episodes", b.il_eval_episodes)
    return {"table": _agg.table(learners), "expert": _agg.table(
                [o for o in obs if o["row"] == "expert"]),
            "paired": [p for a, bb in rows_paired for p in _agg.paired(obs, a, bb)],
            "modes": mode_summary(obs, reference_shares(records), eval_episodes),
            "interval": "95% bootstrap (BCa) over seeds; paired: of the per-seed differences",
            "protocol": protocol_config(b), "observations": obs}


def versus_start_aggregate(records, b) -> dict:
    """:func:`standard_aggregate` with every learner row paired with the BC start (the
    learning-rate sweeps: each rate against the seed's warm start)."""
    out = standard_aggregate(records, b)
    rows = sorted({o["row"] for o in out["observations"] if o["row"] not in ("bc", "expert")})
    out["paired"] = [p for r in rows for p in _agg.paired(out["observations"], r, "bc")]
    return out


def expert_rows(study: str, tasks, b):
    return _common.expert_rows(study, tasks, b, b.il_eval_episodes)
