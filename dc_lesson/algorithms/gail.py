"""Generative adversarial imitation learning (GAIL, Ho and Ermon 2016), in one file.

The objective.  GAIL plays a two-player game between the policy pi and a discriminator
D(s, a) in (0, 1), here the probability that the pair (s, a) came from the *expert*:

    min_pi max_D   E_{(s,a) ~ expert} [ log D(s, a) ] + E_{(s,a) ~ pi} [ log(1 - D(s, a)) ]
                   - lambda H(pi)

For a fixed policy the best discriminator is D* = rho_E / (rho_E + rho_pi) (rho: the
occupancy measures, the state-action distributions), and at D* the inner maximum equals
2 JS(rho_E || rho_pi) - log 4: GAIL minimises the Jensen-Shannon divergence between the
expert's and the learner's state-action distributions, through samples, without a model.

The discriminator step.  D = sigmoid(f(s, a)) for an MLP f (the logit); maximising the
objective over D is the logistic regression "expert = 1, learner = 0", i.e. minimising the
binary cross-entropy

    L_D = - mean_expert log sigmoid(f)  - mean_learner log(1 - sigmoid(f))

(optionally plus a gradient penalty, below).

The reward, and its sign.  The policy wants to *minimise* E_pi[log(1 - D)], i.e. to maximise
the return of the per-step reward

    r(s, a) = - log(1 - D(s, a)) = softplus(f(s, a))           (reward_form="gail", default)

which is >= 0, grows without bound as D -> 1 ("this looks like the expert") and is about
e^f, nearly 0 and flat, where D is sure the pair is the learner's (f << 0): a discriminator
that wins outright leaves the policy little to climb.  The alternatives are

    r = log D(s, a) = -softplus(-f)        (reward_form="log_d", <= 0; about f where f << 0,
                                            GAN's "non-saturating" form)
    r = log D - log(1 - D) = f(s, a)       (reward_form="logit", AIRL's; their sum)

All three have the same optimum; they differ in scale and in the *survival bias*: a positive
reward rewards long episodes and a negative one short ones.  Our tasks have fixed horizons
and no early termination, so the bias does not matter here.  Because rewards are computed
by the discriminator *after* its update on the very batch the policy collected, the policy
always chases the discriminator's latest opinion.

Why adversarial training is unstable.  The policy's reward moves every iteration (D is trained
on the policy's newest samples), so PPO optimises a non-stationary objective; a discriminator
that wins outright (accuracy near 1) gives r = softplus(f) with f very negative on every
learner pair, a nearly flat reward with no direction; one that loses gives noise.  Nothing
in the game rewards covering *every* mode of the expert: the policy is paid for pairs that
look expert-like, and one mode done well pays as much per step as all modes done well,
until D learns that the learner's pairs all sit in one mode and lowers its reward there
(the chase that can oscillate between modes rather than cover them).  See chapter 02.

Pseudo-code (one iteration of :func:`train`; the loop is PPO on an imitation reward,
:func:`dc_lesson.algorithms._reward_ppo.run`, and the discriminator is GAIL's reward in it):

    collect n_envs x n_steps pairs with the stochastic policy             (ppo.collect_batch)
    for k in 1..disc_steps:                                               (discriminator_step)
        B_E <- disc_batch expert pairs, B_pi <- disc_batch learner pairs
        D <- Adam step on BCE(D(B_E), 1) + BCE(D(B_pi), 0) [+ gp * penalty]
    r_t <- -log(1 - D(s_t, a_t)) for the whole batch                      (reward_from_logit)
    advantages <- GAE(r, V)                                               (ppo.compute_gae)
    pi, V <- PPO's clipped-surrogate epochs                               (ppo.ppo_update)

Implementation details, each a field of :class:`GAILConfig`:

* Inputs of D: the state and the action *as applied* (clipped to the action bounds; a raw
  Gaussian sample beyond them would let D spot the learner by |a| > 1 alone), each dimension
  standardised with the mean and std of the expert's pairs (fixed for the whole run, so the
  scale of D's input does not drift with the learner).
* Gradient penalty (``grad_penalty > 0``): Gulrajani et al.'s penalty
  gp * (||grad_x f(x)|| - 1)^2 at random interpolates of expert and learner inputs (as in
  DAC, Kostrikov et al. 2019), which keeps f smooth and D from winning outright.
* The expert's actions as D sees them (``expert_noise``; None, as recorded, by default): the
  demonstrations hold the experts' *mean* actions, so a learner that explores with any noise
  is told apart by the noise alone, however close its mean.  ``"learner"`` adds the learner's
  current Gaussian noise (its std, per dimension, from the discriminator's generator) to the
  expert's actions in every discriminator step: D then compares the learner with the expert
  acting as noisily as the learner does (as if the demonstrations had been sampled), and is
  left with the states and the mean actions to tell them apart.  Measured (issue 38, cartpole
  from a perfect BC start, seed 4): D's accuracy on the expert's pairs at the first iteration
  fell from 0.90 to 0.63 (on the learner's, 0.45 both), yet D still won within 30,000
  interactions once the policy had drifted, and the start was lost unless PPO's advantages
  were left unstandardised as well (``ppo.norm_adv=False``; the competence study's
  ``FIXES``, where the probes are listed).
* The BC warm start (``bc_warm_start``, used by the benchmark through
  :func:`dc_lesson.algorithms.bc.warm_start`): GAIL starts from BC's policy, whose mean network it keeps.
* The start's noise (``start_log_std``; None, i.e. kept, by default, and
  ``TUNED_START_LOG_STD`` = -2 in :func:`preset`, which ``table1`` and ``table3`` use): a
  given Gaussian start policy's log-std is set to it before the first iteration (the
  ``gail_lr`` cells and chapter 02's live run keep the warm start's -0.5).  The warm start arrives with PPO's -0.5 (a std of
  0.61, what DC and the other baselines explore with), ten times the spread of the reacher
  experts' actions (std about 0.05): an (s, a) discriminator then separates learner from
  expert by the action noise alone, and the reward teaches nothing about states.  At -2
  (std 0.14) GAIL on reacher4 (18 demonstrations, 5 seeds, mean action) reached a scaled
  return of 0.56 on average against 0.27 at -0.5 (4 of 5 seeds higher, EMD lower on all 5)
  and imitation 1.0.1's GAIL's 0.54 (one seed, an exploratory script outside the repo): the one GAIL knob tuned, on reacher4 only; lower
  learning rates (1e-4, 3e-5), the logit reward and SB3's PPO minibatching (10 epochs of
  64) did not help there.
* The observation normaliser inside the policy (and value network) is *frozen*, set once from
  the expert's states.  PPO alone keeps updating it (``ppo.train``), but here that would
  silently change a warm-started policy: BC's mean network was fitted to inputs standardised
  with the expert's statistics, and moving them towards the learner's own states changes
  every action without a single gradient step (and with it the BC start we want to keep).
  Frozen expert statistics also put the policy, the value network and D on one input scale.
* ``value_warmup``: the first iterations update only the value network (the policy's
  learning rate is 0): a fresh critic next to a warm-started actor otherwise gives the actor
  advantages that are mostly the critic's error, and PPO's first steps undo BC's work.

Determinism: ``config.seed`` decides the initialisation of the networks, one generator for the
action noise and PPO's minibatch order, the stream of episode seeds and one generator for the
discriminator's minibatches and the expert's action noise (four streams of
:func:`~dc_lesson.algorithms.base.seed_streams`, as in ``ppo.py``).  A checkpoint (``_reward_ppo.run``'s, with the
discriminator, its optimiser and its generator) stores all of it, so a resumed run ends
exactly where an uninterrupted one does.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np
import torch
from torch import nn

from dc_lesson import timing as _timing
from dc_lesson import tasks as _tasks
from dc_lesson.algorithms import _reward_ppo
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms import bc as _bc
from dc_lesson.algorithms import ppo as _ppo
from dc_lesson.algorithms.base import TrainResult, check_inputs
from dc_lesson.checks import check_fields
from dc_lesson.nn import fast as _fast
from dc_lesson.nn.policies import ACTION_HIGH, ACTION_LOW, GaussianPolicy, mlp

REWARD_FORMS = ("gail", "log_d", "logit")
EXPERT_NOISE = (None, "learner")


@dataclasses.dataclass(frozen=True)
class GAILConfig(_reward_ppo.PPOImitationConfig):
    """Every knob of GAIL.  PPO's own knobs (and the run's length, ``ppo.total_steps``) live in
    ``ppo``; ``seed`` here is the run's one seed (``ppo.seed`` is ignored)."""

    # start_log_std was GAIL's from its first cells (always in its JSON); knobs added later
    # are named only when set, so stored cells keep their identity
    LATER_KNOBS = ("expert_noise",)

    # PPO's settings for GAIL (and DRIL, PWIL, NDI): larger batches, fewer and larger
    # minibatches, a smaller learning rate than PPOConfig's (imitation_ppo_default says why)
    ppo: _ppo.PPOConfig = dataclasses.field(default_factory=_reward_ppo.imitation_ppo_default)
    disc_hidden: tuple[int, ...] = (64, 64)   # hidden layer sizes of the discriminator MLP
    disc_activation: str = "tanh"   # its activation
    disc_actions: bool = True       # D(s, a) (GAIL); False: D(s), a state-only discriminator
    #                                 that the learner's action noise cannot give away
    disc_lr: float = 3e-4           # Adam's learning rate for the discriminator
    disc_steps: int = 8             # discriminator gradient steps per PPO iteration
    disc_batch: int = 512           # expert pairs and learner pairs in each of those steps
    grad_penalty: float = 0.0       # weight of the gradient penalty (0: none); DAC uses 10
    expert_noise: str | None = None  # "learner": D sees the expert's actions with the
    #                                 learner's current action noise added (module doc);
    #                                 None: as recorded
    reward_form: str = "gail"       # "gail": -log(1-D); "log_d": log D; "logit": log D/(1-D)
    reward_scale: float = 1.0       # multiplies the reward (PPO here does not normalise it)
    value_warmup: int = 2           # first iterations that train only the value network
    bc_warm_start: bool = True      # start from bc.warm_start (experiments.gail.run_one honours it;
    #                                 train() itself starts from the policy it is given)
    entropy: float = 0.0            # entropy bonus lambda (overrides ppo.ent_coef)
    start_log_std: float | None = None   # the log-std a given start policy is set to (None:
    #                                 kept); preset() sets TUNED_START_LOG_STD (module doc)
    seed: int = 0                   # the one seed of the run

    def __post_init__(self):
        check_fields(self, positive=("disc_lr", "disc_steps", "disc_batch", "reward_scale"),
                     non_negative=("grad_penalty", "value_warmup", "entropy", "seed"),
                     choices={"expert_noise": EXPERT_NOISE, "reward_form": REWARD_FORMS})
        self.check_ppo()

    @property
    def ppo_config(self) -> _ppo.PPOConfig:
        """The PPO settings actually used: ``ppo`` with this seed and entropy weight."""
        return dataclasses.replace(self.ppo, seed=self.seed, ent_coef=self.entropy)

    def with_lr(self, lr: float) -> "GAILConfig":
        """The same configuration with one learning rate for the policy (and value network)
        and the discriminator: the knob of the learning-rate sweep (the paper's Figure 4)."""
        if not lr > 0:
            raise ValueError(f"the learning rate must be positive, got {lr}")
        return dataclasses.replace(self, ppo=dataclasses.replace(self.ppo, lr=float(lr)),
                                   disc_lr=float(lr))

    # with_steps, to_dict and to_json: _reward_ppo.PPOImitationConfig's.


