"""The paper's single-mode benchmark asked again, on demonstrations that leave BC room and at
interactions where the learners' curves have flattened (issue 41, items 1-3;
``dc-lesson sweep benchmark``, ``benchmark.json``): Table III, Figure 9 and Figure 11 as
the book's final grid.  The first grid (``table3``, 100,000 interactions on whole
demonstrations, every learner at its preset) stays stored beside it: chapter 06's old -> new
verdict table reads both.

**Demonstrations** (:func:`design`): per task, the protocol and the two demonstration counts
the ``headroom`` study chose by measurement (``headroom.json``, its ``benchmark`` rows:
GAIL's subsampling, every 20th pair from a random offset, where it puts BC's fewest count in
the band of the paper's BC, 0.4-0.7, else whole demonstrations; the fewest such count and the
most).  Where that rule found no count (ant: BC jumps past the band between neighbouring
counts and falls back below it), the task runs the preferred protocol at
:data:`FALLBACK_COUNTS`, the counts of most tasks, and the aggregate says why.  A task whose
default expert is a sampling planner would have no row (the humanoid's, until its SAC
network met the floor in December 2026): BC from a planner stays at the random level at
every count, so every learner built on BC would measure nothing.  The subsampling offsets are drawn from the
cell's seed (``data.subsample``), so BC and every learner of a seed see the same pairs.

**Learners** (:func:`learners`): BC (the start every other row shares, trained as the headroom
study trains it: at a twentieth of the pairs, twenty times the epoch cap, the same pair
visits) and every RL learner that passed the competence gate (``competence.json``), run as the
gate ran it (``studies.competence.gated_config``: the start's exploration noise, the
training-only fall termination of hopper, the learner's fixes).  A learner that failed is not
listed (the aggregate names it and why); one whose gate is still open is listed once it
passes.  The expert row (expert against expert) on every task.

**Interactions** (``budget.benchmark_steps``): per task where the gate-passing learners'
curves flattened in the competence study (``experiments.competence.budgets``: hopper and
halfcheetah, the tasks it measures); every other task takes the longest of those, having no
curve of its own (``test_benchmark_steps_follow_the_competence_curves`` holds the numbers
to the rule).  The same for every learner, up to whole batches (a PPO learner stops at
its last whole update; DC's count adds the rollouts that refit P_w, ``DCConfig.env_steps``).
A learner's parts counted in epochs get ``EVERY`` times the epochs on subsampled
demonstrations (:data:`EPOCH_FIELDS`: DRIL's ensemble), as BC does.

**Measures**: the final policy's mean action on ``benchmark_eval_episodes`` fresh episodes
(scaled return, and EMD, KL and reverse KL of its states against the fresh expert reference);
the start's, so each RL cell shows where it began; and ``benchmark_curve_points``
checkpoints of ``benchmark_curve_episodes`` episodes each (scaled return only) on every RL
cell, spread over the run's whole interactions (``curve_total``; Figure 11, and the
stability question read on curves).

The aggregate carries ``competence.GRID_MARK``: the verdicts judge a gated learner only on it.
"""

from __future__ import annotations

import dataclasses
import json
import time

from dc_lesson import budget as _budget
from dc_lesson import data as _data
from dc_lesson import evaluation as _evaluation
from dc_lesson import storage as _storage
from dc_lesson.algorithms import bc as _bc
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies import _common, _imitation as _im
from dc_lesson.experiments.studies import competence as _competence
from dc_lesson.experiments.studies import headroom as _headroom

NAME = "benchmark"
TASKS = ("cartpole", "reacher1", "hopper", "walker", "halfcheetah", "ant", "humanoid")
RL = ("gail", "dril", "pwil", "ndi", "gpril", "dc")
FALLBACK_COUNTS = (11, 25)   # a task the headroom rule found no count for (module docstring)
HEADROOM = "headroom.json"
COMPETENCE = "competence.json"


def _stored(name: str) -> dict | None:
    try:
        return _storage.read_result(name)
    except FileNotFoundError:
        return None


def stored_competence() -> dict | None:
    """The stored competence aggregate, or None while none is on record."""
    return _stored(COMPETENCE)


def design(task: str, headroom: dict | None = None) -> dict:
    """The demonstrations of ``task`` in the benchmark: ``{"task", "protocol", "every",
    "counts", "why"}`` from the headroom aggregate (the stored one when ``headroom`` is None);
    ``counts`` is empty for a task with no row, and ``why`` says why."""
    if _data.manifest_entry(task)["expert"]["kind"] == "planner":
        return {"task": task, "protocol": None, "every": None, "counts": [],
                "why": "its default expert is a sampling planner, which BC cannot clone (BC "
                       "stays at the random level at every count: headroom.json)"}
    rec = _stored(HEADROOM) if headroom is None else headroom
    rows = {r["task"]: r for r in (rec or {}).get("benchmark", ())}
    if task not in rows:
        return {"task": task, "protocol": None, "every": None, "counts": [],
                "why": "no headroom study on record (dc-lesson sweep headroom)"}
    row = rows[task]
    if row["protocol"] is not None:
        return {"task": task, "protocol": row["protocol"], "every": row["every"],
                "counts": [int(n) for n in row["counts"]], "why": ""}
    proto = _headroom.PREFERENCE[0]
    return {"task": task, "protocol": proto, "every": _headroom.PROTOCOLS[proto][0],
            "counts": list(FALLBACK_COUNTS),
            "why": f"the headroom rule found no count ({row['why']}); the preferred "
                   f"protocol at the counts most tasks use"}


