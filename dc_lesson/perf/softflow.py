"""How fast is SoftFlow's density, and what does the speed cost in accuracy?

``dc-lesson perf softflow`` times, for a ``dim``-dimensional state (17: HalfCheetah's)
and batches of ``batch`` states, a flow (64-64-64) trained briefly on synthetic data so that its
dynamics are not trivial:

* **training steps per second** with Hutchinson's trace, ours (one Jacobian-vector product
  carried forward through the layers, see :mod:`dc_lesson.density.softflow`) against the usual FFJORD
  way (a vector-Jacobian product by ``torch.autograd.grad(..., create_graph=True)``, so the
  backward pass differentiates a backward pass), both with rk4 (step 0.25) and dopri5 (1e-5);
* **log_prob states per second** with the exact trace: NAIVE (the reference: a Python loop of D
  autograd calls for the trace, dopri5 at rtol = atol = 1e-5) against ours (the Jacobian carried
  forward as one batched tensor, no autograd graph) with the same dopri5 and with fixed-step rk4,
  and ``torch.func`` (``vmap(jacfwd)``) for comparison; each with the mean absolute difference of
  its log-densities from the naive reference, in nats.

Figures drift by up to 30% between runs on a shared machine: the ratios, measured back to back
in one run, are what carry over.  The benchmark takes a minute or two on one thread.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time

import numpy as np
import torch
from torch import nn

from dc_lesson.density import softflow as sf
from dc_lesson.nn import fast


# -- the naive references ------------------------------------------------------------------------

class NaiveDynamics(nn.Module):
    """f and its trace by plain autograd, as a first implementation would write them.

    ``trace="loop"``: the exact trace as ``sum_i d f_i / d z_i``, one ``autograd.grad`` per
    dimension; ``trace="vjp"``: FFJORD's Hutchinson estimate ``(e^T df/dz) e`` with the
    vector-Jacobian product from ``autograd.grad``.  ``create_graph`` for training.
    """

    def __init__(self, net: sf.ODENet, noise_in: torch.Tensor, trace: str,
                 probe: torch.Tensor | None = None, create_graph: bool = False):
        super().__init__()
        self.net, self.noise_in, self.trace, self.probe = net, noise_in, trace, probe
        self.create_graph = create_graph
        self.nfe = 0

    def forward(self, t, state):
        self.nfe += 1
        z = state[0]
        with torch.enable_grad():
            if not z.requires_grad:
                z = z.detach().requires_grad_(True)
            f = self.net(t, z, self.noise_in)
            if self.trace == "loop":
                tr = torch.zeros(len(z), dtype=z.dtype)
                for i in range(z.shape[1]):
                    g = torch.autograd.grad(f[:, i].sum(), z, create_graph=self.create_graph,
                                            retain_graph=True)[0]
                    tr = tr + g[:, i]
            else:
                g = torch.autograd.grad(f, z, self.probe, create_graph=self.create_graph)[0]
                tr = (g * self.probe).sum(-1)
        if not self.create_graph:
            f, tr = f.detach(), tr.detach()
        return f, tr


def naive_log_prob(flow: sf.SoftFlow, states, rtol: float = 1e-5,
                   atol: float = 1e-5) -> torch.Tensor:
    """log p(states) at noise 0: per-dimension autograd loop for the trace, dopri5."""
    u = flow.standardise(torch.as_tensor(states, dtype=torch.float32))
    func = NaiveDynamics(flow.net, flow.noise_input(0.0), "loop")
    with torch.no_grad():
        z1, delta = sf.solve(func, (u, torch.zeros(len(u))), 0.0, 1.0, "dopri5", 0.25,
                              rtol, atol)
    return sf.standard_normal_logpdf(z1) + delta + flow.log_jacobian_standardisation


def _naive_train_step(flow, optimizer, u, config, generator):
    """One FFJORD-style training step: Hutchinson by vector-Jacobian product."""
    sigma = torch.rand(len(u), generator=generator) * config.sigma_max
    u = u + sigma.unsqueeze(1) * torch.randn(u.shape, generator=generator)
    probe = sf.draw_probe(u.shape, "rademacher", generator)
    func = NaiveDynamics(flow.net, flow.noise_input(sigma), "vjp", probe, create_graph=True)
    z1, delta = sf.solve(func, (u, torch.zeros(len(u))), 0.0, 1.0, config.solver,
                          config.step_size, config.rtol, config.atol)
    loss = -(sf.standard_normal_logpdf(z1) + delta).mean()
    optimizer.zero_grad()
    loss.backward()
    optimizer.step()
    return func.nfe


def _our_train_step(flow, optimizer, u, config, generator):
    loss, nfe = sf.nll_loss(flow, u, config, generator)
    optimizer.zero_grad()
    loss.backward()
    optimizer.step()
    return nfe


# -- data ----------------------------------------------------------------------------------------

def synthetic_states(n: int, dim: int = 17, seed: int = 0) -> np.ndarray:
    """States near a curved 3-dimensional manifold in R^dim, with scales from 0.01 to 10 and a
    little noise: a stand-in for expert states (few degrees of freedom, mixed units)."""
    rng = np.random.default_rng(seed)
    latent = rng.uniform(-np.pi, np.pi, size=(n, 3))
    freq = rng.normal(size=(3, dim))
    phase = rng.uniform(0, 2 * np.pi, size=dim)
    x = np.sin(latent @ freq + phase) + 0.3 * (latent @ rng.normal(size=(3, dim)))
    x = x + 0.05 * rng.normal(size=x.shape)
    scales = np.logspace(-2, 1, dim)
    return (x * scales + rng.normal(size=dim)).astype(np.float32)


# -- the benchmark -------------------------------------------------------------------------------

def _median_ratio_runs(fns: dict, repeats: int) -> dict:
    """Calls every function of ``fns`` once per repeat, back to back, ``repeats`` times (after
    one untimed warm-up call each); returns per name the list of wall times and the last
    output."""
    out = {name: {"times": [], "out": fn()} for name, fn in fns.items()}   # warm-up
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            out[name]["out"] = fn()
            out[name]["times"].append(time.perf_counter() - t0)
    return out


# log_prob variants: name -> keyword arguments of SoftFlow.log_prob (exact trace throughout)
LOG_PROB_VARIANTS = {
    "ours, dopri5 1e-5 (the reference's solver)": dict(solver="dopri5", rtol=1e-5, atol=1e-5,
                                                       quadrature=None),
    "ours, rk4 step 0.25": dict(solver="rk4", step_size=0.25, quadrature=None),
    "ours, rk4 0.25 + 4-node quadrature [default]": dict(solver="rk4", step_size=0.25,
                                                         quadrature=4),
    "ours, rk4 0.5 + 4-node quadrature": dict(solver="rk4", step_size=0.5, quadrature=4),
    "ours, rk4 0.25 + 6-node quadrature": dict(solver="rk4", step_size=0.25, quadrature=6),
    "torch.func vmap(jacfwd), default settings": dict(solver="rk4", step_size=0.25,
                                                      quadrature=4, trace="exact_autodiff"),
}
NAIVE = "naive: autograd loop, dopri5 1e-5"


@fast.on()   # a benchmark times the fast path (dc_lesson.nn.fast)
def softflow_benchmark(dim: int = 17, batch: int = 2048, hidden=(64, 64, 64),
                       pretrain_iterations: int = 400, repeats: int = 3, train_steps: int = 3,
                       threads: int = 1, seed: int = 0, progress: bool = False) -> dict:
    """Training and log_prob throughput, ours against the naive references; returns a dict.

    The flow is first fitted for ``pretrain_iterations`` (Hutchinson, rk4 step 0.25, batches
    of 256) to ``dim``-dimensional synthetic states.  Then every variant is timed on the same
    ``batch`` held-out states, all of them back to back in each of ``repeats`` rounds; a
    ``speedup`` is the median over rounds of naive time / variant time.  ``log_prob`` rows:
    ``states_per_s`` (median), ``speedup``, ``nfe`` (evaluations of f, with or without the
    trace), ``trace_evals`` and the mean and max absolute difference in log-density from the
    naive reference (nats).  ``train`` rows (Hutchinson, per solver): steps per second of ours
    and of the naive vjp, timed alternately ``train_steps`` times each after a warm-up step,
    and the median ratio.
    """
    old_threads = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        data = synthetic_states(20_000 + batch, dim, seed)
        train, held_out = data[:20_000], data[20_000:]
        config = sf.SoftFlowConfig(hidden=tuple(hidden), iterations=pretrain_iterations,
                                   batch_size=256, solver="rk4", step_size=0.25, seed=seed)
        t0 = time.perf_counter()
        flow, log = sf.fit(train, config, progress=progress)
        nll = [r["nll"] for r in log] or [float("nan")]
        pretrain = {"iterations": pretrain_iterations, "seconds": time.perf_counter() - t0,
                    "nll_first": nll[0], "nll_last": float(np.mean(nll[-20:]))}
        x = torch.from_numpy(held_out)
        u = flow.standardise(x)

        # log_prob, exact trace
        fns = {NAIVE: lambda: naive_log_prob(flow, x)}
        for name, kw in LOG_PROB_VARIANTS.items():
            fns[name] = (lambda kw=kw: flow.log_prob(x, **{"trace": "exact", **kw}))
        runs = _median_ratio_runs(fns, repeats)
        ref, t_naive = runs[NAIVE]["out"], np.array(runs[NAIVE]["times"])
        nfe_naive = NaiveDynamics(flow.net, flow.noise_input(0.0), "loop")
        with torch.no_grad():
            sf.solve(nfe_naive, (u, torch.zeros(len(u))), 0.0, 1.0, "dopri5", 0.25, 1e-5, 1e-5)
        log_prob = {}
        for name, r in runs.items():
            times = np.array(r["times"])
            if name == NAIVE:
                nfe, trace_evals = nfe_naive.nfe, nfe_naive.nfe
            else:
                kw = {"trace": "exact", **LOG_PROB_VARIANTS[name]}
                with torch.no_grad():
                    _, _, nfe = flow.integrate(u, 0.0, **kw)
                trace_evals = kw["quadrature"] or nfe
            diff = (r["out"] - ref).abs()
            log_prob[name] = {"states_per_s": float(np.median(batch / times)),
                              "speedup": float(np.median(t_naive / times)),
                              "nfe": int(nfe), "trace_evals": int(trace_evals),
                              "mean_abs_diff": float(diff.mean()),
                              "max_abs_diff": float(diff.max())}

        # training steps, Hutchinson
        u_all = flow.standardise(torch.from_numpy(train))
        train_rows = {}
        for solver, kw in (("rk4 step 0.25", dict(solver="rk4", step_size=0.25)),
                           ("dopri5 1e-5", dict(solver="dopri5", rtol=1e-5, atol=1e-5))):
            cfg = sf.SoftFlowConfig(hidden=tuple(hidden), batch_size=batch, seed=seed, **kw)
            who = {"ours": _our_train_step, "naive vjp": _naive_train_step}
            state = {}
            for name in who:   # each on its own copy, from the same parameters and batches
                copy = sf.SoftFlow(**flow.config())
                copy.load_state_dict(flow.state_dict())
                state[name] = (copy, sf.make_optimizer(copy, cfg),
                               torch.Generator().manual_seed(seed))
            times = {name: [] for name in who}
            nfes = {name: [] for name in who}
            for i in range(train_steps + 1):
                for name, step in who.items():
                    copy, opt, gen = state[name]
                    idx = torch.randint(0, len(u_all), (batch,), generator=gen)
                    t0 = time.perf_counter()
                    nfe = step(copy, opt, u_all[idx], cfg, gen)
                    if i > 0:   # the first step is a warm-up
                        times[name].append(time.perf_counter() - t0)
                        nfes[name].append(nfe)
            res = {name: {"steps_per_s": float(np.median(1 / np.array(times[name]))),
                          "nfe": float(np.mean(nfes[name]))} for name in who}
            res["ratio"] = float(np.median(np.array(times["naive vjp"]) /
                                           np.array(times["ours"])))
            train_rows[solver] = res
        return {"dim": dim, "batch": batch, "hidden": list(hidden), "threads": threads,
                "repeats": repeats, "torch": torch.__version__,
                "machine": platform.processor() or platform.machine(),
                "pretrain": pretrain, "log_prob": log_prob, "train": train_rows}
    finally:
        torch.set_num_threads(old_threads)


def format_report(res: dict) -> str:
    p = res["pretrain"]
    lines = [f"SoftFlow benchmark: dim {res['dim']}, batch {res['batch']}, hidden "
             f"{res['hidden']}, {res['threads']} thread(s), torch {res['torch']}, medians of "
             f"{res['repeats']} rounds",
             f"flow pretrained {p['iterations']} iterations ({p['seconds']:.0f} s): "
             f"NLL {p['nll_first']:.2f} -> {p['nll_last']:.2f} nats", "",
             f"{'log_prob, exact trace':46s} {'states/s':>9s} {'speedup':>8s} {'nfe':>5s} "
             f"{'traces':>6s} {'mean|diff|':>11s} {'max|diff|':>10s}"]
    for name, r in res["log_prob"].items():
        lines.append(f"  {name:44s} {r['states_per_s']:9.0f} {r['speedup']:7.1f}x "
                     f"{r['nfe']:5d} {r['trace_evals']:6d} {r['mean_abs_diff']:11.1e} "
                     f"{r['max_abs_diff']:10.1e}")
    lines += ["", f"{'training step, Hutchinson':30s} {'ours steps/s (nfe)':>20s} "
                  f"{'naive-vjp steps/s (nfe)':>25s} {'ratio':>7s}"]
    for solver, r in res["train"].items():
        lines.append(f"  {solver:28s} {r['ours']['steps_per_s']:12.2f} ({r['ours']['nfe']:4.0f})"
                     f" {r['naive vjp']['steps_per_s']:17.2f} ({r['naive vjp']['nfe']:4.0f})"
                     f" {r['ratio']:7.2f}x")
    lines.append("(diff: |log p - naive log p| per state in nats; speedup and ratio: naive time "
                 "/ our time)")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="dc-lesson perf softflow",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--dim", type=int, default=17)
    p.add_argument("--batch", type=int, default=2048)
    p.add_argument("--threads", type=int, default=1, help="torch threads (1 or 2)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--train-steps", type=int, default=3)
    p.add_argument("--pretrain", type=int, default=400, help="pretraining iterations")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--save", help="also write the figures to this JSON result file")
    args = p.parse_args(argv)
    res = softflow_benchmark(dim=args.dim, batch=args.batch, threads=args.threads,
                             repeats=args.repeats, train_steps=args.train_steps,
                             pretrain_iterations=args.pretrain, seed=args.seed)
    print(format_report(res))
    if args.save:
        from dc_lesson.storage import write_result
        cmd = "dc-lesson perf softflow " + " ".join(
            sys.argv[1:] if argv is None else argv)
        write_result(args.save, json.loads(json.dumps(res, default=float)), command=cmd.strip(),
                     seeds=[args.seed])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
