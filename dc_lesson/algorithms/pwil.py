r"""Primal Wasserstein imitation learning (PWIL, Dadashi, Hussenot, Geist, Pietquin, ICLR 2021).

The objective.  PWIL minimises the Wasserstein-1 distance between the learner's episode and
the expert's demonstrations, both as empirical distributions of standardised state-action
"atoms": a learner episode puts weight 1/T on each of its T steps, the expert 1/N_E on each
of its N_E atoms.  The primal form of W_1 is an optimal transport problem over couplings P,

    W_1 = min_{P >= 0, P 1 = 1/T, P^T 1 = 1/N_E}  sum_{t, j} P_tj || x_t - e_j ||,

which needs the whole episode.  PWIL replaces it by a *greedy* coupling that is built one step
at a time, as the steps arrive: step t sends its mass 1/T to the nearest expert atoms that
still have mass left (the nearest first, as much as it has, then the next), and pays

    c_t = sum_j P_tj || x_t - e_j ||          (so sum_t c_t >= W_1: an upper bound),

then takes those atoms' mass away for the rest of the episode.  The reward of step t is

    r_t = alpha * exp( - beta * T * c_t / sqrt(d) )                 (alpha = beta = 5)

(d: the dimension of an atom; T c_t is the step's mean cost per unit mass).  The reward is
offline: no discriminator, nothing is trained, and any RL learner optimises it (ours: PPO).
Because an expert atom can be used only once per episode, a learner that stays in one mode
uses that mode's atoms up and is paid less and less for staying: the coupling itself asks
for every mode in proportion.

Pseudo-code (one iteration of :func:`train`):

    collect n_envs x n_steps pairs with the stochastic policy             (ppo.collect_batch)
    for t in the batch's steps, in order, for every environment:          (Rewarder.rewards)
        x <- standardised (s_t, clip(a_t))
        c_t <- greedy coupling of x's 1/T mass to the remaining atoms      (couple_step)
        r_t <- alpha exp(-beta T c_t / sqrt(d))
        at an episode end: every atom gets its mass 1/N_E back             (Rewarder.reset)
    PPO on r                                                               (_reward_ppo.run)

Choices (each a field of :class:`PWILConfig`), with PWIL's reference code where it has one:

* *Atoms on state-actions* (``use_actions=True``, the paper's MuJoCo setting); ``False``
  couples states only (its "observation only" variant).  The learner's action enters as the
  environment applies it, clipped to the bounds.
* *Standardisation*: each dimension by the mean and std of the expert's atoms (the reference's
  StandardScaler), the std floored at ``std_floor`` so a dimension the expert never moves (a
  balanced cartpole's cos) does not divide by almost nothing.
* *Subsampling*: every ``subsampling``-th pair of each demonstration (the paper: 20, as in
  GAIL's benchmark), from an offset drawn per demonstration from the seed (the reference
  draws it at random), so N_E is about n_demos * T / 20.
* *T* is the training episode's length (the task's horizon, or ``ppo.episode_steps``).
* *Order*: the reward depends on the order of an episode's steps, so it is computed per
  environment as the steps arrive, and each environment's remaining mass is kept from one
  PPO batch to the next (and in the checkpoint) until its episode ends.
* The last of an episode's mass can find every atom used up (rounding); it then costs
  nothing more (the reference subtracts 1e-6 from 1/T for the same reason).
* The RL learner is PPO with GAIL's settings, the frozen expert normaliser and the critic
  warm-up (:mod:`dc_lesson.algorithms._reward_ppo`); the paper used D4PG.

What it gives on the cheap tasks (``tests/test_baselines.py``, measured): nothing yet.  The
kernel is a few *expert* standard deviations wide, the expert's states on a reacher at its
target or a balanced cartpole barely vary, and PPO's Gaussian exploration (std 0.6) alone puts
a learner's pairs hundreds of such deviations away, so the reward is 0 almost everywhere:
reacher1 from the BC warm start ended at 582 against its start's 578 (40k interactions), from
a fresh policy at 0.  The competence study (issue 38) runs PWIL with ``beta = 1``, a kernel
five times wider, which pays along the way to the expert's states: from a weak hopper start
it learns where the paper's 5 does not (``experiments.studies.competence.FIXES`` has the
probes).

Determinism: ``seed`` decides the network initialisation, the subsampling offsets, PPO's
generator and the episode seeds.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch

from dc_lesson import tasks as _tasks
from dc_lesson.checks import check_fields
from dc_lesson.algorithms import _reward_ppo
from dc_lesson.algorithms import bc as _bc
from dc_lesson.algorithms import ppo as _ppo
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms.base import LearnerInputError, TrainResult, check_inputs
from dc_lesson.nn.policies import ACTION_HIGH, ACTION_LOW, GaussianPolicy


@dataclasses.dataclass(frozen=True)
class PWILConfig(_reward_ppo.PPOImitationConfig):
    """Every knob of PWIL; PPO's own (and the run's length) live in ``ppo``."""

    ppo: _ppo.PPOConfig = dataclasses.field(default_factory=_reward_ppo.imitation_ppo_default)
    alpha: float = 5.0           # the reward's scale (the paper: 5)
    beta: float = 5.0            # the kernel's width: r = alpha exp(-beta T c / sqrt(d)) (5)
    use_actions: bool = True     # atoms are (s, a) (the paper's MuJoCo runs) or s alone
    subsampling: int = 20        # keep every k-th expert pair (the paper: 20)
    std_floor: float = 1e-3      # smallest per-dimension std of the standardisation
    value_warmup: int = 2        # first iterations that train only the critic
    bc_warm_start: bool = True   # the benchmark starts from bc.warm_start (train() itself
    #                              starts from the policy it is given)
    start_log_std: float | None = None   # a given (warm) start's log-std is set to this
    #                              first (None: kept); base.START_LOG_STD is the shared rule
    seed: int = 0

    def __post_init__(self):
        # Types first (a bool is no count, NaN or infinity no scale), then PWIL's own ranges.
        check_fields(self, positive=("alpha", "beta", "subsampling", "std_floor"),
                     non_negative=("value_warmup", "seed"))
        if not (self.alpha > 0 and self.beta > 0 and self.std_floor > 0):
            raise ValueError("PWILConfig.alpha, beta and std_floor must be positive, got "
                             f"{self.alpha}, {self.beta}, {self.std_floor}")
        if self.subsampling < 1:
            raise ValueError(f"PWILConfig.subsampling must be at least 1, got "
                             f"{self.subsampling}")
        self.check_ppo()


def sized(total_steps: int, seed: int = 0, base: PWILConfig | None = None) -> PWILConfig:
    """PWIL's configuration for ``total_steps`` interactions (see ``_reward_ppo.sized``)."""
    return _reward_ppo.sized(base or PWILConfig(), total_steps, seed)


