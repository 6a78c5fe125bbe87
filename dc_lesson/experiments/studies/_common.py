"""What the studies share: the BC warm-start cells' configs, subsampled features, and the
reference a cell reads."""

from __future__ import annotations

import numpy as np

from dc_lesson.experiments import protocol

FEATURES_KEPT = 2000    # mode features per policy and cell in the .npz (a seeded subsample)


def reference(needs) -> protocol.Reference:
    """The :class:`protocol.Reference` among a cell's needs (its first)."""
    return protocol.reference_from(*needs[0])


def features(named: dict, seed: int) -> dict:
    """``{name: at most FEATURES_KEPT rows}`` of each policy's evaluation features."""
    return {k: protocol.subsample(v, FEATURES_KEPT, seed) for k, v in named.items()}


def expert_rows(study: str, tasks, budget, eval_episodes: int) -> list:
    """The expert-vs-expert cells of a study: per task, as many disjoint expert samples as the
    study has seeds there."""
    return [protocol.expert_row_cell(study, t, s, eval_episodes)
            for t in tasks for s in budget.seeds_for(t)]


def run_expert_or(cell, needs, run):
    """``protocol.run_expert_row`` for the expert row's cells, ``run`` for the others."""
    if cell.learner == "expert":
        return protocol.run_expert_row(cell, needs)
    return run(cell, needs)


def finite(x) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)
