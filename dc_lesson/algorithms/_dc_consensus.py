r"""DC's Algorithm 2, one iteration: the paper's parameter averaging, and consensus ADMM.

Both take Eq. 4's two local steps the same way (:func:`local_steps`: BC steps on one copy, one
PPO update on pi') and differ in what follows them:

* :func:`parameter_averaging` (``DCConfig.update="average"``, the paper's): pi <- (pi + pi') / 2;
* :func:`consensus_admm` (``update="admm"``): z <- mean(x_i + u_i), u_i <- u_i + x_i - z.

Why each choice is what it is: :mod:`dc_lesson.algorithms.dc`'s docstring.  ``dc.train``
samples the batch and the rewards, then calls one of the two.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import torch

from dc_lesson.algorithms import bc as _bc
from dc_lesson.algorithms.ppo import compute_gae, ppo_update
from dc_lesson.nn import fast as _fast
from dc_lesson.nn.policies import GaussianPolicy, ValueNetwork


# -- parameters as flat vectors ------------------------------------------------------------------

def policy_parameters(policy: GaussianPolicy, include_log_std: bool = True) -> list:
    """The parameters DC averages: the mean network's, and the log-std if asked (a mixture
    policy, whose spreads are outputs of its network, averages all its parameters)."""
    if not policy.gaussian:
        return list(policy.parameters())
    return list(policy.mean_net.parameters()) + ([policy.log_std] if include_log_std else [])


def flat(params) -> torch.Tensor:
    return torch.cat([p.detach().reshape(-1) for p in params])


@torch.no_grad()
def _set_flat(params, vector: torch.Tensor) -> None:
    i = 0
    for p in params:
        n = p.numel()
        p.copy_(vector[i:i + n].reshape(p.shape))
        i += n


@torch.no_grad()
def average_into(target: GaussianPolicy, other: GaussianPolicy,
                 average_log_std: bool = True) -> None:
    """target <- (target + other) / 2, element-wise, over the mean network's parameters and
    (with ``average_log_std``) the log-std; without it, target takes other's log-std."""
    for p, q in zip(policy_parameters(target, False), policy_parameters(other, False)):
        p.add_(q).mul_(0.5)
    if not target.gaussian:
        return     # a mixture: its spreads are network outputs, averaged with the rest
    if average_log_std:
        target.log_std.add_(other.log_std).mul_(0.5)
    else:
        target.log_std.copy_(other.log_std)


@torch.no_grad()
def copy_into(target: torch.nn.Module, source: torch.nn.Module) -> None:
    """Copies parameters and buffers in place (so an optimiser holding ``target``'s tensors
    keeps its state)."""
    for p, q in zip(target.parameters(), source.parameters()):
        p.copy_(q)
    for b, c in zip(target.buffers(), source.buffers()):
        b.copy_(c)


# -- what Algorithm 2 updates --------------------------------------------------------------------

@dataclasses.dataclass
class Learner:
    """Everything Algorithm 2 updates.  ``pi`` is the policy (z under ADMM); ``pi_prime`` its
    PPO copy; ``pi_bc`` the BC copy x_1 under ADMM (None under averaging, where pi itself takes
    the BC step); ``duals`` the scaled dual vectors (u_1, u_2) under ADMM."""
    pi: GaussianPolicy
    pi_prime: GaussianPolicy
    value_fn: ValueNetwork
    opt_bc: torch.optim.Optimizer
    opt_ppo: torch.optim.Optimizer
    pi_bc: GaussianPolicy | None = None
    duals: list | None = None


