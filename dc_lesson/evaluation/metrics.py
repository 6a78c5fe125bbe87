"""How close a learner's behaviour is to the expert's: distances between state distributions,
returns on a common scale, mode shares, and the drift away from the expert's states.

The distribution measures compare samples of a task's *mode feature* (``TaskSpec.
mode_feature_names``: fingertip x-y for the reachers, forward velocity for the cheetahs, ...),
arrays of shape (n, k) in the feature's own units, one row per visited state:

* :func:`emd`: the earth mover's (Wasserstein-1) distance, exact, with POT;
* :func:`kl` and :func:`reverse_kl`: Kullback-Leibler divergences by the k-nearest-neighbour
  estimator of Wang, Kulkarni and Verdu (2009);
* :func:`compare`: all three at once, expert against learner.

Every measure checks its inputs and raises a ``ValueError`` that names the problem (empty,
NaN or inf, wrong number of dimensions, features that do not match).

The states of one episode are strongly correlated, so n states are worth far fewer than n
independent draws: differences between two learners smaller than the spread over seeds or
episode sets mean nothing.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from dc_lesson import data as _data
from dc_lesson.data.modes import mode_shares
from dc_lesson import tasks as _tasks


# -- input checks --------------------------------------------------------------------------------

def check_samples(name: str, x) -> np.ndarray:
    """``x`` as a float64 array (n, k), or a ValueError naming what is wrong with it."""
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name} is not a numeric array: {e}") from None
    if a.ndim != 2:
        hint = " (reshape a single feature with x[:, None])" if a.ndim == 1 else ""
        raise ValueError(f"{name} must be a 2-D array (n_samples, n_features), got shape "
                         f"{a.shape}{hint}")
    if a.shape[0] == 0:
        raise ValueError(f"{name} is empty (no samples)")
    if a.shape[1] == 0:
        raise ValueError(f"{name} has no features (shape {a.shape})")
    bad = ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{name} contains {int(np.isnan(a).sum())} NaN and "
                         f"{int(np.isinf(a).sum())} inf values")
    return a


def check_pair(x, y, names=("x", "y")) -> tuple[np.ndarray, np.ndarray]:
    """Two samples of the same feature: both valid and with the same number of columns."""
    a, b = check_samples(names[0], x), check_samples(names[1], y)
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"{names[0]} has {a.shape[1]} features and {names[1]} has "
                         f"{b.shape[1]}: compare samples of the same mode feature")
    return a, b


def subsample(x: np.ndarray, n_max: int | None, seed) -> np.ndarray:
    """At most ``n_max`` rows of ``x`` drawn without replacement by a generator seeded with
    ``seed`` (all rows, in order, when there are no more than that)."""
    if n_max is None or len(x) <= n_max:
        return x
    if n_max < 1:
        raise ValueError(f"n_max must be at least 1, got {n_max}")
    idx = np.sort(np.random.default_rng(seed).choice(len(x), n_max, replace=False))
    return x[idx]


# -- earth mover's distance ----------------------------------------------------------------------

EMD_METRICS = ("euclidean", "sqeuclidean", "cityblock")


def emd(x, y, n_max: int | None = 2000, seed: int = 0, metric: str = "euclidean") -> float:
    """The earth mover's distance between two samples, each point of a sample weighing the same.

    The exact optimal transport cost (``ot.emd2``, network simplex) with the ground distance
    ``metric`` between points: by default the Euclidean distance in the mode feature's own
    units (metres, metres per second, ...), which makes the result the Wasserstein-1 distance
    in those units; ``"sqeuclidean"`` gives the squared Wasserstein-2 distance instead.  The
    features are *not* rescaled, so for a multi-dimensional feature they must be commensurate
    (the reachers' x and y are).

    Exact transport costs O(n^3) time and O(n^2) memory, so each sample is cut to at most
    ``n_max`` points drawn without replacement (``n_max=None``: all points).  Each side is
    drawn by its own generator seeded with ``seed``, so the same call gives the same number,
    and a sample compared with itself picks the same points and gives exactly 0.
    """
    import ot
    x, y = check_pair(x, y)
    if metric not in EMD_METRICS:
        raise ValueError(f"unknown ground metric {metric!r}; choose one of "
                         f"{', '.join(EMD_METRICS)}")
    x, y = subsample(x, n_max, seed), subsample(y, n_max, seed)
    # scipy computes each distance directly; ot.dist expands |x|^2 + |y|^2 - 2 x.y, which
    # loses digits (identical points come out ~1e-8 apart instead of 0).
    cost = cdist(x, y, metric=metric)
    a = np.full(len(x), 1.0 / len(x))
    b = np.full(len(y), 1.0 / len(y))
    value, log = ot.emd2(a, b, cost, numItermax=10_000_000, log=True)
    if log.get("warning"):  # the simplex stopped before the optimum: the number is wrong
        raise RuntimeError(f"ot.emd2 did not converge ({log['warning']}); lower n_max")
    return float(max(value, 0.0))   # round-off can leave -1e-17 for identical samples


# -- Kullback-Leibler divergence -----------------------------------------------------------------

def kl(p_samples, q_samples, k: int = 1, jitter: float = 1e-4, n_max: int | None = None,
       seed: int = 0) -> float:
    """KL(P || Q) from samples of P and Q, by the k-nearest-neighbour estimator of Wang,
    Kulkarni and Verdu (2009, IEEE Trans. Inf. Theory 55(5), Eq. 5):

        D = (d / n) sum_i log(nu_k(i) / rho_k(i)) + log(m / (n - 1))

    with n points x_i of P, m points of Q, d features; rho_k(i) is the distance from x_i to its
    k-th nearest neighbour among the other points of P, nu_k(i) to its k-th nearest neighbour
    in Q (Euclidean, in the features' own units).  The idea: rho and nu measure how densely P
    and Q put points around x_i, so d log(nu / rho) estimates log p(x_i) / q(x_i).

    Properties.  The estimator is consistent (it converges to the true divergence as n and m
    grow, for any fixed k) but biased at finite sizes, and the bias grows with the dimension
    and where the densities change fast or have heavy tails; it can come out slightly
    negative for identical distributions.  Measured over 30 seeds with 5000 points a side and
    k=1: two samples of one Gaussian give 0.00 +- 0.03 (1-D) and -0.01 +- 0.03 (2-D);
    N(0,1) against N(1,1) gives 0.51 +- 0.04 (truth 0.5); for 2-D Gaussians the estimate falls
    short of the closed form, by 0.05 (truth 0.71) and by 0.15 when P is much wider than Q in
    one direction (truth 1.02; Q has few points where P's tail is), a bias that shrinks only
    slowly (0.09 at 20000 points, 0.06 at 80000).  k=5 halves the spread but doubles that
    bias.  Compare numbers computed with the same k, jitter and sample sizes only.

    Duplicate points.  A policy that comes to rest repeats the same state (to the last float32
    bit) for hundreds of steps, so samples hold exact duplicates, whose zero distances would
    make log(nu / rho) infinite.  Every point therefore gets independent Gaussian noise of
    standard deviation ``jitter`` (in the features' units; 1e-4 is a tenth of a millimetre for
    the reachers' fingertip, far below any difference that matters and far above float32
    rounding), drawn from ``seed``.  The result is the divergence between P and Q each blurred
    at that scale, which differs negligibly from KL(P || Q) for spread-out distributions.  A
    distribution with a point mass (the reacher expert at rest on its target) has an infinite
    divergence from any distribution that misses the point; the estimate then stays finite but
    large, and grows as the jitter shrinks.  ``jitter=0`` turns the noise off and raises an
    error on duplicates.

    A sample compared with itself is not an estimate of 0: pass independent samples.
    ``n_max`` subsamples each side first (see :func:`subsample`); None keeps every point.
    """
    p, q = check_pair(p_samples, q_samples, ("p_samples", "q_samples"))
    if int(k) != k or k < 1:
        raise ValueError(f"k must be a positive integer, got {k}")
    if not jitter >= 0:
        raise ValueError(f"jitter must be >= 0, got {jitter}")
    k = int(k)
    p_seed, q_seed, noise_seed = np.random.SeedSequence(seed).generate_state(3)
    p, q = subsample(p, n_max, p_seed), subsample(q, n_max, q_seed)
    n, m, d = len(p), len(q), p.shape[1]
    if n < k + 1 or m < k:
        raise ValueError(f"the k={k} nearest-neighbour estimator needs at least {k + 1} points "
                         f"of p_samples and {k} of q_samples, got {n} and {m}")
    if jitter > 0:
        rng = np.random.default_rng(noise_seed)
        p = p + rng.normal(0.0, jitter, p.shape)
        q = q + rng.normal(0.0, jitter, q.shape)
    # The nearest point of P to x_i is x_i itself, at distance 0: ask for k + 1 and skip it.
    rho = cKDTree(p).query(p, k=[k + 1])[0][:, 0]
    nu = cKDTree(q).query(p, k=[k])[0][:, 0]
    if np.any(rho == 0) or np.any(nu == 0):
        raise ValueError("the samples contain duplicate points (zero nearest-neighbour "
                         "distances); use jitter > 0")
    return float(d * np.mean(np.log(nu / rho)) + np.log(m / (n - 1)))


def reverse_kl(p_samples, q_samples, **kwargs) -> float:
    """KL(Q || P): :func:`kl` with the samples swapped (same keyword arguments)."""
    return kl(q_samples, p_samples, **kwargs)


def compare(expert_features, learner_features, *, n_max: int | None = 2000, seed: int = 0,
            k: int = 1, jitter: float = 1e-4) -> dict[str, float]:
    """Expert against learner on a mode feature: ``emd``; ``kl`` = KL(expert || learner),
    large when the learner misses states the expert visits (mode-covering); ``rkl`` =
    KL(learner || expert), large when the learner goes where the expert never does
    (mode-seeking).  ``n_max`` applies to the EMD only (the KL estimator is cheap)."""
    expert, learner = check_pair(expert_features, learner_features,
                                 ("expert_features", "learner_features"))
    return {"emd": emd(expert, learner, n_max=n_max, seed=seed),
            "kl": kl(expert, learner, k=k, jitter=jitter, seed=seed),
            "rkl": reverse_kl(expert, learner, k=k, jitter=jitter, seed=seed)}


# -- returns and modes ---------------------------------------------------------------------------

def _returns(returns) -> np.ndarray:
    items = list(returns) if not isinstance(returns, np.ndarray) else returns
    if len(items) and all(isinstance(t, _data.Trajectory) for t in items):
        items = [t.ret for t in items]
    try:
        r = np.asarray(items, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"returns is not a list of numbers or trajectories: {e}") from None
    if r.ndim != 1:
        raise ValueError(f"returns must be 1-D (one per episode), got shape {r.shape}")
    if len(r) == 0:
        raise ValueError("returns is empty (no episodes)")
    if not np.all(np.isfinite(r)):
        raise ValueError("returns contains NaN or inf")
    return r


def scaled_return(task: str, returns, expert: float | None = None,
                  random: float | None = None, variant: str | None = None
                  ) -> tuple[float, np.ndarray]:
    """Returns on the scale random policy = 0, expert = 1: (R - random) / (expert - random).

    ``expert`` and ``random`` default to the mean returns the demonstrations' manifest
    records for ``task`` (measured over 50 episodes each by ``dc-lesson demos``; for an expert
    ``variant``, what it records for that variant's demonstrations).  ``returns``
    are episode returns, or trajectories.  Gives (scaled mean return, scaled return of each
    episode).
    """
    r = _returns(returns)
    if expert is None or random is None:
        entry = _data.manifest_entry(task, variant=variant)
        expert = entry["expert_return"]["mean"] if expert is None else expert
        random = entry["random_return"]["mean"] if random is None else random
    else:
        _tasks.check_name(task)
    expert, random = float(expert), float(random)
    if not (np.isfinite(expert) and np.isfinite(random)) or expert == random:
        raise ValueError(f"the expert ({expert}) and random ({random}) returns must be finite "
                         f"and different to scale by")
    scaled = (r - random) / (expert - random)
    return float(scaled.mean()), scaled


# -- drift from the expert's states --------------------------------------------------------------

def _episode_observations(trajectories) -> np.ndarray:
    if isinstance(trajectories, np.ndarray):
        obs = trajectories
    else:
        items = list(trajectories)
        if not items:
            raise ValueError("trajectories is empty (no episodes)")
        arrays = [t.observations if isinstance(t, _data.Trajectory) else np.asarray(t)
                  for t in items]
        lengths = {a.shape for a in arrays}
        if len(lengths) != 1:
            raise ValueError(f"the episodes must all have the same shape, got {sorted(lengths)}")
        obs = np.stack(arrays)
    obs = np.asarray(obs, dtype=np.float64)
    if obs.ndim != 3:
        raise ValueError(f"trajectories must give observations of shape (n_episodes, T + 1, "
                         f"obs_dim), got {obs.shape}")
    if obs.size == 0:
        raise ValueError("trajectories hold no observations")
    if not np.all(np.isfinite(obs)):
        raise ValueError("the trajectories' observations contain NaN or inf")
    return obs


def distance_to_expert(expert_obs, trajectories, standardise: bool = True) -> np.ndarray:
    """For every step of every episode, the distance from the learner's observation to the
    nearest observation the expert visited: an array (n_episodes, T + 1).

    ``expert_obs`` is an array (N, obs_dim) or :class:`~dc_lesson.data.Demonstrations`;
    ``trajectories`` a list of :class:`~dc_lesson.data.Trajectory` (or of (T + 1, obs_dim)
    arrays, or one (n_episodes, T + 1, obs_dim) array).  With ``standardise`` both are first
    scaled by the expert's per-dimension mean and standard deviation, so every observation
    dimension counts in units of the expert's own spread (a dimension the expert never varies,
    std below 1e-6, is left in its raw units rather than divided by almost nothing).

    Run on held-out expert episodes it gives the floor (how far a fresh expert episode is from
    the demonstrations); a learner's curve rising above it over time is compounding error.
    """
    if isinstance(expert_obs, _data.Demonstrations):
        expert_obs = expert_obs.observations
    expert = check_samples("expert_obs", expert_obs)
    obs = _episode_observations(trajectories)
    if obs.shape[2] != expert.shape[1]:
        raise ValueError(f"expert observations have {expert.shape[1]} dimensions and the "
                         f"trajectories' {obs.shape[2]}: they are of different tasks")
    if standardise:
        mean, std = expert.mean(0), expert.std(0)
        scale = np.where(std > 1e-6, std, 1.0)
        expert, obs = (expert - mean) / scale, (obs - mean) / scale
    dist, _ = cKDTree(expert).query(obs.reshape(-1, obs.shape[2]), k=1)
    return dist.reshape(obs.shape[:2])


__all__ = ["EMD_METRICS", "check_pair", "check_samples", "compare", "distance_to_expert",
           "emd", "kl", "mode_shares", "reverse_kl", "scaled_return", "subsample"]