def sized(total_steps: int, seed: int = 0, lr: float | None = None,
          base: GAILConfig | None = None) -> GAILConfig:
    """GAIL's configuration for a run of ``total_steps`` interactions (the library defaults).

    A run shorter than four of the default batches (only at the ``smoke`` budget) collects
    smaller batches, so it still makes four iterations, and warms its critic up for one.
    """
    cfg = _reward_ppo.sized(base or GAILConfig(), total_steps, seed)
    return cfg if lr is None else cfg.with_lr(lr)


TUNED_START_LOG_STD = -2.0   # the one GAIL knob tuned (reacher4; module docstring)


def preset(budget, seed: int = 0) -> GAILConfig:
    """GAIL's configuration at a budget: the imitation protocol's ``il_steps`` interactions,
    its start exploring with ``TUNED_START_LOG_STD``."""
    return dataclasses.replace(sized(budget.il_steps, seed), start_log_std=TUNED_START_LOG_STD)


# -- the discriminator ---------------------------------------------------------------------------

class Discriminator(nn.Module):
    """f(s, a), the logit of D(s, a) = P(expert | s, a), an MLP on standardised (s, a).

    The input statistics are buffers (saved with the weights) set once by
    :meth:`fit_input_stats` from the expert's pairs.
    """

    def __init__(self, obs_dim: int, act_dim: int, hidden=(64, 64), activation: str = "tanh",
                 use_actions: bool = True):
        super().__init__()
        self._config = dict(obs_dim=int(obs_dim), act_dim=int(act_dim),
                            hidden=[int(h) for h in hidden], activation=activation,
                            use_actions=bool(use_actions))
        # State-only (use_actions=False): D(s) cannot tell expert from learner by the noise
        # of the learner's sampled actions, only by where its states go.
        self.use_actions = bool(use_actions)
        dim = obs_dim + (act_dim if use_actions else 0)
        self.register_buffer("in_mean", torch.zeros(dim))
        self.register_buffer("in_std", torch.ones(dim))
        self.net = mlp(dim, hidden, 1, activation, out_gain=1.0)

    def config(self) -> dict:
        return dict(self._config)

    @torch.no_grad()
    def fit_input_stats(self, obs, act, min_std: float = 1e-3) -> None:
        """Standardise inputs with the mean and std of these (expert) pairs; a dimension that
        barely varies in the expert's data gets ``min_std`` so it cannot blow up."""
        x = torch.as_tensor(obs, dtype=torch.float32)
        if self.use_actions:
            x = torch.cat([x, torch.as_tensor(act, dtype=torch.float32)], -1)
        self.in_mean.copy_(x.mean(0))
        self.in_std.copy_(x.std(0).clamp_min(min_std))

    def inputs(self, obs, act) -> torch.Tensor:
        """The standardised, concatenated input; actions are clipped to the bounds first."""
        obs = torch.as_tensor(obs, dtype=torch.float32)
        if not self.use_actions:
            return (obs - self.in_mean) / self.in_std
        act = torch.as_tensor(act, dtype=torch.float32).clamp(ACTION_LOW, ACTION_HIGH)
        return (torch.cat([obs, act], -1) - self.in_mean) / self.in_std

    def logit_of_inputs(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x).squeeze(-1)

    def forward(self, obs, act) -> torch.Tensor:
        """The logit f(s, a) (shape (...,)); D = sigmoid(f)."""
        return self.logit_of_inputs(self.inputs(obs, act))