def learners(competence: dict | None = None) -> dict[str, str]:
    """Every RL learner of :data:`RL` -> ``"passed"`` or why it is not in the grid, from the
    competence gate (the stored one when ``competence`` is None)."""
    rec = _stored(COMPETENCE) if competence is None else competence
    gate = (rec or {}).get("gate", {})
    out = {}
    for name in RL:
        g = gate.get(name)
        out[name] = ("passed" if g and g["passed"] is True else
                     "no competence study on record" if g is None else
                     f"failed the competence gate: {g['reason']}" if g["passed"] is False
                     else f"the competence gate has not decided yet: {g['reason']}"
                     if g.get("open", True) else
                     f"the competence gate cannot decide on our ports: {g['reason']}")
    return out


def listed(competence: dict | None = None) -> tuple[str, ...]:
    """The rows of the grid: BC, then the RL learners that passed the gate."""
    return ("bc",) + tuple(k for k, v in learners(competence).items() if v == "passed")


def bc_settings(n_demos: int, every: int | None, b) -> dict:
    """BC's settings of a cell (the BC row and every RL learner's start), as the headroom
    study's protocol trains it."""
    scale = _headroom.EVERY if every else 1
    return _headroom.bc_settings(n_demos, scale * b.bc_max_epochs)


# A learner's parts counted in epochs see a twentieth of the pairs on subsampled
# demonstrations, so they get EVERY times the epochs, the same pair visits (as BC's cap,
# module docstring): DRIL's ensemble (50 epochs: 150 gradient steps per member at 11
# subsampled hopper demonstrations against about 800 in the gate's runs on 4 whole ones;
# found by a review before any DRIL cell ran).  DC counts its BC and flow work in steps.
EPOCH_FIELDS = {"dril": ("ensemble_epochs",)}


def learner_config(learner: str, b, task: str, seed: int, every: int | None = None):
    """The learner as the gate ran it at the task's interactions; with ``every`` (subsampled
    demonstrations) its :data:`EPOCH_FIELDS` scaled by ``every``."""
    cfg = _competence.gated_config(learner, b, b.benchmark_steps_for(task), seed, task)
    if every:
        cfg = dataclasses.replace(cfg, **{f: getattr(cfg, f) * every
                                          for f in EPOCH_FIELDS.get(learner, ())})
    return cfg


def curve_total(cfg, task: str, steps: int) -> int:
    """The interactions a run's checkpoint marks are spread over: DC's whole run with the
    rollouts that refit P_w (``DCConfig.env_steps``, which its step counter counts), else
    the cell's ``steps``."""
    return int(cfg.env_steps(task)) if hasattr(cfg, "env_steps") else int(steps)


def cells_at(b) -> list[cells.Cell]:
    out, rows = [], listed()
    for task in TASKS:
        d = design(task)
        needs = (protocol.reference_cell(task),)
        for n in d["counts"]:
            for seed in range(b.benchmark_seeds):
                for learner in rows:
                    config = {"budget": b.name, "protocol": d["protocol"],
                              "subsample_every": d["every"],
                              "bc": bc_settings(n, d["every"], b),
                              "eval_episodes": b.benchmark_eval_episodes,
                              "eval_seed": protocol.expert_eval_seed(0),
                              "demos": cells.demos_identity(task)}
                    if learner != "bc":
                        made = learner_config(learner, b, task, seed, d["every"])
                        cfg = json.loads(made.to_json())
                        config.update({"steps": b.benchmark_steps_for(task),
                                       "curve_total": curve_total(
                                           made, task, b.benchmark_steps_for(task)),
                                       "curve_points": b.benchmark_curve_points,
                                       "curve_episodes": b.benchmark_curve_episodes,
                                       learner: _im.without_seed(cfg)})
                    out.append(cells.make_cell(NAME, learner, task, n, seed, config,
                                               needs=needs))
    out.sort(key=lambda c: (c.seed, c.n_demos, TASKS.index(c.task)))   # seed-major
    tasks = [t for t in TASKS if design(t)["counts"]]
    return out + _common.expert_rows(NAME, tasks, _with_seeds(b), b.benchmark_eval_episodes)


def _with_seeds(b):
    return dataclasses.replace(b, sweep_seeds_other=b.benchmark_seeds,
                               sweep_seeds_reacher=b.benchmark_seeds)


