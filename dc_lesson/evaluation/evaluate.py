"""One way to judge every learner (BC, GAIL, DC, ...): the same episodes, the same measures.

:func:`evaluate_policy` runs a policy for ``n_episodes`` fresh episodes and measures, against a
task's demonstrations:

* the mean return and the scaled return (:func:`metrics.scaled_return`: random 0, expert 1);
* EMD, KL(expert || learner) and KL(learner || expert) between the mode features of *all* the
  task's demonstrations (one fixed reference, so every learner is compared with the same
  thing) and those of every step of the evaluation episodes (:func:`metrics.compare`);
* for multi-mode tasks, the share of episodes in each mode.

By default the policy acts with its mean action (``GaussianPolicy.act``, what
:func:`rollout.collect` calls for a torch module); ``actions="sampled"`` draws its actions from
the policy at its learned standard deviation instead (:class:`~dc_lesson.nn.StochasticPolicy`,
seeded): the policy Eq. 2 of the paper is about, whose mode shares can differ from the mean
action's (chapter 04); ``actions="components"`` draws a mixture policy's component and acts
with its mean (:class:`~dc_lesson.nn.mixture.ComponentMeans`: the mode question without the
within-component noise).  :func:`evaluate_both` gives the two side by side.  For multi-mode
tasks ``mode_tv`` is the total-variation distance of the episodes' mode shares ("none"
included) from the reference's.  The evaluation episodes start from
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
from dc_lesson.data import modes as _modes
from dc_lesson.nn.mixture import ComponentMeans, MixturePolicy
from dc_lesson.nn.policies import StochasticPolicy

EVAL_SEED = 1000
MEASURES = ("scaled_return", "return", "emd", "kl", "rkl")


def learner_features(trajectories) -> np.ndarray:
    """The mode features of every step of the episodes (the last state, after the final
    action, is left out, as for the demonstrations' pairs)."""
    return np.concatenate([t.mode_features[:-1] for t in trajectories])


def measure(task: str, trajectories, reference: _data.Demonstrations | None,
            emd_n_max: int | None = 2000, variant: str | None = None) -> dict:
    """The measures of the module docstring for episodes already collected; with no
    ``reference`` (None) only the returns and mode shares, the divergences None.
    ``variant``: scale the return by that expert variant's manifest entry."""
    trajectories = list(trajectories)
    if isinstance(reference, _data.Demonstrations):
        reference = reference.whole()   # every step of the expert's episodes, subsampled or not
    scaled, _ = _metrics.scaled_return(task, trajectories, variant=variant)
    returns = _rollout.returns(trajectories)
    out = {"scaled_return": scaled, "return": float(returns.mean()),
           "return_std": float(returns.std()),
           **(_metrics.compare(reference.mode_features, learner_features(trajectories),
                               n_max=emd_n_max, seed=0) if reference is not None
              else {"emd": None, "kl": None, "rkl": None})}
    multi = len(_tasks.spec(task).modes) > 1
    out["mode_shares"] = _metrics.mode_shares(task, trajectories) if multi else None
    out["mode_tv"] = None
    if multi and reference is not None:   # against the reference's own shares
        ref_shares = (_modes.mode_shares(task, reference.trajectories)
                      if hasattr(reference, "trajectories")
                      else getattr(reference, "mode_shares", None))
        if ref_shares is not None:
            out["mode_tv"] = _modes.total_variation(out["mode_shares"], ref_shares)
    return out


ACTIONS = ("mean", "sampled")
COMPONENTS = "components"   # a mixture's drawn component, acting with its mean (module docstring)


def evaluate_policy(task: str, policy, reference: _data.Demonstrations | None = None, *,
                    n_episodes: int = 50, seed: int = EVAL_SEED,
                    emd_n_max: int | None = 2000, keep_features: bool = False,
                    actions: str = "mean", divergences: bool = True,
                    variant: str | None = None) -> dict:
    """Runs ``policy`` for ``n_episodes`` fresh episodes and measures it (module docstring).

    ``reference`` defaults to all the task's demonstrations; ``divergences=False`` measures
    the returns (and mode shares) only, against no reference: EMD, KL and RKL are None
    (for a study that has no fresh expert episodes to compare with, rather than comparing
    with the training data).  With ``keep_features`` the
    result also holds ``features``, the learner's mode features (for coverage plots).
    ``actions``: ``"mean"`` (the mean action) or ``"sampled"`` (actions drawn at the
    policy's learned std, from a generator seeded by ``seed``) or ``"components"`` (a
    mixture's component drawn by its weight at each step, acting with its mean:
    :class:`~dc_lesson.nn.mixture.ComponentMeans`; a Gaussian policy's mean action).
    ``variant``: the scaled
    return's ends are that expert variant's (``"planner"``), not the task's default expert's.
    """
    if actions not in ACTIONS + (COMPONENTS,):
        raise ValueError(f"actions must be one of {ACTIONS + (COMPONENTS,)}, got {actions!r}")
    _rollout.check_policy(task, policy)   # before loading anything or running an episode
    if not divergences:
        reference = None
    elif reference is None:
        reference = _data.load_demos(task)
    if actions == "sampled":
        acting = StochasticPolicy(policy, seed=seed)
    elif actions == COMPONENTS and isinstance(policy, MixturePolicy):
        acting = ComponentMeans(policy, seed=seed)
    elif actions == COMPONENTS and not getattr(policy, "gaussian", False):
        raise ValueError(f"actions='components' needs a mixture or a Gaussian policy, got "
                         f"{type(policy).__name__}; evaluate it with actions='mean' instead")
    else:   # the mean action; a Gaussian's one component acts with its mean
        acting = policy
    t0 = time.perf_counter()
    trajs = _rollout.collect(task, acting, n_episodes, seed=seed, progress=False)
    t1 = time.perf_counter()
    out = measure(task, trajs, reference, emd_n_max, variant=variant)
    out["eval_seconds"], out["measure_seconds"] = t1 - t0, time.perf_counter() - t1
    out["returns"] = [round(float(t.ret), 3) for t in trajs]
    if keep_features:
        out["features"] = learner_features(trajs)
    out["actions"] = actions
    return out


def evaluate_both(task: str, policy, reference: _data.Demonstrations | None = None,
                  **kwargs) -> dict:
    """``{"mean": ..., "sampled": ...}``: :func:`evaluate_policy` with either kind of action,
    on the same episodes' initial states."""
    if reference is None:
        reference = _data.load_demos(task)
    return {a: evaluate_policy(task, policy, reference, actions=a, **kwargs) for a in ACTIONS}


__all__ = ["ACTIONS", "COMPONENTS", "EVAL_SEED", "MEASURES", "evaluate_both", "evaluate_policy",
           "learner_features", "measure"]


class CheckpointCurve:
    """Return against interactions from deterministic evaluations (Figures 5 and 11).

    Passed as a learner's ``callback(row, policy)``: each time the run's interactions
    (``row["env_steps"]``, or ``row["steps"]``) first reach one of ``points`` evenly spaced
    marks of ``total_steps``, ``evaluate(policy)`` runs and its scaled return is kept in
    :attr:`points` as ``{"steps", "scaled_return"}``.  The evaluation uses its own episodes
    and the policy's mean action, so it touches none of the run's generators: the run ends as
    it would without it.  Never asks the learner to stop."""

    def __init__(self, evaluate, total_steps: int, points: int):
        if points < 1 or total_steps < 1:
            raise ValueError(f"a curve needs at least one point over at least one interaction, "
                             f"got {points} points over {total_steps}")
        self.evaluate = evaluate
        self.marks = [int(round(total_steps * (i + 1) / points)) for i in range(points)]
        self.points: list[dict] = []

    def __call__(self, row: dict, policy) -> bool:
        steps = row.get("env_steps", row.get("steps"))
        while self.marks and steps is not None and steps >= self.marks[0]:
            self.marks.pop(0)
            self.points.append({"steps": int(steps),
                                "scaled_return": self.evaluate(policy)["scaled_return"]})
        return False