def reward_from_logit(logit: torch.Tensor, form: str = "gail") -> torch.Tensor:
    """The policy's reward from the discriminator's logit f (see the module docstring).

    ``softplus(f) = log(1 + e^f) = -log(1 - sigmoid(f))`` is computed without forming D, so it
    stays exact where D rounds to 0 or 1.
    """
    if form == "gail":
        return nn.functional.softplus(logit)          # -log(1 - D)
    if form == "log_d":
        return -nn.functional.softplus(-logit)        # log D
    if form == "logit":
        return logit                                  # log D - log(1 - D)
    raise ValueError(f"unknown reward form {form!r}; choose one of {', '.join(REWARD_FORMS)}")


def discriminator_loss(disc: Discriminator, expert_obs, expert_act, learner_obs, learner_act,
                       grad_penalty: float = 0.0,
                       generator: torch.Generator | None = None) -> dict[str, torch.Tensor]:
    """The discriminator's loss on one batch of expert and one of learner pairs.

    Returns ``loss`` (carries the gradient: BCE plus the weighted penalty) and, detached,
    ``bce``, ``penalty``, ``acc_expert`` (share of expert pairs with D > 1/2) and
    ``acc_learner`` (share of learner pairs with D < 1/2).
    """
    xe, xl = disc.inputs(expert_obs, expert_act), disc.inputs(learner_obs, learner_act)
    fe, fl = disc.logit_of_inputs(xe), disc.logit_of_inputs(xl)
    bce = (nn.functional.binary_cross_entropy_with_logits(fe, torch.ones_like(fe))
           + nn.functional.binary_cross_entropy_with_logits(fl, torch.zeros_like(fl)))
    penalty = torch.zeros(())
    if grad_penalty > 0:
        n = min(len(xe), len(xl))
        eps = torch.rand(n, 1, generator=generator)
        x = (eps * xe[:n] + (1 - eps) * xl[:n]).requires_grad_(True)
        grad, = torch.autograd.grad(disc.logit_of_inputs(x).sum(), x, create_graph=True)
        penalty = ((grad.norm(dim=-1) - 1) ** 2).mean()
    loss = bce + grad_penalty * penalty
    return {"loss": loss, "bce": bce.detach(), "penalty": penalty.detach(),
            "acc_expert": (fe.detach() > 0).float().mean(),
            "acc_learner": (fl.detach() < 0).float().mean()}


