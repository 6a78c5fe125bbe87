"""The paper's Table I asked again under the competence gate (issue 41, item 4; ``dc-lesson
sweep modes``, ``modes.json``): does DC keep the expert's modes where a BC start does not,
and which learner collapses on the hidden-coin demonstrations?  The first grid (``table1``,
300,000 interactions, every learner at its preset) stays stored beside it for chapter 06's
old -> new verdict table.

Cells: per task of ``reacher2, reacher4, halfcheetah2``, seed of ``range(modes_seeds)`` (10
on every task: halfcheetah2's first grid had 5, too few to tell its rows apart; the mixture
rows and their control ``bc-full-coin`` on the first ``table1_mixture_seeds``, 5) and row of
:data:`ROWS`, on the first ``il_demos`` (18) whole demonstrations (the realizable experts',
or the hidden-coin experts' for the ``*-coin`` rows); the RL rows at the benchmark's
interactions (``budget.benchmark_steps_for``: no competence curve measures these tasks, so
they take the longest the curves needed) with the gate's settings
(``competence.gated_config``); every policy evaluated with its mean action and with sampled
actions against the fresh reference, as in the first grid, and a mixture policy also with
its drawn component acting with that component's mean (``"components"``,
:class:`~dc_lesson.nn.mixture.ComponentMeans`): under sampled actions the floor's spread
(e^-2) can stop a reacher arriving anywhere (the first reacher4 ``bc-mix`` cell, seed 0:
96% of its sampled episodes arrived nowhere, 4% of its mean-action ones), so sampled actions
cannot say whether the mixture holds several modes, and the mean action picks one mode per
state by construction.
A Gaussian row's ``"components"`` evaluation is its mean action (one component), so the
mixture rows pair with their Gaussian controls under it.

The rows (stage: the order a sweep runs them in):

==================  =====  ===================================================================
row                 stage  what it is
==================  =====  ===================================================================
``bc`` (start)             the 70/30 BC warm start of the ``dc`` and baseline rows
``bc-full``         1      BC on all 18 to a fixed budget, the last kept
``bc-lib``          1      BC as imitation 1.0.1 trains it (the standard library's recipe)
``dc``              1      DC from the 70/30 start
``dc-lib``          1      DC from ``bc-lib``, the best BC a user could have had (its start is
                           the ``bc-lib`` row's policy, its noise reset by the gate's rule)
``dc-coin``         2      DC on the hidden-coin demonstrations, from their 70/30 BC
``<learner>``       3      every other RL learner that passed the gate, from the 70/30 start
``bc-mix``          4      the mixture BC (4 components) trained until it matches plain BC
``dc-mix``          4      DC from it
``bc-full-coin``    4      plain BC on the coin demonstrations (the mixture's matched control)
``bc-mix-coin``     4      the mixture BC on them, trained until it matches ``bc-full-coin``
``dc-mix-coin``     4      DC from it
==================  =====  ===================================================================

**The mixture BC is trained until it matches plain BC** (:func:`matched_mixture`, from
``_mixture_match``, the rule ``competence`` applies too): the same seed's plain BC
(``bc-full``'s training, the same demonstrations) is scored with its mean
action on :data:`MATCH_EPISODES` episodes from :data:`MATCH_SEED` (no evaluation or
demonstration episode shares their starts); the mixture is trained for ``bc_max_epochs``
epochs, then twice and four times as many (each a fresh, deterministic run), and the first
that scores at least plain BC's score less :data:`MATCH_TOLERANCE` on those episodes (no
weaker: a mixture above plain BC is no handicap) is kept, else the longest; the cell
records the epochs, both scores and whether it matched.  The mixture rows are judged only
on seeds whose start matched: an unmatched seed's mixture rows are named ``ROW
(unmatched)`` in the aggregate (:func:`observations`), shown in the table and paired with
nothing, since a weaker start would make any comparison with the Gaussian rows a
comparison of starts (the first grid's mixture BC was weaker than plain BC on every task).  The mixture's component spreads are set to the gate's exploration noise
(``algorithms.base.START_LOG_STD``), as every other start's.  Its spreads are floored at
``nn.mixture.LOG_STD_MIN`` (e^-2; the first grid's e^-5 let the mixture's likelihood
shrink a component onto its own pairs, and no number of epochs matched plain BC: the
module's docstring has the measurements); the floor is part of a mixture cell's identity.

Not run: GAIL and its variants and the other baselines that failed the competence gate
(``learners`` in the aggregate says why), and the rows of a gated variant that failed it
(:func:`failed_variants`: ``dc-mix`` and ``dc-mix-coin`` once ``dc-mix`` failed, on 6
December, its cartpole keep part; the rows were listed while its gate was undecided); the
first grid's DC diagnostics (``dc-noppo``, ``dc-raw``, ``dc-gailreward``), which explain DC
rather than judge a claim.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import time

from dc_lesson import algorithms as _algorithms
from dc_lesson import evaluation as _evaluation
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms import bc as _bc
from dc_lesson.data import store as _store
from dc_lesson.nn import mixture as _mixture
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies import _common, _imitation as _im
from dc_lesson.experiments.studies import benchmark as _bench
from dc_lesson.experiments.studies import competence as _competence
from dc_lesson.experiments.studies import table1 as _t1
from dc_lesson.experiments.studies import _mixture_match as _match
from dc_lesson.experiments.studies._mixture_match import (MATCH_EPISODES, MATCH_SCALES,
                                                          MATCH_SEED, MATCH_TOLERANCE,
                                                          matched_mixture)

NAME = "modes"
TASKS = ("reacher4", "reacher2", "halfcheetah2")
# the evaluations a mixture cell stores: the two every cell has, and the drawn component
# acting with its mean (module docstring); a Gaussian row's "components" is its mean action
EVALUATIONS = (*_t1.ACTIONS, _evaluation.COMPONENTS)


@dataclasses.dataclass(frozen=True)
class Row:
    learner: str
    variant: str
    stage: int
    start: str = ""        # "" (the 70/30 BC), "lib" (bc-lib's policy), "mix" (matched mixture)
    demos: str = ""        # "" or "coin"
    mixture_seeds: bool = False

    @property
    def name(self) -> str:
        return self.learner + (f"-{self.variant}" if self.variant else "")


FIXED_ROWS = (
    Row("bc", "full", 1), Row("bc", "lib", 1), Row("dc", "", 1), Row("dc", "lib", 1, "lib"),
    Row("dc", "coin", 2, demos="coin"),
    Row("bc", "mix", 4, "mix", mixture_seeds=True),
    Row("dc", "mix", 4, "mix", mixture_seeds=True),
    Row("bc", "full-coin", 4, demos="coin", mixture_seeds=True),
    Row("bc", "mix-coin", 4, "mix", "coin", mixture_seeds=True),
    Row("dc", "mix-coin", 4, "mix", "coin", mixture_seeds=True),
)


def failed_variants(competence: dict | None = None) -> dict[str, str]:
    """Each gated variant (``competence.VARIANTS``: ``dc-mix``) that failed the gate -> why
    (the stored gate when ``competence`` is None).  Its rows are not run, like every learner
    that failed: no verdict could judge them.  A variant not yet decided keeps its rows."""
    gate = (_bench.stored_competence() if competence is None else competence or {}).get(
        "gate", {})
    return {k: f"failed the competence gate: {gate[k]['reason']}"
            for k in _competence.VARIANTS if gate.get(k, {}).get("passed") is False}


def rows(competence: dict | None = None) -> dict[str, Row]:
    """The rows: :data:`FIXED_ROWS` but those of a variant that failed the gate
    (:func:`failed_variants`), and, at stage 3, every other RL learner that passed the
    gate (``benchmark.listed``), from the 70/30 start."""
    failed = failed_variants(competence)
    fixed = tuple(r for r in FIXED_ROWS
                  if not any(r.name == k or r.name.startswith(k + "-") for k in failed))
    extra = [Row(x, "", 3) for x in _bench.listed(competence) if x not in ("bc", "dc")]
    return {r.name: r for r in fixed + tuple(extra)}


def seeds(row: Row, b) -> range:
    return range(min(b.table1_mixture_seeds, b.modes_seeds) if row.mixture_seeds
                 else b.modes_seeds)


def learner_config(row: Row, b, task: str, seed: int):
    if row.name in ("bc-lib",):
        return _bc.library_recipe(seed)
    if row.learner == "bc":
        return _t1._bc_config(b, seed, row.start == "mix", full=True)
    return _competence.gated_config(row.learner, b, b.benchmark_steps_for(task), seed, task)


def _demo_variant(row: Row) -> str | None:
    return row.demos or None


def cells_at(b) -> list[cells.Cell]:
    sized = dataclasses.replace(b, sweep_seeds_reacher=b.modes_seeds,
                                sweep_seeds_other=b.modes_seeds)
    table = rows()
    out = []
    for row in table.values():
        for task in TASKS:
            steps = 0 if row.learner == "bc" else b.benchmark_steps_for(task)
            for seed in seeds(row, b):
                cfg = _im.without_seed(json.loads(learner_config(row, b, task, seed).to_json()))
                extra = {"row_start": row.start, "demo_variant": _demo_variant(row),
                         "match": {**_match.RULE,
                                   "log_std_min": _mixture.LOG_STD_MIN,
                                   "evaluations": list(EVALUATIONS)}
                         if row.start == "mix" else None}
                c = _im.learner_cell(NAME, row.learner, task, seed, b, cfg,
                                     variant=row.variant, steps=steps, **extra)
                out.append(dataclasses.replace(c, stage=row.stage))
    order = list(table)   # within a seed, a mixture BC just before the DC that starts from it
    out.sort(key=lambda c: (c.stage, c.seed, TASKS.index(c.task), order.index(c.row)))
    return _im.expert_rows(NAME, TASKS, sized) + out


def _start(row: Row, task, demos, seed, b, c):
    """The row's start and, for a mixture, its match record (cached per worker)."""
    key = (NAME, task, len(demos.trajectories), c["demo_variant"], row.start, seed,
           b.bc_max_epochs)
    if row.start == "mix":
        policy, record = _im.cached_start(key, lambda: matched_mixture(task, demos, seed, b))
        return policy, record
    if row.start == "lib":
        return _im.cached_start(key, lambda: _bc.train(task, demos, _bc.library_recipe(seed),
                                                       progress=False).policy), None
    return _im.cached_start(key, lambda: _bc.warm_start_policy(
        demos, seed, max_epochs=b.bc_max_epochs)), None


