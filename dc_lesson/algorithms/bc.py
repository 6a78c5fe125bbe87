"""Behaviour cloning (BC): supervised learning of the expert's actions, the paper's Eq. 1.

The objective.  Given expert pairs D_E = {(s, a)}, BC fits the policy by maximum likelihood,

    max_theta  E_{(s, a) in D_E} [ log pi_theta(a | s) ]                               (Eq. 1)

Here pi_theta is the library's :class:`~dc_lesson.nn.policies.GaussianPolicy` (an MLP mean and a
learned state-independent log-std), the same class PPO trains, so a BC policy can start PPO or
DC.  For a Gaussian the negative log-likelihood of one pair is

    sum_j [ (a_j - mu_j(s))^2 / (2 sigma_j^2) + log sigma_j ] + (k / 2) log(2 pi),

a squared error weighted by the learned noise plus a price on that noise: the mean goes where
the expert's actions are, and sigma settles at their spread around it.

Why pairs are enough (the paper's footnote, as we read it).  The log-likelihood of a whole
expert trajectory under pi is

    log p(tau) = log p(s_0) + sum_t log pi(a_t | s_t) + sum_t log P(s_{t+1} | s_t, a_t),

and only the middle sum depends on the policy.  Maximising the summed log pi over the
demonstrations' pairs therefore maximises the likelihood of the expert's trajectories, up to
constants (the initial-state and dynamics terms), without a model of the dynamics.

Covariate shift.  BC learns only in the states the expert visited, but the learner is then run
in the states *it* visits, so a small action error moves it off the expert's states, where its
errors are larger and compound over the episode (Ross and Bagnell: the cost grows as T^2 rather
than T).  ``metrics.distance_to_expert`` and ``plots.drift_plot`` draw this.

Choices made where the paper is silent (each a field of :class:`BCConfig`):

* Train/validation split: the paper splits the pairs 70/30 and lets the validation likelihood
  decide when to stop.  We split *whole trajectories* (``val_fraction`` of them, rounded, at
  least one), drawn from the seed: consecutive states of one episode are near copies of each
  other, so a split of pairs would put a neighbour of nearly every validation state in the
  training set and the validation likelihood would barely differ from the training one.
  With ``val_fraction=0`` there is no validation: all epochs run and the last parameters stay.
* Early stopping: after every epoch the mean validation NLL is computed; training stops after
  ``patience`` epochs without an improvement of at least ``min_delta`` nats, and the parameters
  of the best epoch are restored.
* Observation normaliser: fitted once on the training states before the first step (never on
  validation states), then frozen; it lives inside the policy, so PPO/DC inherit it.
* Optimiser: AdamW (as PPO), minibatches in an order drawn from a seeded generator, no
  gradient clipping unless ``max_grad_norm`` is set.  The loss is the mean NLL per pair.
* Architecture and log-std initialisation: PPO's defaults (``PPOConfig``), so the policy drops
  into PPO/DC unchanged.

Determinism: ``config.seed`` decides the split, the initial weights and the minibatch order
(three streams of :func:`~dc_lesson.algorithms.base.seed_streams`), so one configuration gives the same policy
to the last digit (in one process with a fixed thread count).

Speed (``dc_lesson.nn.fast``): :func:`bc_step` as you read it, :func:`bc_loss` through autograd
and AdamW's ``step()``, is what ``train`` runs by default; sweep workers and benchmarks turn on
``fast.on()``, where the same gradients are taken by hand and the optimiser is fused (the same
update to float32 rounding).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import time
import numpy as np
import torch

from dc_lesson.checks import check_fields
from dc_lesson.data.types import Demonstrations, Trajectory
from dc_lesson import progress as _progress
from dc_lesson import timing as _timing
from dc_lesson.algorithms.base import (LearnerInputError, TrainResult, check_inputs,
                                      seed_streams)
from dc_lesson.nn import backprop as _backprop
from dc_lesson.nn import fast as _fast
from dc_lesson.nn.mixture import MixturePolicy
from dc_lesson.nn.policies import GaussianPolicy


@dataclasses.dataclass(frozen=True)
class BCConfig:
    """Every knob of behaviour cloning; the network defaults are PPO's (``PPOConfig``)."""

    epochs: int = 200            # maximum passes over the training pairs
    batch_size: int = 256        # pairs per gradient step
    lr: float = 1e-3             # AdamW's learning rate
    weight_decay: float = 0.0    # AdamW's decoupled weight decay (a regulariser; 0 = plain MLE)
    patience: int = 20           # epochs without a validation improvement before stopping
    min_delta: float = 1e-4      # what counts as an improvement of the validation NLL (nats)
    val_fraction: float = 0.3    # share of *trajectories* held out for validation (paper: 30%)
    max_grad_norm: float | None = None   # clip the gradient norm of each step (None: no clip)
    hidden: tuple[int, ...] = (64, 64)   # hidden layer sizes of the mean network (() = linear)
    activation: str = "tanh"     # the hidden layers' activation
    log_std_init: float = -0.5   # initial log standard deviation of every action dimension
    norm_obs: bool = True        # observation normaliser in the policy, fitted on train states
    stop_on_others: bool = False  # train() only: train on every demonstration given and stop
    #                               early on the task's *other* demonstrations (val_fraction 0)
    policy: str = "gaussian"     # "gaussian" (GaussianPolicy) or "mixture" (nn.MixturePolicy)
    n_components: int = 4        # the mixture's components (policy="mixture" only)
    seed: int = 0                # the one seed: split, initial weights, minibatch order

    def __post_init__(self):
        check_fields(self, positive=("epochs", "batch_size", "lr", "patience", "max_grad_norm",
                                     "n_components"),
                     non_negative=("weight_decay", "min_delta", "seed"),
                     choices={"policy": ("gaussian", "mixture")})
        for name in ("epochs", "batch_size"):
            if getattr(self, name) < 1:
                raise ValueError(f"BCConfig.{name} must be at least 1, got {getattr(self, name)}")
        if self.patience < 1:
            raise ValueError(f"BCConfig.patience must be at least 1, got {self.patience}")
        if not 0.0 <= self.val_fraction < 1.0:
            raise ValueError(f"BCConfig.val_fraction must be in [0, 1), got {self.val_fraction}")
        if self.lr <= 0:
            raise ValueError(f"BCConfig.lr must be positive, got {self.lr}")

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)