def make_learner(policy: GaussianPolicy, config, obs_dim: int) -> Learner:
    """The two copies, the critic and their optimisers, from a (BC-initialised) policy and a
    ``dc.DCConfig``."""
    pi = policy
    pi_prime = copy.deepcopy(policy)
    value_fn = ValueNetwork(obs_dim, config.ppo.hidden, norm_obs=pi.obs_norm is not None)
    if pi.obs_norm is not None:   # the critic sees the policy's (frozen) normalisation
        value_fn.obs_norm.load_state_dict(pi.obs_norm.state_dict())
    pi_bc = copy.deepcopy(policy) if config.update == "admm" else None
    bc_target = pi_bc if pi_bc is not None else pi
    opt_bc = _fast.adamw(bc_target.parameters(), lr=config.lr, eps=1e-5,
                         weight_decay=config.weight_decay)
    # Weight decay on the policy copy only, not on the critic.
    opt_ppo = _fast.adamw([{"params": list(pi_prime.parameters()),
                            "weight_decay": config.weight_decay},
                           {"params": list(value_fn.parameters()), "weight_decay": 0.0}],
                          lr=config.lr, eps=1e-5)
    duals = None
    if config.update == "admm":
        n = flat(policy_parameters(pi)).numel()
        duals = [torch.zeros(n), torch.zeros(n)]
    return Learner(pi, pi_prime, value_fn, opt_bc, opt_ppo, pi_bc, duals)


# -- Eq. 4's two local steps ---------------------------------------------------------------------

def sample_bc_pairs(expert_obs: torch.Tensor, expert_act: torch.Tensor, batch, config,
                    generator: torch.Generator):
    """One BC minibatch: ``bc_batch_size`` expert pairs and (with ``bc_learner_pairs``) as many
    pairs of the learner batch, drawn uniformly with ``generator``."""
    i = torch.randint(len(expert_obs), (config.bc_batch_size,), generator=generator)
    obs, act = expert_obs[i], expert_act[i]
    if config.bc_learner_pairs:
        lo = batch.obs.reshape(-1, batch.obs.shape[-1])
        la = batch.actions.reshape(-1, batch.actions.shape[-1])
        j = torch.randint(len(lo), (config.bc_batch_size,), generator=generator)
        obs, act = torch.cat([obs, lo[j]]), torch.cat([act, la[j]])
    return obs, act


def local_steps(learner: Learner, bc_copy: GaussianPolicy, batch, rewards: torch.Tensor,
                expert_obs: torch.Tensor, expert_act: torch.Tensor, config,
                generator: torch.Generator, prox_bc=None, prox_ppo=None) -> dict:
    """``config.bc_steps`` BC steps on ``bc_copy`` (Eq. 4's first term) and one PPO update of
    pi' on ``batch`` with ``rewards`` (its second term); ``prox_bc`` / ``prox_ppo`` add ADMM's
    proximal terms to the two losses.  Returns the logged terms."""
    L, c = learner, config
    if c.optimizer_state == "reset":   # fresh AdamW moments for both copies every iteration
        L.opt_bc.state.clear()
        L.opt_ppo.state.clear()
    bc_terms = []
    if c.bc_step:
        for _ in range(c.bc_steps):
            obs, act = sample_bc_pairs(expert_obs, expert_act, batch, c, generator)
            bc_terms.append(_bc.bc_step(bc_copy, L.opt_bc, obs, act, c.max_grad_norm,
                                        extra_loss=prox_bc))
    out = {"bc_nll": float(np.mean([t["nll"] for t in bc_terms])) if bc_terms else math.nan}
    if c.ppo_step:
        batch.advantages, batch.returns = compute_gae(rewards, batch.values, batch.next_values,
                                                      batch.dones, c.ppo.gamma, c.ppo.gae_lambda,
                                                      batch.terminals)
        ppo_terms = ppo_update(L.pi_prime, L.value_fn, L.opt_ppo, batch, c.ppo_config,
                               generator, extra_loss=prox_ppo)
        out.update({f"ppo_{k}": v for k, v in ppo_terms.items()})
    out["pi_pi_prime_l1"] = float((flat(policy_parameters(bc_copy))
                                   - flat(policy_parameters(L.pi_prime))).abs().sum())
    return out