def run_cell(cell, needs):
    c = cell.config
    row = rows().get(cell.row)
    if row is None:
        raise cells.CellError(f"{cell.study}/{cell.task}/{cell.name}: row {cell.row} is no "
                              f"longer in the grid (the competence gate changed since the "
                              f"cell was listed); list the study again")
    b = _im.sized_budget(c)
    cfg = learner_config(row, b, cell.task, cell.seed)
    _im.check_config(cell, json.loads(cfg.to_json()))
    reference = _common.reference(needs)
    demos = _store.load_demos(cell.task, n_trajectories=c["n_demos"], variant=c["demo_variant"])
    out, feats = {}, {}
    t0 = time.perf_counter()
    if row.learner == "bc" and row.start != "mix":
        policy = _bc.train(cell.task, demos, cfg, progress=False).policy
    else:
        start, match = _start(row, cell.task, demos, cell.seed, b, c)
        if match is not None:
            out["match"] = match
        if row.learner == "bc":
            policy = start
        else:
            if row.start == "":   # the 70/30 start: its own row, evaluated where it is used
                out["start"], feats["start"] = _t1._evaluate(cell.task, start, reference, c,
                                                             cell.seed)
            if row.start == "mix":
                start = _t1._mixture_start(start, _base.START_LOG_STD)
            t1 = time.perf_counter()
            result = _algorithms.get(row.learner).train(
                cell.task, demos, cfg, policy=copy.deepcopy(start), progress=False)
            out["curve"] = _t1._curve(result.log)
            out["rl_seconds"] = time.perf_counter() - t1
            policy = result.policy
    out["train_seconds"] = time.perf_counter() - t0
    out["final"], feats["final"] = _t1._evaluate(cell.task, policy, reference, c, cell.seed)
    if row.start == "mix":
        ev = _evaluation.evaluate_policy(cell.task, policy, reference,
                                         n_episodes=c["eval_episodes"], seed=c["eval_seed"],
                                         actions=_evaluation.COMPONENTS)
        out["final"][_evaluation.COMPONENTS] = protocol.measures_of(ev)
    return out, feats