@_timing.timed("disc_step")
def discriminator_step(disc: Discriminator, optimizer: torch.optim.Optimizer, expert_obs,
                       expert_act, learner_obs, learner_act, grad_penalty: float = 0.0,
                       generator: torch.Generator | None = None) -> dict[str, float]:
    """One Adam step on :func:`discriminator_loss`; returns its terms (before the step)."""
    terms = discriminator_loss(disc, expert_obs, expert_act, learner_obs, learner_act,
                               grad_penalty, generator)
    if _fast.enabled():   # the same step without torch's wrappers (dc_lesson.nn.fast)
        _fast.zero_grad(optimizer)
        terms["loss"].backward()
        _fast.optimizer_step(optimizer)
    else:
        optimizer.zero_grad()
        terms["loss"].backward()
        optimizer.step()
    return {k: float(v.detach()) for k, v in terms.items()}


def expert_actions(actions: torch.Tensor, policy, config: GAILConfig,
                   generator: torch.Generator) -> torch.Tensor:
    """The expert's actions as D sees them: as recorded, or (``expert_noise="learner"``) with
    the learner's current Gaussian action noise added, so that D cannot tell the learner from
    mean-action demonstrations by the noise alone."""
    if config.expert_noise is None:
        return actions
    std = policy.log_std.detach().exp()
    return actions + std * torch.randn(actions.shape, generator=generator)


