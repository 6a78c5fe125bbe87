"""Algorithm 2 with GAIL's reward in place of log P_w(s'): DC's control arm ``reward="gail"``.

Everything of DC stays (the BC step, the PPO step on pi', the average); only the density that
scores the states pi' reaches changes: instead of a SoftFlow fitted once per loop, a
discriminator D(s') = P(expert | s') is trained every iteration on the expert's states against
the batch's next states, as GAIL trains its own, and the reward is GAIL's

    r(s') = -log(1 - D(s')) = softplus(f(s')),    f the discriminator's logit.

Choices (ours; the paper has no such arm): the discriminator sees states only, like log P_w(s')
(so the arm differs from DC in the density estimator alone, and the learner's action noise
cannot give it away); its network, learning rate, steps and batch are GAIL's defaults
(:class:`dc_lesson.algorithms.gail.GAILConfig`), fixed here so DC's config does not grow; its
minibatches are drawn with DC's one generator, so the run stays deterministic and resumable.
"""

from __future__ import annotations

import torch

from dc_lesson.algorithms import gail as _gail
from dc_lesson.nn import fast as _fast

_DEFAULTS = _gail.GAILConfig()


class DiscriminatorReward:
    """A state-only GAIL discriminator and its reward, updated once per DC iteration.  A DC
    checkpoint holds ``disc`` and ``optimizer`` (``dc._parts``)."""

    def __init__(self, expert_states: torch.Tensor, obs_dim: int, seed: int):
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self.disc = _gail.Discriminator(obs_dim, 0, _DEFAULTS.disc_hidden,
                                            _DEFAULTS.disc_activation, use_actions=False)
        self.disc.fit_input_stats(expert_states, None)
        self.optimizer = _fast.adam(self.disc.parameters(), lr=_DEFAULTS.disc_lr)
        self.expert_states = expert_states

    def __call__(self, next_obs: torch.Tensor, generator: torch.Generator):
        """Trains D on expert states against ``next_obs`` (T, N, obs_dim), then returns the
        reward of each next state (T, N) and the logged terms."""
        learner = next_obs.reshape(-1, next_obs.shape[-1])
        steps = []
        for _ in range(_DEFAULTS.disc_steps):
            ie = torch.randint(len(self.expert_states), (_DEFAULTS.disc_batch,),
                               generator=generator)
            il = torch.randint(len(learner), (_DEFAULTS.disc_batch,), generator=generator)
            steps.append(_gail.discriminator_step(self.disc, self.optimizer,
                                                  self.expert_states[ie], None, learner[il],
                                                  None))
        with torch.no_grad():
            logit = self.disc(next_obs, None)
        n = len(steps)
        return _gail.reward_from_logit(logit, "gail"), {
            "disc_loss": sum(s["loss"] for s in steps) / n,
            "disc_acc_expert": sum(s["acc_expert"] for s in steps) / n,
            "disc_acc_learner": float((logit < 0).float().mean())}


__all__ = ["DiscriminatorReward"]