def demonstrations(task: str, n_demos: int, every: int | None, seed: int):
    """The cell's demonstrations: the first ``n_demos`` of the task's default expert,
    subsampled with offsets from ``seed`` when ``every`` is set."""
    return _headroom.demonstrations(task, n_demos, every, seed)


def start_policy(task: str, n_demos: int, every: int | None, seed: int, settings: dict):
    """The seed's BC policy: the BC row, and (its exploration noise reset by the learner's
    ``start_log_std``) every RL learner's start."""
    demos = demonstrations(task, n_demos, every, seed)
    policy, _ = _bc.train_bc(demos, _bc.BCConfig(**{**settings, "seed": seed}), progress=False)
    return policy


def cached_start(cell, c: dict):
    """The seed's BC start of ``cell`` (config ``c``), trained once per worker for every
    cell of that (task, count, protocol, seed): this study's and the ablations'."""
    return _im.cached_start(
        (NAME, cell.task, cell.n_demos, c["subsample_every"], cell.seed,
         json.dumps(c["bc"], sort_keys=True)),
        lambda: start_policy(cell.task, cell.n_demos, c["subsample_every"], cell.seed,
                             c["bc"]))


def evaluator(cell, c: dict, reference):
    """``evaluate(policy, n_episodes)``: the mean action on the cell's fresh episodes,
    scaled return and divergences against ``reference`` (None: the scaled return alone,
    all a checkpoint curve keeps)."""
    def evaluate(policy, n_episodes):
        return _evaluation.evaluate_policy(cell.task, policy, reference,
                                           n_episodes=n_episodes, seed=c["eval_seed"],
                                           divergences=reference is not None)
    return evaluate


def run_cell(cell, needs):
    c = cell.config
    b = _budget.get(c["budget"])
    if bc_settings(cell.n_demos, c["subsample_every"], b) != c["bc"]:
        raise cells.CellError(f"{cell.name}: BCConfig's defaults changed since the cell was "
                              f"listed; list the study again")
    evaluate = evaluator(cell, c, _common.reference(needs))
    t0 = time.perf_counter()
    start = cached_start(cell, c)
    if cell.learner == "bc":
        return {"final": protocol.measures_of(evaluate(start, c["eval_episodes"])),
                "train_seconds": time.perf_counter() - t0}, None
    cfg = learner_config(cell.learner, b, cell.task, cell.seed, c["subsample_every"])
    _im.check_config(cell, json.loads(cfg.to_json()))
    demos = demonstrations(cell.task, cell.n_demos, c["subsample_every"], cell.seed)
    return _im.train_from_start(cell, cfg, demos, start, evaluate,
                                checkpoint=evaluator(cell, c, None)), None


def observations(records) -> list[dict]:
    """One observation per cell (this study's and the ablations'): the final policy's
    measures, with the start's, the checkpoint curve and (DC's ablations) the iteration log
    beside them; the expert row's at ``n_demos`` 0."""
    from dc_lesson.experiments import aggregate as _agg
    out = []
    for r in records:
        res = r["result"]
        if "measures" in res:   # the expert row
            out.append({**_agg.observation(r, res["measures"]), "n_demos": 0})
        else:
            dc = r["config"].get("dc") or {}   # DC's iterations per loop: the log's unit
            out.append(_agg.observation(r, res["final"], curve=res.get("curve"),
                                        start=res.get("start"),
                                        **({"log": res["log"]} if "log" in res else {}),
                                        **({"iterations": dc["iterations"]}
                                           if "iterations" in dc else {})))
    return out


def aggregate(records, b) -> dict:
    from dc_lesson.experiments import aggregate as _agg
    from dc_lesson.experiments import competence as _gate
    obs = observations(records)
    rows = [o for o in obs if o["row"] != "expert"]
    expert = [o for o in obs if o["row"] == "expert"]
    grid = listed()
    paired = [p for x in grid if x not in ("bc", "dc")
              for p in _agg.paired(rows, "dc", x)] + _agg.paired(rows, "dc", "bc")
    return {"table": _agg.table(rows), "expert": _agg.table(expert), "paired": paired,
            "design": [design(t) for t in TASKS], "learners": learners(), "rows": list(grid),
            "steps": {t: b.benchmark_steps_for(t) for t in TASKS},
            "interval": "95% bootstrap (BCa) over seeds; paired: of the per-seed differences",
            _gate.GRID_MARK: _gate.RULES, "observations": obs}


STUDY = cells.Study(NAME, "the benchmark with headroom (issue 41): Table III, Figures 9 and 11",
                    cells=cells_at,
                    run_cell=lambda c, n: _common.run_expert_or(c, n, run_cell),
                    aggregate=aggregate, result_file="benchmark.json")

__all__ = ["EPOCH_FIELDS", "curve_total", "FALLBACK_COUNTS", "NAME", "RL", "STUDY", "TASKS", "bc_settings", "cached_start",
           "cells_at", "demonstrations", "design", "evaluator", "observations", "learner_config", "learners", "listed", "run_cell",
           "start_policy", "stored_competence"]
