"""Judging learners: the measures, and one way to evaluate every learner.

* ``metrics``: EMD (POT), k-NN KL and reverse KL of state distributions, scaled return,
  distance to the expert's states;
* ``evaluate``: :func:`evaluate_policy`: fresh episodes, scaled return, EMD / KL / RKL against
  a reference set, mode shares; :class:`CheckpointCurve`: return against interactions from
  deterministic evaluations during a run.
"""

from dc_lesson.evaluation import metrics
from dc_lesson.evaluation import evaluate
from dc_lesson.evaluation.evaluate import (ACTIONS, COMPONENTS, EVAL_SEED, MEASURES, CheckpointCurve,
                                           evaluate_both,
                                           evaluate_policy, learner_features, measure)

__all__ = ["ACTIONS", "COMPONENTS", "EVAL_SEED", "MEASURES", "CheckpointCurve", "evaluate", "evaluate_both", "evaluate_policy", "learner_features", "measure",
           "metrics"]
