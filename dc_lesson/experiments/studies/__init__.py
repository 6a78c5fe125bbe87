"""The cell studies, one module per result file (``dc-lesson sweep NAME``).

| study | result file | cells |
|---|---|---|
| ``reference`` | (read by the others) | fresh expert episodes per task, collected once |
| ``bc_demos`` | ``bc_demos.json`` | BC per task, demonstration count and seed; the expert row |
| ``bc_drift`` | ``bc_drift_cells.json`` (chapter 01) | BC's distance from the demonstrated states, and the expert's |
| ``gail_modes`` | ``gail_modes.json`` (not run: ``table1``'s ``gail`` and ``gail-coin`` rows hold this at the same seeds and chapter 02 reads them; the module gives ``gail_lr`` its cells) | BC warm start and GAIL per multi-mode task and seed |
| ``gail_lr`` | ``gail_lr.json`` | GAIL per learning rate and seed on hopper (11 demonstrations) |
| ``dc_modes`` | ``dc_modes.json`` (not run: ``table1``'s ``dc`` and ``dc-coin`` rows hold it; the module gives the hopper ablations their cells) | BC warm start and DC per multi-mode task and seed |
| ``dc_ablation`` | ``dc_ablation.json`` | DC's loop counts, one long loop and consensus ADMM on hopper (11 demonstrations), every seed |
| ``dc_lr`` | ``dc_lr.json`` | DC per learning rate and seed on hopper (11 demonstrations) |
| ``table1`` | ``table1.json`` | every learner and control on the multi-mode tasks, both evaluations |
| ``table3`` | ``table3.json`` | every learner on the single-mode tasks per demonstration count |
| ``softflow_fit`` | ``softflow_fit_cells.json`` (chapter 03 reads it and the cells' arrays through ``fit_record``) | SoftFlow on the circle toy and on expert states, and each task's data and baselines |
"""

from __future__ import annotations

import importlib

from dc_lesson.experiments.cells import Study

NAMES = ("reference", "bc_demos", "bc_drift", "gail_modes", "gail_lr", "dc_modes",
         "dc_ablation", "dc_lr", "table1", "table3", "softflow_fit")


# The grid the book reads: every study but the two that table1 supersedes (its gail, gail-coin,
# dc and dc-coin rows hold their runs at the same seeds; their modules still give the hopper
# studies their cells).  ``dc-lesson sweep all`` runs these, and its ``--dry-run`` ledgers them.
SUPERSEDED = {"gail_modes": "table1 (rows gail, gail-coin)",
              "dc_modes": "table1 (rows dc, dc-coin)"}
BOOK = tuple(n for n in NAMES if n not in SUPERSEDED)


class UnknownStudyError(ValueError):
    """A study name that is not in :data:`NAMES`."""


def get(name: str) -> Study:
    """The study called ``name`` (dashes and underscores alike: ``bc-demos`` is ``bc_demos``)."""
    key = name.replace("-", "_")
    if key not in NAMES:
        raise UnknownStudyError(f"unknown study {name!r}; the studies are: {', '.join(NAMES)}")
    return importlib.import_module(f"dc_lesson.experiments.studies.{key}").STUDY


__all__ = ["BOOK", "NAMES", "SUPERSEDED", "UnknownStudyError", "get"]
