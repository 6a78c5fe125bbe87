"""One way to judge every learner (BC, GAIL, DC, ...): the same episodes, the same measures.

:func:`evaluate_policy` runs a policy for ``n_episodes`` fresh episodes and measures, against a
task's demonstrations:

* the mean return and the scaled return (:func:`metrics.scaled_return`: random 0, expert 1);
* EMD, KL(expert || learner) and KL(learner || expert) between the mode features of *all* the
  task's demonstrations (one fixed reference, so every learner is compared with the same
  thing) and those of every step of the evaluation episodes (:func:`metrics.compare`);
* for multi-mode tasks, the share of episodes in each mode.

The policy acts with its mean action (``GaussianPolicy.act``, what :func:`rollout.collect`
calls for a torch module), as BC's benchmark does; the evaluation episodes start from
``EVAL_SEED``'s initial states, none of which is a demonstration's (the demonstrations use
seed 0 and the manifest's expert and random evaluations seeds 1 and 2).
"""

from __future__ import annotations

import time

import numpy as np

from dc_lesson import data as _data
from dc_lesson.evaluation import metrics as _metrics
from dc_lesson.data import rollout as _rollout
from dc_lesson import tasks as _tasks

EVAL_SEED = 1000
MEASURES = ("scaled_return", "return", "emd", "kl", "rkl")


def learner_features(trajectories) -> np.ndarray:
    """The mode features of every step of the episodes (the last state, after the final
    action, is left out, as for the demonstrations' pairs)."""
    return np.concatenate([t.mode_features[:-1] for t in trajectories])


def measure(task: str, trajectories, reference: _data.Demonstrations,
            emd_n_max: int | None = 2000) -> dict:
    """The measures of the module docstring for episodes already collected."""
    trajectories = list(trajectories)
    scaled, _ = _metrics.scaled_return(task, trajectories)
    returns = _rollout.returns(trajectories)
    out = {"scaled_return": scaled, "return": float(returns.mean()),
           "return_std": float(returns.std()),
           **_metrics.compare(reference.mode_features, learner_features(trajectories),
                              n_max=emd_n_max, seed=0)}
    multi = len(_tasks.spec(task).modes) > 1
    out["mode_shares"] = _metrics.mode_shares(task, trajectories) if multi else None
    return out


def evaluate_policy(task: str, policy, reference: _data.Demonstrations | None = None, *,
                    n_episodes: int = 50, seed: int = EVAL_SEED,
                    emd_n_max: int | None = 2000, keep_features: bool = False) -> dict:
    """Runs ``policy`` for ``n_episodes`` fresh episodes and measures it (module docstring).

    ``reference`` defaults to all the task's demonstrations.  With ``keep_features`` the
    result also holds ``features``, the learner's mode features (for coverage plots).
    """
    _rollout.check_policy(task, policy)   # before loading anything or running an episode
    if reference is None:
        reference = _data.load_demos(task)
    t0 = time.perf_counter()
    trajs = _rollout.collect(task, policy, n_episodes, seed=seed, progress=False)
    t1 = time.perf_counter()
    out = measure(task, trajs, reference, emd_n_max)
    out["eval_seconds"], out["measure_seconds"] = t1 - t0, time.perf_counter() - t1
    out["returns"] = [round(float(t.ret), 3) for t in trajs]
    if keep_features:
        out["features"] = learner_features(trajs)
    return out


__all__ = ["EVAL_SEED", "MEASURES", "evaluate_policy", "learner_features", "measure"]