def observations(records, actions: str) -> list[dict]:
    """One observation per policy a cell evaluated with ``actions``; a DC cell's 70/30 start
    becomes row ``bc`` (``bc-coin`` on the coin demonstrations), once per (task, seed); a
    mixture row carries ``matched`` (its start, or itself, matched plain BC)."""
    from dc_lesson.experiments import aggregate as _agg
    obs = [_agg.observation(r, r["result"]["measures"]) for r in records
           if "measures" in r["result"]]        # the expert row: one evaluation
    seen = set()
    for r in (r for r in records if "measures" not in r["result"]):
        res, cell = r["result"], r["cell"]
        if "start" in res:
            start = "bc" + ("-coin" if r["config"]["demo_variant"] else "")
            key = (cell["task"], cell["seed"], start)
            if key not in seen:
                seen.add(key)
                obs.append(_agg.observation(r, res["start"][
                    "mean" if actions == _evaluation.COMPONENTS else actions], row=start))
        extra = {"curve": res.get("curve")}
        row = None
        if actions not in res["final"]:
            if actions != _evaluation.COMPONENTS or "match" in res:
                raise cells.CellError(
                    f"{cell['study']}/{cell['task']}: the {cell['learner']}-{cell['variant']} "
                    f"cell of seed {cell['seed']} has no {actions!r} evaluation (a mixture "
                    f"cell from before it was added); delete it and run the sweep again")
            actions_here = "mean"      # a Gaussian's one component acts with its mean
        else:
            actions_here = actions
        if "match" in res:
            extra["matched"] = res["match"]["matched"]
            if not extra["matched"]:   # shown, paired with nothing (module docstring)
                row = f"{cell['learner']}-{cell['variant']} (unmatched)"
        obs.append(_agg.observation(r, res["final"][actions_here], row=row, **extra))
    return obs


