"""The mixture BC trained until it matches plain BC: the start of every mixture DC row
(``modes``' ``dc-mix`` rows, ``competence``'s ``dc-mix`` variant), in one place so both
studies apply the same rule and name it in their cells' identity (:data:`RULE`).

The same seed's plain BC (``table1``'s ``bc-full`` training, the same demonstrations) is
scored with its mean action on :data:`MATCH_EPISODES` episodes from :data:`MATCH_SEED` (no
evaluation or demonstration episode shares their starts); the mixture is trained for
``bc_max_epochs`` epochs, then twice and four times as many (:data:`MATCH_SCALES`, each a
fresh, deterministic run), and the first that scores at least plain BC's score less
:data:`MATCH_TOLERANCE` on those episodes (no weaker: a mixture above plain BC is no
handicap) is kept, else the longest.
"""

from __future__ import annotations

import dataclasses

from dc_lesson import evaluation as _evaluation
from dc_lesson.algorithms import bc as _bc
from dc_lesson.experiments import protocol
from dc_lesson.experiments.studies import table1 as _t1

MATCH_SEED = 5000          # away from the evaluation (1000+), reference (3000) and headroom's
MATCH_EPISODES = 10
MATCH_TOLERANCE = 0.05     # the verdicts' smallest effect on scaled return
MATCH_SCALES = (1, 2, 4)   # the mixture's epochs, in multiples of bc_max_epochs
RULE = {"seed": MATCH_SEED, "episodes": MATCH_EPISODES, "tolerance": MATCH_TOLERANCE,
        "scales": list(MATCH_SCALES)}   # part of a matched start's cell identity


def _plain(task, demos, seed, b):
    return _bc.train(task, demos, _t1._bc_config(b, seed, False, full=True),
                     progress=False).policy


def _match_score(task, policy) -> float:
    return float(_evaluation.evaluate_policy(task, policy, None, n_episodes=MATCH_EPISODES,
                                             seed=MATCH_SEED, divergences=False)
                 ["scaled_return"])


def matched_mixture(task: str, demos, seed: int, b) -> tuple:
    """``(mixture BC policy, record)`` by the module's rule; the record holds the target,
    every try's score and epochs, and whether it matched."""
    protocol.check_disjoint(task, {"match": (MATCH_SEED, MATCH_EPISODES),
                                   "evaluation": (protocol.expert_eval_seed(0),
                                                  b.il_eval_episodes)})
    target = _match_score(task, _plain(task, demos, seed, b))
    tries = []
    for scale in MATCH_SCALES:
        cfg = dataclasses.replace(_t1._bc_config(b, seed, True, full=True),
                                  epochs=scale * b.bc_max_epochs)
        policy = _bc.train(task, demos, cfg, progress=False).policy
        tries.append({"epochs": cfg.epochs, "scaled_return": _match_score(task, policy)})
        if tries[-1]["scaled_return"] >= target - MATCH_TOLERANCE:
            break
    return policy, {"target": target, "tries": tries,
                    "matched": tries[-1]["scaled_return"] >= target - MATCH_TOLERANCE}


__all__ = ["MATCH_EPISODES", "MATCH_SCALES", "MATCH_SEED", "MATCH_TOLERANCE", "RULE",
           "matched_mixture"]
