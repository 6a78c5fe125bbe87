"""What SoftFlow learns (chapter 03): the runs behind the ``softflow_fit`` cell study.

(a) the circle toy: a plain CNF against SoftFlow, over the budget's seeds; (b) expert states
of ``reacher4`` and ``halfcheetah2``: training curve, held-out NLL against a Gaussian and a
KDE, each mode's log-density, the modes of the flow's samples; (c) a sigma_max sweep.  The
study (:mod:`dc_lesson.experiments.studies.softflow_fit`) runs them as cells;
:func:`softflow_fit_benchmark` runs them all in one process, for a reader at a small budget.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import torch

from dc_lesson.density import softflow as sf


# == what SoftFlow learns ==========================================================================
#
# The speed benchmark above times a flow; this one asks what flows learn, at the budget's sizes
# (``budget.softflow_*``):
#
# (a) the circle toy: a plain CNF against SoftFlow, trained on points exactly on the unit circle,
#     scored by the held-out negative log-likelihood of fresh points at several distances from it
#     (noise std 0, 0.02, 0.05), over the budget's seeds;
# (b) expert states of ``reacher4`` and ``halfcheetah2``: SoftFlow on the full observation,
#     its training curve, held-out NLL against a Gaussian and a KDE of the same states, the
#     log-density of each mode's states (flow and KDE), and whether samples of the flow visit
#     every mode in the data's proportions (the mode feature read off the sampled states);
# (c) a sigma_max sweep (0 = the plain CNF) on the toy and on ``reacher4``.

TOY_TEST_NOISES = (0.0, 0.02, 0.05)   # std of the held-out points' distance from the circle
TOY_TEST_POINTS = 1000
FIT_TASKS = ("reacher4", "halfcheetah2")
SWEEP_TASK = "reacher4"
TASK_TEST_NOISE = 0.05    # perturbation of held-out states, in standardised units
SETTLE_STEPS = 100        # a demonstration's states from this step on are "at its mode", before it
#                           "in transit" (reaching the target, speeding up)
N_SAMPLES = 2000          # samples drawn from each task flow to read its mode shares
CURVE_POINTS = 10         # held-out NLL checkpoints per fit (plus the untrained flow)

# Where the mode feature sits in the observation.  reacher4's fingertip x-y IS observation 4:6;
# halfcheetah2's mode feature (the torso's subtree linear velocity, a sensor) is not in the
# observation, so the root's forward velocity qvel[0] (observation 8) stands in for it
# (correlation 0.995 on the demonstrations, recorded in the result).  The third entry is the
# distance from a mode's centre (the median feature of the training states at that mode) within
# which a state counts as AT the mode: 2 cm for the fingertip, 1.5 m/s for the speed.
FEATURE_IN_STATE = {"reacher4": (slice(4, 6), "fingertip x, y (observation 4:6)", 0.02),
                    "halfcheetah2": (slice(8, 9), "root forward velocity (observation 8)", 1.5)}


class FitBenchError(ValueError):
    """Bad input to the fitting benchmark."""


def circle(n: int, seed: int, noise: float = 0.0) -> np.ndarray:
    """``n`` points on the unit circle at uniform angles, plus Gaussian noise of std ``noise``."""
    if n < 1 or noise < 0:
        raise FitBenchError(f"circle needs n >= 1 and noise >= 0, got n={n}, noise={noise}")
    rng = np.random.default_rng(seed)
    theta = rng.uniform(0, 2 * np.pi, n)
    x = np.stack([np.cos(theta), np.sin(theta)], 1)
    return (x + noise * rng.standard_normal(x.shape)).astype(np.float32)


def _sigma_config(base: sf.SoftFlowConfig, sigma_max: float) -> sf.SoftFlowConfig:
    """``base`` as SoftFlow with this sigma_max, or as a plain CNF for sigma_max = 0."""
    if sigma_max < 0:
        raise FitBenchError(f"sigma_max must be >= 0 (0: the plain CNF), got {sigma_max}")
    if sigma_max == 0:
        return dataclasses.replace(base, noise_conditioned=False)
    return dataclasses.replace(base, noise_conditioned=True, sigma_max=float(sigma_max))


def toy_config(sigma_max: float = 0.1, iterations: int = 600, seed: int = 0) -> sf.SoftFlowConfig:
    """The toy's flows: 32-32, exact trace (2-D), rk4 with 4 steps, batches of 128, lr 3e-3
    (short fits: three times SoftFlow's reference rate).  sigma_max 0: the plain CNF."""
    base = sf.SoftFlowConfig(hidden=(32, 32), solver="rk4", step_size=0.25, trace="exact",
                             batch_size=128, lr=3e-3, iterations=iterations, seed=seed)
    return _sigma_config(base, sigma_max)


def task_config(sigma_max: float = 0.1, iterations: int = 1000,
                seed: int = 0) -> sf.SoftFlowConfig:
    """The expert-state flows: 64-64, Hutchinson trace, rk4 with 4 steps, batches of 256,
    SoftFlow's reference lr 1e-3.  sigma_max 0: the plain CNF."""
    base = sf.SoftFlowConfig(hidden=(64, 64), solver="rk4", step_size=0.25, trace="hutchinson",
                             batch_size=256, iterations=iterations, seed=seed)
    return _sigma_config(base, sigma_max)


def model_name(sigma_max: float) -> str:
    return "plain CNF" if sigma_max == 0 else f"SoftFlow sigma_max={sigma_max:g}"


def fit_with_curve(x: np.ndarray, config: sf.SoftFlowConfig, held_out: dict,
                   checks: int = CURVE_POINTS):
    """Fits like :func:`softflow.fit`, recording the mean held-out NLL (nats per state) of each
    array in ``held_out`` before training and at ``checks`` evenly spaced steps.  Returns
    ``(flow, log, curve, seconds)``; ``curve`` maps ``"iteration"`` and each held-out name to a
    list.  ``seconds`` counts training only."""
    flow, _ = sf.fit(x, dataclasses.replace(config, iterations=0), progress=False)
    every = max(1, config.iterations // checks)
    curve = {"iteration": [0], **{k: [_nll(flow, v)] for k, v in held_out.items()}}
    spent = [0.0]

    def check(row, flow):
        spent[0] += row["seconds"]
        if row["iteration"] % every == 0 or row["iteration"] == config.iterations:
            curve["iteration"].append(row["iteration"])
            for k, v in held_out.items():
                curve[k].append(_nll(flow, v))

    flow, log = sf.fit_more(flow, x, config, progress=False, callback=check)
    return flow, log, curve, spent[0]


def _nll(flow: sf.SoftFlow, x) -> float:
    return -float(flow.log_prob(x).mean())


def _train_curve(log: list[dict], points: int = 50) -> dict:
    """The minibatch NLL, averaged over ``points`` consecutive windows of steps."""
    if not log:
        return {"iteration": [], "nll": []}
    chunks = np.array_split(np.arange(len(log)), min(points, len(log)))
    return {"iteration": [int(log[c[-1]]["iteration"]) for c in chunks],
            "nll": [float(np.mean([log[i]["nll"] for i in c])) for c in chunks]}


def mean_std(values) -> dict:
    v = np.asarray(values, dtype=float)
    return {"mean": float(v.mean()), "std": float(v.std()), "per_seed": v.tolist()}


def toy_run(seed: int, sigma_maxes, points: int, iterations: int, grid: int = 0,
            keep_flows: bool = False) -> list[dict]:
    """One seed of the toy: a flow per sigma_max (0: plain CNF) on ``points`` clean circle
    points; rows with held-out NLL per test noise, curves, (``grid`` > 0) the density on a
    ``grid`` x ``grid`` square [-1.6, 1.6]^2 and (``keep_flows``) the flow itself."""
    train = circle(points, seed=seed)
    tests = {f"{nz:g}": circle(TOY_TEST_POINTS, seed=10_000 + seed, noise=nz)
             for nz in TOY_TEST_NOISES}
    rows = []
    for sigma_max in sigma_maxes:
        cfg = toy_config(sigma_max, iterations, seed)
        flow, log, curve, seconds = fit_with_curve(train, cfg, tests)
        row = {"seed": seed, "sigma_max": float(sigma_max), "model": model_name(sigma_max),
               "heldout_nll": {k: v[-1] for k, v in curve.items() if k != "iteration"},
               "heldout_curve": curve, "train_curve": _train_curve(log), "seconds": seconds}
        if grid:
            g = np.linspace(-1.6, 1.6, grid, dtype=np.float32)
            pts = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
            row["density"] = flow.log_prob(pts).exp().numpy().reshape(grid, grid)
            row["grid"] = g
        if keep_flows:
            row["flow"] = flow
        rows.append(row)
    return rows


def _split_by_mode(demos, modes: int):
    """Holds out the last demonstration of every mode; the rest are for training."""
    ep_modes = np.asarray(demos.modes)
    if any((ep_modes == m).sum() < 2 for m in range(modes)):
        raise FitBenchError(f"{demos.task}: need at least two demonstrations of every mode to "
                            f"hold one out (modes per episode: {ep_modes.tolist()})")
    held = sorted(int(np.flatnonzero(ep_modes == m)[-1]) for m in range(modes))
    train = [i for i in range(len(ep_modes)) if i not in held]
    return train, held


def task_data(task: str, n_states: int, seed: int = 0) -> dict:
    """The demonstrations of ``task`` split for fitting: ``train`` (a random subsample of
    ``n_states`` states of all but the last demonstration of each mode), ``held_out`` (every
    state of those held-out demonstrations), and per mode the held-out states from step
    SETTLE_STEPS on (``at_mode``), with names, the feature slice and the task's classifier."""
    from dc_lesson import data, tasks
    if task not in FEATURE_IN_STATE:
        raise FitBenchError(f"the softflow fit knows the tasks {', '.join(FEATURE_IN_STATE)}; "
                            f"not {task!r}")
    demos = data.load_demos(task)
    spec = tasks.spec(task)
    train_eps, held_eps = _split_by_mode(demos, len(spec.modes))
    obs = lambda eps: np.concatenate([demos.trajectories[i].observations[:-1] for i in eps])
    pool = obs(train_eps)
    if not 1 <= n_states <= len(pool):
        raise FitBenchError(f"{task}: asked for {n_states} training states; there are "
                            f"{len(pool)}")
    rng = np.random.default_rng(seed)
    train = pool[np.sort(rng.choice(len(pool), n_states, replace=False))]
    at_mode = {spec.modes[demos.modes[i]]: demos.trajectories[i].observations[SETTLE_STEPS:-1]
               for i in held_eps}
    transit = np.concatenate([demos.trajectories[i].observations[:SETTLE_STEPS]
                              for i in held_eps])
    sl, feature_name, tol = FEATURE_IN_STATE[task]
    centres = np.stack([np.median(np.concatenate([
        demos.trajectories[i].observations[SETTLE_STEPS:-1, sl] for i in train_eps
        if demos.modes[i] == m]), axis=0) for m in range(len(spec.modes))])
    mf = demos.mode_features[:, 0]
    corr = float(np.corrcoef(demos.observations[:, sl][:, 0], mf)[0, 1])
    env_task = tasks.make(task).task
    held = obs(held_eps)
    std = train.std(0).clip(min=1e-3)
    noise = np.random.default_rng(seed + 1).standard_normal(held.shape)
    perturbed = (held + TASK_TEST_NOISE * std * noise).astype(np.float32)
    return {"task": task, "train": train, "pool": pool, "held_out": held,
            "perturbed": perturbed, "at_mode": at_mode, "transit": transit, "modes": spec.modes,
            "feature": sl,
            "feature_name": feature_name, "centres": centres, "tolerance": tol,
            "feature_corr": corr, "classify": env_task.classify_mode,
            "train_episodes": train_eps, "held_episodes": held_eps}


def _held_out_sets(d: dict) -> dict:
    return {"clean": d["held_out"], f"perturbed {TASK_TEST_NOISE:g}": d["perturbed"]}


def _shares(classes: np.ndarray, n_modes: int) -> list[float]:
    return (np.bincount(classes, minlength=n_modes)[:n_modes] / max(1, len(classes))).tolist()


def _at_mode_shares(d: dict, features: np.ndarray) -> list[float]:
    """Per mode, the share of ``features`` within ``d["tolerance"]`` of the mode's centre."""
    dist = np.linalg.norm(features[:, None, :] - d["centres"][None], axis=-1)
    return (dist < d["tolerance"]).mean(0).tolist()


def task_run(d: dict, sigma_max: float, iterations: int, seed: int,
             samples: int = N_SAMPLES) -> dict:
    """One flow on a task's expert states (see :func:`task_data`); a JSON-able row (plus the
    sampled features under ``"sample_features"``, an array)."""
    cfg = task_config(sigma_max, iterations, seed)
    flow, log, curve, seconds = fit_with_curve(d["train"], cfg, _held_out_sets(d))
    gen = torch.Generator().manual_seed(seed)
    sample = flow.sample(samples, generator=gen).numpy()
    feat = sample[:, d["feature"]]
    finite = np.isfinite(sample).all(1)
    n_modes = len(d["modes"])
    per_mode = {m: float(flow.log_prob(x).mean()) for m, x in d["at_mode"].items()}
    transit = float(flow.log_prob(d["transit"]).mean())
    return {"seed": seed, "sigma_max": float(sigma_max), "model": model_name(sigma_max),
            "config": dataclasses.asdict(cfg), "seconds": seconds,
            "heldout_nll": {k: v[-1] for k, v in curve.items() if k != "iteration"},
            "heldout_curve": curve, "train_curve": _train_curve(log),
            "mode_logp": per_mode, "transit_logp": transit,
            "sample_finite_share": float(finite.mean()),
            "sample_mode_shares": _shares(d["classify"](feat[finite]), n_modes),
            "sample_at_mode_shares": _at_mode_shares(d, feat[finite]),
            "sample_features": feat}


def baselines(d: dict) -> dict:
    """A full-covariance Gaussian and a Gaussian KDE (Scott's bandwidth) of the training
    states: held-out NLL, clean and perturbed, and each mode's mean log-density."""
    from scipy import stats
    train = d["train"]
    std = train.std(0).clip(min=1e-3)
    # Standardised, as the flow sees them; the log-Jacobian returns to original units.
    z = lambda x: ((x - train.mean(0)) / std).astype(np.float64)
    jac = -float(np.log(std).sum())
    mean, cov = z(train).mean(0), np.cov(z(train).T) + 1e-6 * np.eye(train.shape[1])
    gauss = stats.multivariate_normal(mean, cov)
    kde = stats.gaussian_kde(z(train).T)
    out = {}
    for name, logpdf in (("gaussian", gauss.logpdf), ("kde", lambda x: kde.logpdf(x.T))):
        out[name] = {"heldout_nll": {k: -float(np.mean(logpdf(z(x)))) - jac
                                     for k, x in _held_out_sets(d).items()},
                     "mode_logp": {m: float(np.mean(logpdf(z(x)))) + jac
                                   for m, x in d["at_mode"].items()},
                     "transit_logp": float(np.mean(logpdf(z(d["transit"])))) + jac}
    out["kde"]["bandwidth_factor"] = float(kde.factor)
    return out


def task_context(d: dict) -> tuple[dict, dict]:
    """A task's facts beside its flows (the ``data`` cell of the ``softflow_fit`` study): the
    split, the data's mode shares, the Gaussian and KDE baselines, and (features) a subsample
    of the data's mode feature; the same entries :func:`softflow_fit_benchmark` writes."""
    n_modes = len(d["modes"])
    data_feat = d["pool"][:, d["feature"]]
    res = {"state_dim": int(d["train"].shape[1]), "train_states": len(d["train"]),
           "train_episodes": d["train_episodes"], "held_episodes": d["held_episodes"],
           "heldout_states": len(d["held_out"]), "modes": list(d["modes"]),
           "feature": d["feature_name"], "feature_corr_with_mode_feature": d["feature_corr"],
           "data_mode_shares": _shares(d["classify"](data_feat), n_modes),
           "data_at_mode_shares": _at_mode_shares(d, data_feat),
           "mode_centres": d["centres"].tolist(), "at_mode_tolerance": d["tolerance"],
           "settle_steps": SETTLE_STEPS, "test_noise": TASK_TEST_NOISE, **baselines(d)}
    if d["feature"].stop - d["feature"].start == 1:   # 1-D feature: density curves
        lo, hi = np.percentile(data_feat, [0.1, 99.9])
        grid = np.linspace(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), 200)
        res["feature_grid"] = grid.tolist()
        res["feature_kde_data"] = feature_kde(data_feat[:, 0], grid)
    sub = data_feat[np.random.default_rng(0).choice(len(data_feat), N_SAMPLES, replace=False)]
    return res, {"data_features": np.asarray(sub, np.float32)}


def feature_kde(values: np.ndarray, grid: np.ndarray) -> list[float]:
    """A 1-D Gaussian KDE (Scott's bandwidth) of ``values`` on ``grid``."""
    from scipy import stats
    return stats.gaussian_kde(np.asarray(values, dtype=np.float64)).evaluate(grid).tolist()


def softflow_fit_benchmark(b=None, tasks=FIT_TASKS, log=print) -> tuple[dict, dict]:
    """Every run of the ``softflow_fit`` study, in one process, at budget ``b`` (default: the current one).

    Returns ``(payload, arrays)``: the JSON-able result and the arrays for the figures (toy
    densities on a grid, the task flows' sampled mode features)."""
    from dc_lesson import budget as _budget
    b = b or _budget.current()
    if not b.softflow_toy_seeds or not b.softflow_task_seeds:
        raise FitBenchError("the budget names no SoftFlow seeds")
    sweep = tuple(float(s) for s in b.softflow_sigma_maxes)
    for s in sweep:
        _sigma_config(sf.SoftFlowConfig(), s)      # a clear error for a negative level
    compared = tuple(sorted({0.0, 0.1} | set(sweep)))
    t_start = time.perf_counter()
    arrays: dict[str, np.ndarray] = {}

    # (a) + (c) the toy
    toy_rows = []
    for seed in b.softflow_toy_seeds:
        rows = toy_run(seed, compared, b.softflow_toy_points, b.softflow_toy_iters,
                       grid=b.softflow_grid if seed == b.softflow_toy_seeds[0] else 0)
        for r in rows:
            if "density" in r:
                arrays[f"toy_density_sigma_{r['sigma_max']:g}"] = r.pop("density")
                arrays["toy_grid"] = r.pop("grid")
            log(f"toy seed {seed} {r['model']:26s} held-out NLL " + ", ".join(
                f"noise {k}: {v:.2f}" for k, v in r["heldout_nll"].items()) +
                f"  ({r['seconds']:.0f} s)")
        toy_rows += rows
    toy_summary = {}
    for s in compared:
        rows = [r for r in toy_rows if r["sigma_max"] == s]
        toy_summary[f"{s:g}"] = {nz: mean_std([r["heldout_nll"][nz] for r in rows])
                                 for nz in rows[0]["heldout_nll"]}
    gap = {nz: mean_std([c["heldout_nll"][nz] - f["heldout_nll"][nz]
                          for c, f in zip([r for r in toy_rows if r["sigma_max"] == 0],
                                          [r for r in toy_rows if r["sigma_max"] == 0.1])])
           for nz in toy_summary["0"]}
    toy = {"config": dataclasses.asdict(toy_config(0.1, b.softflow_toy_iters)),
           "train_points": b.softflow_toy_points, "test_points": TOY_TEST_POINTS,
           "test_noises": list(TOY_TEST_NOISES), "seeds": list(b.softflow_toy_seeds),
           "sigma_maxes": list(compared), "runs": toy_rows, "summary": toy_summary,
           "cnf_minus_softflow": gap}

    # (b) + (c) the expert states
    task_results = {}
    for task in tasks:
        d = task_data(task, b.softflow_states)
        context, extra = task_context(d)
        res = {**context, "runs": []}
        levels = compared if task == SWEEP_TASK else (0.1,)
        for seed in b.softflow_task_seeds:
            for s in levels:
                row = task_run(d, s, b.softflow_iters, seed)
                feat = row.pop("sample_features")
                arrays[f"{task}_samples_seed{seed}_sigma_{s:g}"] = feat
                res["runs"].append(row)
                log(f"{task} seed {seed} {row['model']:26s} held-out NLL " + ", ".join(
                    f"{k}: {v:.2f}" for k, v in row["heldout_nll"].items()) +
                    f"; sample mode shares {np.round(row['sample_mode_shares'], 2).tolist()}"
                    f" (data {np.round(res['data_mode_shares'], 2).tolist()}), at the modes "
                    f"{np.round(row['sample_at_mode_shares'], 2).tolist()}"
                    f" (data {np.round(res['data_at_mode_shares'], 2).tolist()})"
                    f"  ({row['seconds']:.0f} s)")
        if "feature_grid" in res:   # 1-D feature: the samples' density curves too
            for r in res["runs"]:
                f = arrays[f"{task}_samples_seed{r['seed']}_sigma_{r['sigma_max']:g}"][:, 0]
                r["feature_kde_samples"] = feature_kde(f[np.isfinite(f)],
                                                       np.asarray(res["feature_grid"]))
        arrays[f"{task}_data_features"] = extra["data_features"]
        task_results[task] = res
    payload = {"budget_sizes": {k: v for k, v in dataclasses.asdict(b).items()
                                if k.startswith("softflow_")},
               "threads": torch.get_num_threads(), "torch": torch.__version__,
               "toy": toy, "tasks": task_results,
               "wall_seconds": time.perf_counter() - t_start}
    return payload, arrays