PAIRS = (("dc", "bc"), ("dc", "bc-full"), ("dc", "bc-lib"), ("dc-lib", "bc-lib"),
         ("dc-lib", "dc"), ("bc-lib", "bc-full"), ("dc-coin", "bc-coin"),
         ("bc-mix", "bc-full"), ("dc-mix", "bc-mix"), ("dc-mix", "dc"),
         ("bc-mix-coin", "bc-full-coin"), ("dc-mix-coin", "bc-mix-coin"),
         ("dc-mix-coin", "dc-coin"), ("bc-full-coin", "bc-coin"))


def aggregate(records, b) -> dict:
    from dc_lesson.experiments import aggregate as _agg
    from dc_lesson.experiments import competence as _gate
    table = rows()
    pairs = PAIRS + tuple(("dc", x) for x in table if table[x].stage == 3) + tuple(
        (x, "bc") for x in table if table[x].stage == 3)
    out = {"interval": "95% bootstrap (BCa) over seeds; paired: of the per-seed differences",
           "protocol": {k: v for k, v in _im.protocol_config(b).items() if k != "steps"},
           "rows": {k: dataclasses.asdict(v) for k, v in table.items()},
           "learners": {**_bench.learners(), **failed_variants()}, "steps": {t: b.benchmark_steps_for(t) for t in TASKS},
           "match": dict(_match.RULE),
           _gate.GRID_MARK: _gate.RULES}
    out.update(_t1.both_evaluations(records, observations, pairs, b.il_eval_episodes,
                                    actions=EVALUATIONS))
    return out


STUDY = cells.Study(NAME, "Table I rerun under the gate: the multi-mode tasks, the mixture "
                    "matched to plain BC, DC from the best BC", cells=cells_at,
                    run_cell=lambda c, n: _common.run_expert_or(c, n, run_cell),
                    aggregate=aggregate, result_file="modes.json")

__all__ = ["EVALUATIONS", "FIXED_ROWS", "failed_variants", "MATCH_EPISODES", "MATCH_SCALES", "MATCH_SEED",
           "MATCH_TOLERANCE",
           "NAME", "PAIRS", "Row", "STUDY", "TASKS", "cells_at", "learner_config",
           "matched_mixture", "observations", "rows", "run_cell", "seeds"]