# -- data ----------------------------------------------------------------------------------------

Episode = tuple[np.ndarray, np.ndarray]   # (observations (T, obs_dim), actions (T, act_dim))


def episodes(data) -> list[Episode]:
    """The (state, action) pairs of each episode, as float32 arrays.

    ``data`` is a :class:`~dc_lesson.data.Demonstrations`, a sequence of
    :class:`~dc_lesson.data.Trajectory`, or a sequence of ``(obs, act)`` array pairs (for
    synthetic data).  A trajectory's last observation, which no action follows, is dropped;
    of a subsampled trajectory (:func:`dc_lesson.data.subsample`) only the kept pairs are
    taken (``Trajectory.pairs``), so every learner reading pairs through here or
    :func:`pairs` sees the protocol's pairs.
    """
    if isinstance(data, Demonstrations):
        data = data.trajectories
    elif isinstance(data, Trajectory):
        data = [data]
    out = []
    for i, ep in enumerate(data):
        if isinstance(ep, Trajectory):
            obs, act = ep.pairs()
        else:
            try:
                obs, act = ep
            except (TypeError, ValueError):
                raise ValueError(f"episode {i} is neither a Trajectory nor an (obs, act) "
                                 f"pair") from None
        obs = np.asarray(obs, dtype=np.float32)
        act = np.asarray(act, dtype=np.float32)
        if obs.ndim != 2 or act.ndim != 2 or len(obs) != len(act) or len(obs) == 0:
            raise ValueError(f"episode {i} needs observations (T, obs_dim) and actions "
                             f"(T, act_dim) with the same T >= 1, got shapes {obs.shape} "
                             f"and {act.shape}")
        if not (np.all(np.isfinite(obs)) and np.all(np.isfinite(act))):
            raise ValueError(f"episode {i} contains NaN or inf")
        out.append((obs, act))
    if not out:
        raise ValueError("behaviour cloning needs at least one episode")
    dims = {(o.shape[1], a.shape[1]) for o, a in out}
    if len(dims) != 1:
        raise ValueError(f"episodes disagree on (obs_dim, act_dim): {sorted(dims)}")
    return out


