"""The cell studies, one module per result file (``dc-lesson sweep NAME``).

| study | result file | cells |
|---|---|---|
| ``reference`` | (read by the others) | fresh expert episodes per task, collected once |
| ``bc_demos`` | ``bc_demos.json`` | BC per task, demonstration count and seed; the expert row |
| ``bc_drift`` | ``bc_drift_cells.json`` (chapter 01) | BC's distance from the demonstrated states, and the expert's |
| ``gail_lr`` | ``gail_lr.json`` | GAIL per learning rate and seed on hopper (11 demonstrations) |
| ``dc_ablation`` | ``dc_ablation.json`` | DC's loop counts, one long loop and consensus ADMM on hopper (11 demonstrations), every seed |
| ``dc_lr`` | ``dc_lr.json`` | DC per learning rate and seed on hopper (11 demonstrations) |
| ``table1`` | ``table1.json`` | every learner and control on the multi-mode tasks, both evaluations |
| ``table3`` | ``table3.json`` | every learner on the single-mode tasks per demonstration count |
| ``competence`` | ``competence.json`` | every RL learner from a perfect and from a weak start, with checkpoint curves: the gate a learner passes before it judges (issue 38) |
| ``start_noise`` | ``start_noise.json`` (chapter 05, beside the gate) | the competence study's BC starts with small random noise on their weights: how much change they survive |
| ``clonable`` | ``clonable.json`` (chapter 00's floor table) | BC from 25 demonstrations of each single-mode expert, per seed |
| ``headroom`` | ``headroom.json`` (issue 41: the benchmark's protocol) | BC on GAIL's subsampled and on full-length demonstrations per task, count and seed |
| ``benchmark`` | ``benchmark.json`` (issue 41: Table III, Figures 9 and 11 rerun) | BC and every learner that passed the gate, on the headroom study's demonstrations, at the competence curves' interactions, per task, count and seed; the expert row |
| ``ablations`` | ``ablations.json`` (issue 41: Figures 3-6 rerun) | DC's loops, its equal-budget control, consensus ADMM and its learning rates on the benchmark's hopper start, per seed |
| ``modes`` | ``modes.json`` (issue 41: Table I rerun) | DC and the gate-passing learners on the multi-mode tasks, DC from the best BC, the mixture BC trained until it matches plain BC, 10 seeds per task |
| ``softflow_fit`` | ``softflow_fit_cells.json`` (chapter 03 reads it and the cells' arrays through ``fit_record``) | SoftFlow on the circle toy and on expert states, and each task's data and baselines |

Beside them, what they are made of: ``_learners`` (the GAIL and DC cells of the hopper studies),
``_imitation`` (the imitation protocol every learner study shares: warm starts, observations,
the expert rows) and ``_common`` (features, the reference a cell reads).
"""

from __future__ import annotations

import importlib

from dc_lesson.experiments.cells import Study

NAMES = ("reference", "bc_demos", "bc_drift", "gail_lr", "dc_ablation", "dc_lr", "table1",
         "table3", "softflow_fit", "competence", "start_noise", "clonable", "headroom",
         "benchmark", "ablations", "modes")

# The grid the book reads: every study.  ``dc-lesson sweep all`` runs them in this order (the
# reference first: the others read it), and its ``--dry-run`` ledgers them.
BOOK = NAMES

# The first grids, run before the competence gate (issue 38) and kept, complete, as the record
# of what the book first said (chapter 06's "first grid", chapter 02's GAIL sweep): study ->
# the study that asks its question again.  The ledger totals the final grid without them.
SUPERSEDED = {"gail_lr": "ablations (GAIL failed the gate: not rerun)",
              "dc_ablation": "ablations", "dc_lr": "ablations", "table1": "modes",
              "table3": "benchmark"}


class UnknownStudyError(ValueError):
    """A study name that is not in :data:`NAMES`."""


def get(name: str) -> Study:
    """The study called ``name`` (dashes and underscores alike: ``bc-demos`` is ``bc_demos``)."""
    key = name.replace("-", "_")
    if key not in NAMES:
        raise UnknownStudyError(f"unknown study {name!r}; the studies are: {', '.join(NAMES)}")
    return importlib.import_module(f"dc_lesson.experiments.studies.{key}").STUDY


__all__ = ["BOOK", "NAMES", "SUPERSEDED", "UnknownStudyError", "get"]
