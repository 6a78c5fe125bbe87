"""The learners: one module per algorithm, one interface, and the registry by name.

========= ===========================================================================
``bc``    behaviour cloning: maximum likelihood on the expert's pairs (Eq. 1)
``ppo``   proximal policy optimisation on the task's reward (or any reward function)
``gail``  GAIL: a discriminator's reward, optimised with PPO
``dc``    Distributional Cloning: BC and PPO on a SoftFlow reward, combined by ADMM
``dril``  DRIL: PPO on a BC ensemble's disagreement (+1 / -1), interleaved with BC steps
``pwil``  PWIL: PPO on the reward of a greedy Wasserstein coupling to the expert's atoms
``ndi``   NDI: PPO on a SoftFlow's log q(s, a) of the expert, plus a state-entropy bonus
``gpril`` GPRIL: likelihood on expert pairs and on predecessors sampled from MAFs
========= ===========================================================================

Every learner is called the same way (:mod:`dc_lesson.algorithms.base`)::

    from dc_lesson import algorithms, budget, data
    algo = algorithms.get("gail")
    config = algo.preset(budget.current(), seed=0)
    result = algo.train("reacher4", data.load_demos("reacher4", 18), config)
    result.policy, result.log, result.models

Adding a learner is one module with ``train``, a config dataclass and ``preset``, plus one
line in :data:`ALGORITHMS`.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

from dc_lesson.algorithms import base, bc, dc, dril, gail, gpril, ndi, ppo, pwil
from dc_lesson.algorithms.base import LearnerInputError, TrainResult


@dataclasses.dataclass(frozen=True)
class Algorithm:
    """A learner of the registry: its ``train`` function, config class and budget preset."""

    name: str
    train: Callable[..., TrainResult]
    config: type
    preset: Callable
    summary: str
    uses_demos: bool = True


ALGORITHMS: dict[str, Algorithm] = {
    "bc": Algorithm("bc", bc.train, bc.BCConfig, bc.preset,
                    "behaviour cloning: maximum likelihood on the expert's pairs"),
    "ppo": Algorithm("ppo", ppo.train, ppo.PPOConfig, ppo.preset,
                     "PPO on the task's own reward (no demonstrations)", uses_demos=False),
    "gail": Algorithm("gail", gail.train, gail.GAILConfig, gail.preset,
                      "GAIL: a discriminator's reward optimised with PPO"),
    "dc": Algorithm("dc", dc.train, dc.DCConfig, dc.preset,
                    "Distributional Cloning: BC + PPO on a SoftFlow reward, by ADMM"),
    "dril": Algorithm("dril", dril.train, dril.DRILConfig, dril.preset,
                      "DRIL: PPO on a BC ensemble's disagreement, interleaved with BC"),
    "pwil": Algorithm("pwil", pwil.train, pwil.PWILConfig, pwil.preset,
                      "PWIL: PPO on a greedy Wasserstein coupling's reward"),
    "ndi": Algorithm("ndi", ndi.train, ndi.NDIConfig, ndi.preset,
                     "NDI: PPO on a SoftFlow's log q(s, a) plus a kNN state-entropy bonus"),
    "gpril": Algorithm("gpril", gpril.train, gpril.GPRILConfig, gpril.preset,
                       "GPRIL: likelihood on expert pairs and MAF-sampled predecessors"),
}


class UnknownAlgorithmError(KeyError):
    """A learner name that is not in :data:`ALGORITHMS`."""

    def __str__(self):
        return str(self.args[0])


def get(name: str) -> Algorithm:
    """The learner ``name``; an error naming the registered ones otherwise."""
    try:
        return ALGORITHMS[name]
    except (KeyError, TypeError):
        raise UnknownAlgorithmError(f"unknown learner {name!r}; the learners are: "
                                    f"{', '.join(ALGORITHMS)}") from None


__all__ = ["ALGORITHMS", "Algorithm", "LearnerInputError", "TrainResult",
           "UnknownAlgorithmError", "base", "bc", "dc", "dril", "gail", "get", "gpril", "ndi",
           "ppo", "pwil"]