def _moved(out: dict, pi: GaussianPolicy, before: torch.Tensor) -> dict:
    """``out`` with the L1 norm of pi's change over the iteration (the paper's Figure 6) and
    its mean log-std."""
    out["param_change_l1"] = float((flat(policy_parameters(pi)) - before).abs().sum())
    out["log_std"] = float(pi.log_std.detach().mean()) if pi.gaussian else math.nan
    return out


# -- the two updates -----------------------------------------------------------------------------

def parameter_averaging(learner: Learner, batch, rewards: torch.Tensor,
                        expert_obs: torch.Tensor, expert_act: torch.Tensor, config,
                        generator: torch.Generator) -> dict:
    """Algorithm 2's iteration as the paper has it, on a batch pi' sampled right after it was
    made a copy of pi (lines 3-4, in ``dc.train``):

        pi  <- BC steps on expert pairs + pairs of the batch       (lines 5-6)
        pi' <- one PPO update on the batch with ``rewards``         (line 7)
        pi  <- (pi + pi') / 2                                       (line 8)

    Returns the logged terms."""
    before = flat(policy_parameters(learner.pi))
    out = local_steps(learner, learner.pi, batch, rewards, expert_obs, expert_act, config,
                      generator)
    # With one step switched off its copy is still the start, so the average halves the other
    # step: what the paper's update does to each step on its own.
    average_into(learner.pi, learner.pi_prime, config.average_log_std)
    return _moved(out, learner.pi, before)


def _proximal(policy: GaussianPolicy, target: torch.Tensor, rho: float):
    """rho/2 ||x - target||^2 over the policy's averaged parameters, as a closure."""
    def term():
        x = torch.cat([p.reshape(-1) for p in policy_parameters(policy)])
        return 0.5 * rho * ((x - target) ** 2).sum()
    return term


def consensus_admm(learner: Learner, batch, rewards: torch.Tensor, expert_obs: torch.Tensor,
                   expert_act: torch.Tensor, config, generator: torch.Generator) -> dict:
    """One iteration of consensus ADMM (Boyd et al. 2011, section 7.1) on a batch x_2 = pi'
    sampled, with pi holding the consensus z:

        x_1 <- BC steps on   NLL(x_1)   + rho/2 ||x_1 - z + u_1||^2
        x_2 <- PPO update on L_PPO(x_2) + rho/2 ||x_2 - z + u_2||^2
        z   <- mean_i (x_i + u_i);   u_i <- u_i + x_i - z

    Returns the logged terms, with the primal and dual residuals."""
    L, c = learner, config
    if L.duals is None:
        raise ValueError("consensus_admm needs a learner made for update='admm' "
                         "(make_learner); the paper's update is parameter_averaging")
    z = flat(policy_parameters(L.pi))
    u1, u2 = L.duals
    out = local_steps(L, L.pi_bc, batch, rewards, expert_obs, expert_act, c, generator,
                      prox_bc=_proximal(L.pi_bc, z - u1, c.rho),
                      prox_ppo=_proximal(L.pi_prime, z - u2, c.rho))
    with torch.no_grad():
        x1, x2 = flat(policy_parameters(L.pi_bc)), flat(policy_parameters(L.pi_prime))
        z_new = 0.5 * ((x1 + u1) + (x2 + u2))
        u1 += x1 - z_new
        u2 += x2 - z_new
        _set_flat(policy_parameters(L.pi), z_new)
        out["primal_residual"] = float(torch.sqrt(((x1 - z_new) ** 2).sum()
                                                  + ((x2 - z_new) ** 2).sum()))
        out["dual_residual"] = float(c.rho * math.sqrt(2.0)
                                     * torch.sqrt(((z_new - z) ** 2).sum()))
    return _moved(out, L.pi, z)


__all__ = ["Learner", "average_into", "consensus_admm", "copy_into", "flat", "local_steps",
           "make_learner", "parameter_averaging", "policy_parameters", "sample_bc_pairs"]