expert_pairs = _bc.pairs   # all (state, action) pairs of the demonstrations, as tensors


# -- the loop ------------------------------------------------------------------------------------

def train(task: str, demos, config: GAILConfig = GAILConfig(), *,
          policy: GaussianPolicy | None = None, progress: bool = True, checkpoint=None,
          callback: Callable | None = None, checkpoint_every: int = 10) -> TrainResult:
    """GAIL on ``task`` from the expert pairs of ``demos``; returns a :class:`TrainResult`
    (the policy, the log, ``models["discriminator"]`` and ``models["value"]``).

    Args:
        task: a task name.
        demos: the expert's :class:`~dc_lesson.data.Demonstrations` (or anything
            :func:`dc_lesson.algorithms.bc.episodes` accepts).
        config: the hyperparameters and the seed.
        policy: the policy to start from, e.g. ``bc.warm_start(...)[0]``; it is trained in
            place.  None starts from a fresh :class:`GaussianPolicy`.
        callback: called as ``callback(row, policy)`` after every iteration; a true return
            value stops training.
        progress: show a progress bar.
        checkpoint: a file path; the run is saved there every ``checkpoint_every`` iterations
            and at the end, and resumes from it when it exists.

    ``log`` has one row per iteration: the discriminator's mean loss over its steps
    (``disc_loss``, ``disc_bce``, ``disc_penalty``), its accuracy on the whole learner batch
    and on as many expert pairs after its update (``acc_expert``, ``acc_learner``), its mean
    D on both (``d_expert``, ``d_learner``), the reward's mean and std, PPO's terms, the mean
    environment return of the training episodes that ended in the batch (NaN if none; the
    policy's *stochastic* return, measured by the task's reward, which GAIL never sees) and
    steps per second.
    """
    spec = _tasks.spec(task)
    check_inputs(task, demos, policy)
    e_obs, e_act = expert_pairs(demos)
    if e_obs.shape[1] != spec.obs_dim or e_act.shape[1] != spec.act_dim:
        raise ValueError(f"the demonstrations have (obs, act) dims ({e_obs.shape[1]}, "
                         f"{e_act.shape[1]}); {task} has ({spec.obs_dim}, {spec.act_dim})")
    if config.expert_noise is not None and policy is not None and not policy.gaussian:
        raise ValueError("expert_noise='learner' adds the learner's Gaussian noise to the "
                         "expert's actions; this policy has no single log-std (a mixture): "
                         "set expert_noise=None")
    init_seed, sample_seed, env_seed, disc_seed = _base.seed_streams(
        config.seed, "init", "sample", "env", "disc")
    # the start's exploration noise (a mixture has its own spreads; a resume restores the saved)
    _base.set_start_noise(policy, config.start_log_std)
    # the policy's (and critic's) normaliser: the expert's statistics, then frozen; D is drawn
    # from the same seeded stream, after the critic
    policy, value_fn, disc = _reward_ppo.make_networks(
        spec, config.ppo_config, e_obs, policy, init_seed,
        lambda: Discriminator(spec.obs_dim, spec.act_dim, config.disc_hidden,
                              config.disc_activation, use_actions=config.disc_actions))
    disc.fit_input_stats(e_obs, e_act)
    disc_optimizer = _fast.adam(disc.parameters(), lr=config.disc_lr)
    disc_generator = torch.Generator().manual_seed(disc_seed)

    def discriminator_reward(batch):
        """The pseudo-code's discriminator steps and reward on the batch the policy just
        collected: the (n_steps, n_envs) rewards and the discriminator's logged terms."""
        l_obs = batch.obs.reshape(-1, spec.obs_dim)
        l_act = batch.actions.reshape(-1, spec.act_dim)

        # the discriminator: expert = 1, learner = 0
        steps = []
        for _ in range(config.disc_steps):
            ie = torch.randint(len(e_obs), (config.disc_batch,), generator=disc_generator)
            il = torch.randint(len(l_obs), (config.disc_batch,), generator=disc_generator)
            steps.append(discriminator_step(disc, disc_optimizer, e_obs[ie],
                                            expert_actions(e_act[ie], policy, config,
                                                           disc_generator),
                                            l_obs[il], l_act[il], config.grad_penalty,
                                            disc_generator))

        # the reward, from the updated discriminator
        with torch.no_grad():
            f_learner = disc(batch.obs, batch.actions)                    # (T, N)
            ie = torch.randint(len(e_obs), (len(l_obs),), generator=disc_generator)
            f_expert = disc(e_obs[ie], expert_actions(e_act[ie], policy, config,
                                                      disc_generator))
            rewards = config.reward_scale * reward_from_logit(f_learner, config.reward_form)
        return rewards, {"disc_loss": float(np.mean([s["loss"] for s in steps])),
                         "disc_bce": float(np.mean([s["bce"] for s in steps])),
                         "disc_penalty": float(np.mean([s["penalty"] for s in steps])),
                         "acc_expert": float((f_expert > 0).float().mean()),
                         "acc_learner": float((f_learner < 0).float().mean()),
                         "d_expert": float(torch.sigmoid(f_expert).mean()),
                         "d_learner": float(torch.sigmoid(f_learner).mean())}

    # collecting the batch and PPO on the reward are the shared loop's; GAIL's stored cells
    # were made with nn.fast's AdamW (fused on the fast path), which it keeps
    hooks = _reward_ppo.Hooks("gail", discriminator_reward, networks={"disc": disc},
                              optimizers={"disc_optimizer": disc_optimizer},
                              generators={"disc_generator": disc_generator},
                              models={"discriminator": disc}, optimizer=_fast.adamw,
                              shown=("acc_expert", "acc_learner"))
    return _reward_ppo.run(task, config, hooks, policy, value_fn, sample_seed, env_seed,
                           progress=progress, checkpoint=checkpoint, callback=callback,
                           checkpoint_every=checkpoint_every)


__all__ = ["Discriminator", "GAILConfig", "REWARD_FORMS", "discriminator_loss",
           "discriminator_step", "expert_actions", "expert_pairs", "preset", "reward_from_logit",
           "sized", "train"]