def pairs(data) -> tuple[torch.Tensor, torch.Tensor]:
    """All (state, action) pairs of ``data`` (anything :func:`episodes` accepts) as float32
    tensors: the expert pairs GAIL's discriminator and DC's BC step draw from."""
    eps = episodes(data)
    return (torch.from_numpy(np.concatenate([o for o, _ in eps])),
            torch.from_numpy(np.concatenate([a for _, a in eps])))


def split_episodes(n_episodes: int, val_fraction: float, seed) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the training and validation episodes (each sorted), by whole episodes.

    ``round(val_fraction * n_episodes)`` episodes, but at least one, are held out, chosen by
    a generator seeded with ``seed``; ``val_fraction=0`` holds out none.
    """
    if val_fraction == 0:
        return np.arange(n_episodes), np.arange(0)
    n_val = max(1, round(val_fraction * n_episodes))
    if n_episodes - n_val < 1:
        raise ValueError(f"cannot hold out {val_fraction:.0%} of {n_episodes} episode(s) and "
                         f"keep one for training; pass more episodes or val_fraction=0")
    order = np.random.default_rng(seed).permutation(n_episodes)
    return np.sort(order[n_val:]), np.sort(order[:n_val])


def _stack(eps: list[Episode], idx) -> tuple[torch.Tensor, torch.Tensor]:
    obs = np.concatenate([eps[i][0] for i in idx])
    act = np.concatenate([eps[i][1] for i in idx])
    return torch.from_numpy(obs), torch.from_numpy(act)


# -- the loss and one step -----------------------------------------------------------------------

def bc_loss(policy: GaussianPolicy, obs, act) -> dict[str, torch.Tensor]:
    """The terms of Eq. 1 on a batch of pairs.

    Returns ``nll``, the mean negative log-likelihood per pair (the loss; it carries the
    gradient), and for information only (detached): ``mse``, the mean squared error of the
    mean action (averaged over pairs and action dimensions), and ``log_std``, the policy's mean
    log standard deviation.
    """
    obs = torch.as_tensor(obs, dtype=torch.float32)
    act = torch.as_tensor(act, dtype=torch.float32)
    if not policy.gaussian:   # a mixture (nn.mixture): its own density
        return {"nll": -policy.log_prob(obs, act).mean(),
                "mse": ((policy(obs).detach() - act) ** 2).mean(),
                "log_std": torch.tensor(math.nan)}
    dist = policy.distribution(obs)
    nll = -dist.log_prob(act).sum(-1).mean()
    return {"nll": nll,
            "mse": ((dist.mean.detach() - act) ** 2).mean(),
            "log_std": policy.log_std.detach().mean()}


@_timing.timed("bc_step")
def bc_step(policy: GaussianPolicy, optimizer: torch.optim.Optimizer, obs, act,
            max_grad_norm: float | None = None,
            extra_loss=None) -> dict[str, float]:
    """One gradient step of Eq. 1 on a batch of pairs; returns the terms of :func:`bc_loss`
    (before the step) and the gradient norm.  DC's Algorithm 2 calls this on expert plus
    learner pairs; ``extra_loss()``, if given, is added to the NLL (consensus ADMM's proximal
    term)."""
    params = [p for group in optimizer.param_groups for p in group["params"]]
    # clip_grad_norm_ with an infinite bound measures the norm without changing the gradient.
    bound = math.inf if max_grad_norm is None else max_grad_norm
    if _fast.enabled():   # the same step by faster kernels (dc_lesson.nn.fast)
        return _fast_step(policy, optimizer, params, obs, act, bound, extra_loss)
    optimizer.zero_grad()
    terms = bc_loss(policy, obs, act)
    loss = terms["nll"] if extra_loss is None else terms["nll"] + extra_loss()
    loss.backward()
    grad_norm = torch.nn.utils.clip_grad_norm_(params, bound)
    optimizer.step()
    return {**{k: float(v.detach()) for k, v in terms.items()}, "grad_norm": float(grad_norm)}


def _fast_step(policy, optimizer, params, obs, act, bound, extra_loss) -> dict[str, float]:
    """:func:`bc_step` on the fast path: a Gaussian tanh MLP's gradients by hand
    (:func:`dc_lesson.nn.backprop.bc_grads`, autograd's to the bit), the clip and the
    optimiser step as their bare kernel calls (torch's to the bit)."""
    _fast.zero_grad(optimizer)
    if extra_loss is None and policy.gaussian and _backprop.supported(policy.mean_net):
        terms = _backprop.bc_grads(policy, torch.as_tensor(obs, dtype=torch.float32),
                                   torch.as_tensor(act, dtype=torch.float32))
    else:
        terms = bc_loss(policy, obs, act)
        loss = terms["nll"] if extra_loss is None else terms["nll"] + extra_loss()
        loss.backward()
    grad_norm = _fast.clip_grad_norm_(params, bound)
    _fast.optimizer_step(optimizer)
    return {**{k: float(v.detach()) for k, v in terms.items()}, "grad_norm": float(grad_norm)}


@torch.no_grad()
def evaluate(policy: GaussianPolicy, obs, act, batch_size: int = 8192) -> dict[str, float]:
    """:func:`bc_loss` on a whole set of pairs (in chunks), as floats."""
    n = len(obs)
    if n == 0:
        return {"nll": math.nan, "mse": math.nan,
                "log_std": float(policy.log_std.mean()) if policy.gaussian else math.nan}
    sums = {"nll": 0.0, "mse": 0.0}
    for start in range(0, n, batch_size):
        terms = bc_loss(policy, obs[start:start + batch_size], act[start:start + batch_size])
        size = min(batch_size, n - start)
        for k in sums:
            sums[k] += float(terms[k]) * size
    return {"nll": sums["nll"] / n, "mse": sums["mse"] / n,
            "log_std": float(policy.log_std.mean()) if policy.gaussian else math.nan}


# -- training ------------------------------------------------------------------------------------

def train_bc(demos_or_trajectories, config: BCConfig = BCConfig(), progress: bool = True,
             validation=None):
    """Fits a :class:`GaussianPolicy` to expert pairs by Eq. 1 with early stopping.

    Args:
        demos_or_trajectories: :class:`~dc_lesson.data.Demonstrations`, a list of
            trajectories, or a list of ``(obs, act)`` pairs per episode (see :func:`episodes`).
        config: the hyperparameters and the seed.
        progress: show a progress bar over epochs.
        validation: other expert episodes to stop early on (anything :func:`episodes`
            accepts); then every training episode is trained on and ``config.val_fraction``
            must be 0.

    Returns ``(policy, log)``.  ``log`` has one row per epoch: the training set's ``train_nll``
    and ``train_mse`` and the validation set's ``val_nll`` and ``val_mse`` (NaN without
    validation), all measured after the epoch on the whole set; ``step_nll`` (the mean over
    the epoch's minibatches, before each step), ``log_std``, ``grad_norm``, ``best_epoch`` and
    ``seconds``.  The policy holds the parameters of the best validation epoch and a ``meta``
    dict (the config, which episodes were validation, the best epoch) for ``save_policy``.
    """
    eps = episodes(demos_or_trajectories)
    obs_dim, act_dim = eps[0][0].shape[1], eps[0][1].shape[1]
    split_seed, init_seed, order_seed = seed_streams(config.seed, "split", "init", "order")
    train_idx, val_idx = split_episodes(len(eps), config.val_fraction, split_seed)
    train_obs, train_act = _stack(eps, train_idx)
    val_obs, val_act = (_stack(eps, val_idx) if len(val_idx)
                        else (torch.zeros(0, obs_dim), torch.zeros(0, act_dim)))
    if validation is not None:
        if config.val_fraction:
            raise ValueError("give validation episodes or a val_fraction, not both (set "
                             "val_fraction=0 to train on every episode)")
        held = episodes(validation)
        val_idx = np.arange(len(held))
        val_obs, val_act = _stack(held, val_idx)

    # Seed the initialisation without changing the caller's global torch RNG.
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(init_seed)
        if config.policy == "mixture":
            policy = MixturePolicy(obs_dim, act_dim, config.n_components, config.hidden,
                                   config.activation, log_std_init=config.log_std_init,
                                   norm_obs=config.norm_obs)
        else:
            policy = GaussianPolicy(obs_dim, act_dim, config.hidden, config.activation,
                                    log_std_init=config.log_std_init, norm_obs=config.norm_obs)
    # The normaliser sees the training states once, then stays fixed: the loss must not move
    # under the optimiser's feet, and validation states must not leak into training.
    policy.update_obs_norm(train_obs)
    optimizer = _fast.adamw(policy.parameters(), lr=config.lr,
                                  weight_decay=config.weight_decay)
    generator = torch.Generator().manual_seed(order_seed)

    bar = _progress.bar(range(config.epochs), desc="BC", unit="epoch", enabled=progress)
    n = len(train_obs)
    validate = len(val_idx) > 0
    best_nll, best_epoch, best_state, waited = math.inf, 0, None, 0
    log: list[dict] = []
    for epoch in bar:
        start = time.perf_counter()
        order = torch.randperm(n, generator=generator)
        steps = []
        for lo in range(0, n, config.batch_size):
            idx = order[lo:lo + config.batch_size]
            steps.append(bc_step(policy, optimizer, train_obs[idx], train_act[idx],
                                 config.max_grad_norm))
        train = evaluate(policy, train_obs, train_act)
        val = evaluate(policy, val_obs, val_act)

        # Early stopping on the validation NLL; without validation the last epoch is "best".
        if not validate:
            best_epoch = epoch + 1
        elif val["nll"] < best_nll - config.min_delta:
            best_nll, best_epoch, waited = val["nll"], epoch + 1, 0
            best_state = copy.deepcopy(policy.state_dict())
        else:
            waited += 1
        log.append({"epoch": epoch + 1, "train_nll": train["nll"], "train_mse": train["mse"],
                    "val_nll": val["nll"], "val_mse": val["mse"],
                    "step_nll": float(np.mean([s["nll"] for s in steps])),
                    "log_std": train["log_std"],
                    "grad_norm": float(np.mean([s["grad_norm"] for s in steps])),
                    "best_epoch": best_epoch, "seconds": time.perf_counter() - start})
        bar.set_postfix(train=f"{train['nll']:.3f}", val=f"{val['nll']:.3f}", best=best_epoch)
        if validate and waited >= config.patience:
            break
    bar.close()

    if best_state is not None:
        policy.load_state_dict(best_state)
    policy.meta = {"algorithm": "bc", "config": json.loads(config.to_json()),
                   "n_episodes": len(eps), "train_episodes": train_idx.tolist(),
                   "val_episodes": val_idx.tolist(), "best_epoch": best_epoch,
                   "epochs_run": len(log),
                   "best_val_nll": best_nll if validate else None}
    return policy, log


# -- the warm start of GAIL and DC ----------------------------------------------------------------

WARM_START_LOG_STD = -0.5   # PPO's initial log-std (PPOConfig.log_std_init)


def _warm_start(demos, seed: int, max_epochs: int, log_std: float | None, progress: bool):
    policy, log = train_bc(demos, BCConfig(epochs=max_epochs, seed=seed), progress=progress)
    if log_std is not None:
        with torch.no_grad():
            policy.log_std.fill_(float(log_std))
    policy.meta = {**policy.meta, "warm_start_log_std": log_std}
    return policy, log


def warm_start_policy(demos, seed: int, *, max_epochs: int = 200,
                      log_std: float | None = WARM_START_LOG_STD, progress: bool = False):
    """BC on ``demos`` with ``seed``, ready to start GAIL or DC (see :func:`warm_start`)."""
    return _warm_start(demos, seed, max_epochs, log_std, progress)[0]


def warm_start(task: str, n_demos: int, seed: int, *, max_epochs: int = 200,
               log_std: float | None = WARM_START_LOG_STD, progress: bool = False,
               variant: str | None = None):
    """BC on the first ``n_demos`` demonstrations of ``task``, ready to start GAIL or DC.

    Returns ``(policy, demos, log)``.  BC drives the log-std down to the spread of the
    expert's actions around the fitted mean (about -3.7 on the reachers), far too little noise
    for the on-policy updates that follow to explore with; so the log-std is reset to
    ``log_std`` (PPO's initial value) unless it is None.  The mean network and the fitted,
    frozen observation normaliser are kept: the mean action, which is what the evaluation runs,
    is exactly BC's.
    """
    from dc_lesson.data import store as _store
    demos = _store.load_demos(task, n_trajectories=n_demos, variant=variant)
    policy, log = _warm_start(demos, seed, max_epochs, log_std, progress)
    return policy, demos, log


# -- the standard library's recipe -------------------------------------------------------------

def library_recipe(seed: int = 0) -> BCConfig:
    """BC as imitation 1.0.1's training script trains it (its FeedForward32Policy: 32-32 tanh,
    no observation normaliser, Adam 1e-3, log-std 0, the last weights kept): 89 epochs of 32
    pairs, its 50,000 minibatches on the 18,000 pairs of 18 1,000-step demonstrations.  Its
    entropy bonus of 1e-3 is left out: it moves only the log-std, never the mean action.
    table1's ``bc-lib`` row and ``perf.imitation_ref`` both train this."""
    return BCConfig(epochs=89, batch_size=32, val_fraction=0.0, hidden=(32, 32),
                    norm_obs=False, log_std_init=0.0, seed=seed)


# -- the learner interface -----------------------------------------------------------------------

def preset(budget, seed: int = 0) -> BCConfig:
    """BC's configuration at a budget: the budget's epoch limit, the library's defaults."""
    return BCConfig(epochs=budget.bc_max_epochs, seed=seed)


def train(task: str, demos, config: BCConfig = BCConfig(), *, policy=None,
          progress: bool = True, checkpoint=None, callback=None) -> TrainResult:
    """BC as a learner of the registry: :func:`train_bc` on ``demos`` of ``task``.

    BC fits from scratch (``policy`` must be None: it has no use for a start) and trains in
    seconds, so it keeps no checkpoint (``checkpoint`` must be None); ``callback(row, policy)``
    is called once per epoch *after* training, with the final policy, for the log's sake.

    With ``config.stop_on_others`` BC trains on *all* of ``demos`` and stops early on the
    task's demonstrations that are not among them (by episode seed): expert episodes no learner
    trains on.  The 70/30 split of the default trains on 70% of what GAIL and DC see.
    """
    if policy is not None or checkpoint is not None:
        raise LearnerInputError("BC fits from scratch in seconds: it takes no starting policy "
                                "and no checkpoint (pass policy=None, checkpoint=None)")
    check_inputs(task, demos, None)
    validation = None
    if config.stop_on_others:
        if config.val_fraction:
            raise LearnerInputError("stop_on_others trains on every demonstration: set "
                                    "val_fraction=0")
        if getattr(demos, "subsampled", False):
            raise LearnerInputError("stop_on_others stops on the task's other demonstrations, "
                                    "which are whole: with subsampled demonstrations use "
                                    "the default split (val_fraction > 0)")
        from dc_lesson.data import store as _store
        given = {t.seed for t in demos.trajectories}
        variant = demos.manifest.get("variant") if hasattr(demos, "manifest") else None
        others = [t for t in _store.load_demos(task, variant=variant).trajectories
                  if t.seed not in given]
        if not others:
            raise LearnerInputError(f"stop_on_others needs demonstrations of {task} that are "
                                    f"not trained on; all {len(given)} are")
        validation = others
    pi, log = train_bc(demos, config, progress=progress, validation=validation)
    if callback is not None:
        for row in log:
            if callback(row, pi):
                break
    return TrainResult(pi, log, {}, "bc")


__all__ = ["BCConfig", "WARM_START_LOG_STD", "bc_loss", "bc_step", "episodes", "evaluate",
           "pairs", "preset", "split_episodes", "train", "train_bc", "warm_start",
           "warm_start_policy"]