def preset(budget, seed: int = 0) -> PWILConfig:
    """PWIL at a budget: the imitation protocol's ``il_steps`` interactions."""
    return sized(budget.il_steps, seed)


# -- the coupling and the reward -----------------------------------------------------------------

def couple_step(norms: np.ndarray, weights: np.ndarray, mass: float) -> float:
    """One learner step of the greedy coupling: sends ``mass`` to the nearest atoms with mass
    left (``norms``: its distance to every atom), taking it from ``weights`` in place; returns
    the cost sum_j P_j ||x - e_j||."""
    norms = np.where(weights > 0, norms, np.inf)
    cost = 0.0
    while mass > 0:
        j = int(np.argmin(norms))
        if not np.isfinite(norms[j]):
            break                                  # every atom used up (rounding): no cost
        moved = min(mass, weights[j])
        cost += moved * norms[j]
        mass -= moved
        weights[j] -= moved
        if weights[j] <= 0:
            weights[j] = 0.0
            norms[j] = np.inf
    return cost


def greedy_coupling(learner: np.ndarray, expert: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The greedy coupling of a whole learner episode (T, d) to expert atoms (N, d), steps in
    order: returns (the cost c_t of every step, the transport plan P (T, N))."""
    learner, expert = np.asarray(learner, np.float64), np.asarray(expert, np.float64)
    weights = np.full(len(expert), 1.0 / len(expert))
    costs, plan = np.zeros(len(learner)), np.zeros((len(learner), len(expert)))
    for t, x in enumerate(learner):
        before = weights.copy()
        costs[t] = couple_step(np.linalg.norm(expert - x, axis=1), weights, 1.0 / len(learner))
        plan[t] = before - weights
    return costs, plan


def pwil_reward(costs, horizon: int, dim: int, alpha: float = 5.0, beta: float = 5.0):
    """r = alpha exp(-beta T c / sqrt(d)), element-wise."""
    return alpha * np.exp(-beta * horizon * np.asarray(costs, np.float64) / math.sqrt(dim))


class Rewarder:
    """PWIL's reward for ``n_envs`` environments at once, each with its own remaining mass.

    ``atoms``: the expert's atoms, already standardised, (N_E, d); ``mean`` / ``std`` the
    standardisation of a learner's raw atom; ``horizon`` T.
    """

    def __init__(self, atoms, mean, std, horizon: int, n_envs: int, alpha: float, beta: float,
                 use_actions: bool):
        self.atoms = np.asarray(atoms, np.float64)
        self.mean, self.std = np.asarray(mean, np.float64), np.asarray(std, np.float64)
        self.horizon, self.alpha, self.beta = int(horizon), float(alpha), float(beta)
        self.use_actions = use_actions
        self.weights = np.full((n_envs, len(self.atoms)), 1.0 / len(self.atoms))

    def reset(self, which) -> None:
        """Every atom gets its mass back for the environments in ``which`` (a bool mask)."""
        self.weights[np.asarray(which, bool)] = 1.0 / len(self.atoms)

    def atom(self, obs, act) -> np.ndarray:
        x = np.asarray(obs, np.float64)
        if self.use_actions:
            x = np.concatenate([x, np.clip(np.asarray(act, np.float64), ACTION_LOW,
                                           ACTION_HIGH)], -1)
        return (x - self.mean) / self.std

    def step(self, obs, act) -> np.ndarray:
        """The costs of one step of every environment (obs (N, obs_dim), act (N, act_dim))."""
        x = self.atom(obs, act)
        return np.array([couple_step(np.linalg.norm(self.atoms - x[i], axis=1),
                                     self.weights[i], 1.0 / self.horizon)
                         for i in range(len(x))])

    def rewards(self, batch) -> tuple[torch.Tensor, dict]:
        """The (n_steps, n_envs) rewards of a PPO batch, step by step in order."""
        costs = np.zeros(tuple(batch.dones.shape))
        for t in range(len(costs)):
            costs[t] = self.step(batch.obs[t].numpy(), batch.actions[t].numpy())
            self.reset(batch.dones[t].numpy())
        r = pwil_reward(costs, self.horizon, self.atoms.shape[1], self.alpha, self.beta)
        return torch.as_tensor(r, dtype=torch.float32), {"cost_mean": float(costs.mean())}


def expert_atoms(demos, config: PWILConfig, seed: int):
    """(atoms standardised, mean, std) from every ``subsampling``-th pair of each
    demonstration, from an offset drawn per demonstration.  Demonstrations subsampled
    already (``data.subsample``) are refused unless ``subsampling`` is 1: PWIL's own
    subsampling would thin their kept pairs a second time."""
    if getattr(demos, "subsampled", False) and config.subsampling != 1:
        raise LearnerInputError(
            f"these demonstrations are subsampled already ({demos.manifest.get('subsample')}); "
            f"PWIL's own subsampling of {config.subsampling} would keep every "
            f"{config.subsampling}th of their kept pairs: set PWILConfig(subsampling=1)")
    rng = np.random.default_rng(seed)
    parts = []
    for obs, act in _bc.episodes(demos):
        x = np.concatenate([obs, act], -1) if config.use_actions else obs
        parts.append(x[int(rng.integers(config.subsampling))::config.subsampling])
    x = np.concatenate(parts).astype(np.float64)
    mean, std = x.mean(0), np.maximum(x.std(0), config.std_floor)
    return (x - mean) / std, mean, std


# -- the learner ---------------------------------------------------------------------------------

def train(task: str, demos, config: PWILConfig = PWILConfig(), *,
          policy: GaussianPolicy | None = None, progress: bool = True, checkpoint=None,
          callback=None, checkpoint_every: int = 10) -> TrainResult:
    """PWIL on ``task`` from ``demos``; returns a :class:`TrainResult` (``models["value"]``).

    ``policy``: where to start (trained in place; e.g. ``bc.warm_start(...)[0]``), None for a
    fresh one.  ``checkpoint``: saved every ``checkpoint_every`` iterations and at the end,
    resumed from when it exists (with every environment's remaining expert mass).
    ``callback(row, policy)`` after each iteration; a true value stops.  ``log``: one row per
    iteration, PPO's terms plus ``reward_mean``, ``reward_std``, ``cost_mean``.
    """
    spec = _tasks.spec(task)
    check_inputs(task, demos, policy)
    pcfg = config.ppo_config
    init_seed, sample_seed, env_seed, atom_seed = _base.seed_streams(
        config.seed, "init", "sample", "env", "atom")
    e_obs, _ = _bc.pairs(demos)
    _base.set_start_noise(policy, config.start_log_std)   # a given start's noise
    policy, value_fn = _reward_ppo.make_networks(spec, pcfg, e_obs, policy, init_seed)
    atoms, mean, std = expert_atoms(demos, config, atom_seed)
    horizon = min(pcfg.episode_steps or spec.horizon, spec.horizon)
    rewarder = Rewarder(atoms, mean, std, horizon, pcfg.n_envs, config.alpha, config.beta,
                        config.use_actions)

    def set_state(state):
        rewarder.weights = state["weights"].numpy().copy()

    hooks = _reward_ppo.Hooks(
        "pwil", rewarder.rewards,
        get_state=lambda: {"weights": torch.from_numpy(rewarder.weights.copy())},
        set_state=set_state)
    return _reward_ppo.run(task, config, hooks, policy, value_fn, sample_seed, env_seed,
                           progress=progress, checkpoint=checkpoint, callback=callback,
                           checkpoint_every=checkpoint_every)


__all__ = ["PWILConfig", "Rewarder", "couple_step", "expert_atoms", "greedy_coupling",
           "preset", "pwil_reward", "sized", "train"]
