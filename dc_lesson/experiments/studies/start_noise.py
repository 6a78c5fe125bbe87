"""How much can a perfect start bear?  The competence study's BC starts, their weights
perturbed by small random noise (``dc-lesson sweep start_noise``; ``start_noise.json``).

The competence gate's "keeps a perfect start" asks every RL learner not to let its
mean-action return fall more than ``competence.MAX_DIP`` below its BC start at any
checkpoint.  Probes of DC on hopper (issue 38; the note of 5 December 2026) found its early
falls there unchanged by a ten times smaller learning rate and by either of its two steps
alone, but absent when neither step runs: the fall came from moving the weights at all.  So
this study measures the start itself: how large a random change of its weights it survives.

Cells: per task of :data:`TASKS` (the gate's keep tasks) and seed in
``range(budget.competence_keep_seeds)``, the very start the competence cells of that seed
train from (the same cached BC, 4 demonstrations, ``bc_max_epochs``), scored by the same rule
as a competence checkpoint (mean action, ``competence_curve_episodes`` episodes from the
study's evaluation seed); then, per noise scale of :data:`SCALES`, :data:`DRAWS` copies of
it whose mean network's every weight and bias gets independent Gaussian noise of that
standard deviation (the draws from ``NOISE_SEED`` and the seed), each scored alike.  For
scale: one Adam step moves a weight by about the learning rate (3e-4 for DC), and an
iteration takes tens of them.  The log-std is left alone: the mean action does not read it.

The aggregate: per (task, scale) the share of perturbed starts that fall more than
``MAX_DIP`` below their start (the gate's own dip), with its count; per (task, seed) the
smallest scale at which a draw falls that far ("topples at").
"""

from __future__ import annotations

import copy

import numpy as np
import torch

from dc_lesson import evaluation as _evaluation
from dc_lesson.algorithms import bc as _bc
from dc_lesson.data import store as _store
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies import _imitation as _im
from dc_lesson.experiments.studies import competence as _competence

NAME = "start_noise"
TASKS = _competence.KEEP_TASKS
SCALES = (1e-4, 1e-3, 3e-3, 1e-2)
DRAWS = 3
NOISE_SEED = 4000


def cells_at(b) -> list[cells.Cell]:
    return [cells.make_cell(NAME, "bc", task, _competence.N_DEMOS, seed,
                            {"budget": b.name, "start_epochs": b.bc_max_epochs,
                             "eval_episodes": b.competence_curve_episodes,
                             "eval_seed": protocol.expert_eval_seed(0),
                             "scales": list(SCALES), "draws": DRAWS, "noise_seed": NOISE_SEED})
            for task in TASKS for seed in range(b.competence_keep_seeds)]


def perturbed(policy, scale: float, generator: torch.Generator):
    """A copy of ``policy`` whose mean network's parameters each get N(0, scale^2) noise."""
    out = copy.deepcopy(policy)
    with torch.no_grad():
        for p in out.mean_net.parameters():
            p.add_(torch.randn(p.shape, generator=generator) * scale)
    return out


def run_cell(cell, needs):
    c = cell.config
    demos = _store.load_demos(cell.task, n_trajectories=cell.n_demos)
    # the competence cells' own start: the same key, so the same cached policy in a worker
    start = _im.cached_start(
        (cell.task, cell.n_demos, "competence", cell.seed, c["start_epochs"], False),
        lambda: _bc.warm_start_policy(demos, cell.seed, max_epochs=c["start_epochs"]))

    def score(policy) -> float:
        return float(_evaluation.evaluate_policy(
            cell.task, policy, None, n_episodes=c["eval_episodes"], seed=c["eval_seed"],
            divergences=False)["scaled_return"])

    g = torch.Generator().manual_seed(int(c["noise_seed"]) * 1000 + cell.seed)
    noise = {str(s): [score(perturbed(start, s, g)) for _ in range(c["draws"])]
             for s in c["scales"]}
    return {"start": score(start), "noise": noise}, None


def topples(start: float, scores: dict, max_dip: float = _competence.MAX_DIP) -> float | None:
    """The smallest scale (keys of ``scores``, as strings) at which a perturbed copy falls
    more than ``max_dip`` below ``start``; None if none does."""
    for scale in sorted(scores, key=float):
        if any(start - v > max_dip for v in scores[scale]):
            return float(scale)
    return None


def aggregate(records, b) -> dict:
    obs = [{"task": r["cell"]["task"], "seed": r["cell"]["seed"],
            "start": r["result"]["start"], "noise": r["result"]["noise"]} for r in records]
    obs.sort(key=lambda o: (TASKS.index(o["task"]), o["seed"]))
    shares = []
    for task in TASKS:
        mine = [o for o in obs if o["task"] == task]
        for s in SCALES:
            falls = [o["start"] - v > _competence.MAX_DIP for o in mine
                     for v in o["noise"].get(str(s), [])]
            if falls:
                shares.append({"task": task, "scale": s, "fell": int(sum(falls)),
                               "of": len(falls), "share": float(np.mean(falls))})
    return {"tasks": list(TASKS), "scales": list(SCALES), "draws": DRAWS,
            "max_dip": _competence.MAX_DIP,
            "rule": "a perturbed start falls when its score is more than max_dip below its "
                    "start's; it topples at the smallest scale at which a draw falls",
            "shares": shares,
            "seeds": [{"task": o["task"], "seed": o["seed"], "start": o["start"],
                       "topples at": topples(o["start"], o["noise"])} for o in obs],
            "observations": obs}


STUDY = cells.Study(NAME, "the competence starts under small random changes of their weights",
                    cells=cells_at, run_cell=run_cell, aggregate=aggregate,
                    result_file="start_noise.json")

__all__ = ["DRAWS", "NAME", "NOISE_SEED", "SCALES", "STUDY", "TASKS", "aggregate", "cells_at",
           "perturbed", "run_cell", "topples"]
