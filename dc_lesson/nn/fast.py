"""Speed, behind one switch: kernels that compute what the readable code computes, faster.

**Two paths.**  Off (the default, *the reader's path*), ``train`` runs what its module shows:
the loss functions (``ppo.clipped_surrogate``, ``ppo.value_loss``, ``bc.bc_loss``, ...)
differentiated by autograd, ``torch.optim.AdamW`` / ``Adam`` stepped by ``optimizer.step()``,
``torch.nn.utils.clip_grad_norm_``, and rollouts through the torch modules
(``GaussianPolicy.forward`` and ``sample``).  Edit a loss and training changes
(``tests/test_fast.py::test_editing_a_readable_loss_changes_training``).  On (:func:`on`),
the same computations take these kernels:

* PPO's and BC's gradients by hand (:mod:`dc_lesson.nn.backprop`): the same bits
  (``tests/test_backprop.py``: ``test_ppo_gradients_are_autograds_to_the_bit``,
  ``test_bc_gradients_are_autograds_to_the_bit``, ``test_ppo_update_by_hand_ends_where_
  autograd_ends``, ``test_bc_step_by_hand_ends_where_autograd_ends``);
* PPO's batch normalised once per update, the Gaussian's terms without a ``Normal`` per
  minibatch: the same bits (``tests/test_ppo.py::test_the_fast_ppo_update_equals_the_
  reference_path_bit_for_bit``, ``test_log_prob_entropy_equals_torch_normal_bit_for_bit...``);
  a whole ``ppo_update`` and ``bc_step`` on either path, given one optimiser, the same bits
  (``tests/test_backprop.py::test_the_readers_ppo_update_is_the_fast_paths_with_the_same_
  optimiser``, ``test_the_readers_bc_step_is_the_fast_paths_with_the_same_optimiser``);
* the lean optimiser step, ``zero_grad`` and gradient clip (:func:`optimizer_step`,
  :func:`zero_grad`, :func:`clip_grad_norm_`): the same bits as ``optimizer.step()`` and
  ``torch.nn.utils.clip_grad_norm_`` on the same optimiser
  (``tests/test_fast.py::test_the_lean_optimiser_step_is_torchs_to_the_bit``);
* fused AdamW and Adam (:func:`adamw`, :func:`adam`): *not* the same bits, the same update
  computed in another order; a step's weights agree to a few float32 ulps
  (``tests/test_fast.py::test_the_fused_optimiser_is_the_plain_one_to_float32_rounding``);
* the NumPy forward of rollouts (:class:`NumpyForward`, :class:`GaussianSampler`): *not* the
  same bits; each output within a few float32 ulps of the size of the layers' terms
  (``tests/test_fast.py``: ``test_numpy_forward_equals_the_modules_to_float32_rounding``,
  ``test_one_step_from_the_same_state_agrees_on_either_path``);
* NumPy's tanh in a flow (``density._trace``, DC's ``flow.tanh="numpy"``): *not* the same
  bits, within one ulp (``tests/test_softflow.py::test_the_flows_tanh_is_numpys_to_one_ulp...``).
* GPRIL's flows sampled in NumPy (``gpril.MADE.numpy_invert``): *not* the same bits, the same
  samples to float32 rounding (``tests/test_baselines.py::test_gpril_maf_sampling_on_the_fast_
  path_is_the_readers_to_float32_rounding``).

A learner turns a last-bit difference into another trajectory, so a run on the reader's path
is another sample of the same experiment, not the fast path's numbers.

**Who runs which.**  Every stored cell was computed on the fast path, so the sweep worker
(``experiments.sweep.execute``, which ``--recheck`` also runs) turns it on around each cell,
and so do the benchmarks (``dc_lesson.perf``: each ``main``; ``perf learners`` times both
paths).  The book's chapters, the tests, the README's library example and anyone calling
``train`` directly take the reader's path; they are meant to, and their numbers are the
reader's own, not the stored cells'; so does ``dc-lesson train``.  ``dc-lesson expert train``
and ``dc-lesson demos`` turn it on (``cli/run.py``): the stored experts and demonstrations
were made on the fast path, and a command that regenerates them must make the stored file.  Rollouts keep the torch modules on the reader's path
too (the NumPy forward is not bit-identical, so an edited ``forward`` must show), at about
0.4 ms more per control step.

**How the NumPy forward works.**  A rollout calls the policy once per control step on a small
batch (8 to 16 environments): for a 64-64 MLP the arithmetic takes microseconds and torch's
dispatch, autograd bookkeeping and distribution objects take the rest (issue 14's profile).
:class:`NumpyForward` snapshots a network's weights (and its frozen observation normaliser)
into NumPy arrays once per batch of steps and evaluates them with three matrix products.
Sampling stays torch's: the noise of a stochastic action is ``torch.randn`` drawn from the
same ``torch.Generator`` in the same shape as :meth:`GaussianPolicy.sample` draws it, so a
seeded run draws the same noise on either path.

:func:`disabled` is the reader's path with the task engine stepping each copy on its own as
well (``tasks.vec.per_copy``): the code as it was before issue 14, which ``perf learners``
times against the fast path.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np
import torch
import torch.optim.optimizer as _optim
from torch.autograd.graph import increment_version

from dc_lesson.tasks import vec as _vec

_ENABLED = False     # the reader's path unless on() says otherwise
_ONE = torch.tensor(1.0)

_ACTIVATIONS = {
    "Tanh": np.tanh,
    "ReLU": lambda x: np.maximum(x, 0, out=x),
    "ELU": lambda x: np.where(x > 0, x, np.expm1(np.minimum(x, 0))),
    "SiLU": lambda x: x / (1 + np.exp(-x)),
}


def enabled() -> bool:
    """Whether the fast path is on (see the module's table; off by default)."""
    return _ENABLED


@contextlib.contextmanager
def on():
    """Within the block, the fast path: what sweep workers and benchmarks run.  An optimiser
    is fused or not as it is built, so build it (call ``train``) inside the block."""
    global _ENABLED
    old, _ENABLED = _ENABLED, True
    try:
        yield
    finally:
        _ENABLED = old


@contextlib.contextmanager
def disabled():
    """Within the block, the reader's path, and new VecEnvs step their copies one by one (the
    code before issue 14, close to it but not exactly: ``perf learners``' "old" column)."""
    global _ENABLED
    old, _ENABLED = _ENABLED, False
    try:
        with _vec.per_copy():
            yield
    finally:
        _ENABLED = old


class NumpyForward:
    """``net(obs)`` of a :class:`~dc_lesson.nn.policies.GaussianPolicy` (its action mean) or
    :class:`~dc_lesson.nn.policies.ValueNetwork` (its value), from a snapshot of its weights.

    The normaliser is applied as :class:`~dc_lesson.nn.policies.RunningNorm` does (in float64,
    clipped, then float32); the layers in float32.  Take a new snapshot after the weights
    change.
    """

    def __init__(self, net: torch.nn.Module):
        seq = net.mean_net if hasattr(net, "mean_net") else net.net
        norm = net.obs_norm
        if norm is None:
            self.norm = None
        else:
            self.norm = (norm.mean.numpy().copy(),
                         np.sqrt(norm.var.numpy() + norm.eps), float(norm.clip))
        self.layers = []   # (W^T, b, activation or None)
        mods = list(seq)
        for i, m in enumerate(mods):
            if isinstance(m, torch.nn.Linear):
                act = None
                if i + 1 < len(mods) and not isinstance(mods[i + 1], torch.nn.Linear):
                    act = _ACTIVATIONS[type(mods[i + 1]).__name__]
                self.layers.append((m.weight.detach().numpy().T.copy(),
                                    m.bias.detach().numpy().copy(), act))
        self.squeeze = not hasattr(net, "mean_net")   # a value network returns (B,)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        x = np.asarray(obs)
        if self.norm is not None:
            mean, std, clip = self.norm
            x = np.clip((x.astype(np.float64) - mean) / std, -clip, clip)
        x = x.astype(np.float32)
        for w, b, act in self.layers:
            x = x @ w
            x += b
            if act is not None:
                x = act(x)
        return x[..., 0] if self.squeeze else x


class GaussianSampler:
    """Samples ``mean + std * noise`` of a policy for a batch, with its log-probability: what
    :meth:`GaussianPolicy.sample` and :meth:`GaussianPolicy.log_prob` give, in NumPy."""

    def __init__(self, policy):
        self.mean = NumpyForward(policy)
        log_std = policy.log_std.detach().numpy().astype(np.float32)
        self.std = np.exp(log_std)
        # log N(a; mu, sigma) summed over the action: the part that does not depend on a
        self.log_norm = float(-log_std.astype(np.float64).sum()
                              - 0.5 * len(log_std) * math.log(2 * math.pi))

    def __call__(self, obs: np.ndarray, generator: torch.Generator | None):
        """(raw actions (B, act_dim) float32, log-probabilities (B,) float32)."""
        mu = self.mean(obs)
        noise = torch.randn(mu.shape, generator=generator).numpy()
        actions = mu + self.std * noise
        # (a - mu) / sigma is the noise itself; recomputing it keeps the float32 rounding of a
        # module's log_prob on the stored action
        z = (actions - mu) / self.std
        logp = self.log_norm - 0.5 * np.square(z, dtype=np.float64).sum(-1)
        return actions, logp.astype(np.float32)


def _bump_versions(optimizer, args, kwargs) -> None:
    # PyTorch's fused kernels write the parameters without bumping their version counters
    # (measured with torch 2.13: a fused AdamW step leaves every ``_version`` as it was, a
    # foreach or for-loop step bumps them).  :func:`snapshot` keys on those counters, so
    # without this hook a policy snapshotted during training (an evaluation at a checkpoint)
    # kept acting with the old weights for the rest of the run and in its final evaluation:
    # GAIL, whose parameters change only through its optimiser, was evaluated as it stood at
    # its first checkpoint.  Bumping after each step keeps the fused update bit for bit.
    for group in optimizer.param_groups:
        for p in group["params"]:
            increment_version(p)


def _fused(cls, params, kwargs):
    opt = cls(params, fused=True if enabled() else None, **kwargs)
    if enabled():
        opt.register_step_post_hook(_bump_versions)
    return opt


def adamw(params, **kwargs) -> torch.optim.AdamW:
    """AdamW as every learner builds it: on the fast path PyTorch's fused CPU kernel (one
    kernel for all parameters instead of a Python loop over them: the same update, computed in
    another order), with the parameters' version counters bumped after each step (the fused
    kernel leaves them, and :func:`snapshot` reads them)."""
    return _fused(torch.optim.AdamW, params, kwargs)


def adam(params, **kwargs) -> torch.optim.Adam:
    """Adam, likewise (GAIL's discriminator)."""
    return _fused(torch.optim.Adam, params, kwargs)


# -- an optimiser step without Optimizer.step's bookkeeping ---------------------------------------
#
# On the library's 64-unit networks a minibatch step's arithmetic takes tens of microseconds,
# and torch's wrappers around it as long again: ``Optimizer.step`` (hook and profiler wrappers,
# grouping the tensors by device and dtype, checks) took 85 us around a 35 us fused AdamW
# kernel, ``clip_grad_norm_`` 55 us around 33 us of norms and products (torch 2.13, one
# thread).  The functions below make the same kernel calls, with the same arguments in the
# same order, and skip the rest, so parameters, optimiser state and returned norms are the
# same to the bit (``tests/test_fast.py`` steps both for a hundred steps and compares).

def _lean(optimizer) -> bool:
    # the kernel call below is what Adam(W)'s fused path calls, for the settings we use; a
    # hook anyone registered (on this optimiser or on all) sends the step through torch
    return (enabled() and isinstance(optimizer, torch.optim.Adam)
            and all(g["fused"] and not (g["amsgrad"] or g["maximize"] or g["capturable"]
                                        or g["differentiable"]) for g in optimizer.param_groups)
            and not (optimizer._optimizer_step_pre_hooks or _optim._global_optimizer_pre_hooks
                     or _optim._global_optimizer_post_hooks)
            and list(optimizer._optimizer_step_post_hooks.values()) in ([], [_bump_versions]))


def optimizer_step(optimizer) -> None:
    """``optimizer.step()``.  On the fast path a fused Adam or AdamW whose state exists (from
    its first step) calls its kernel directly: ``torch._fused_adam(w)_`` on each group's
    parameters with a gradient, after adding 1 to their step counters, as
    ``torch.optim.adam._fused_adam`` does; then the version counters are bumped (see
    :func:`_bump_versions`).  Anything else takes ``optimizer.step()``."""
    if not _lean(optimizer):
        optimizer.step()
        return
    calls = []
    for group in optimizer.param_groups:
        params = [p for p in group["params"] if p.grad is not None]
        states = [optimizer.state.get(p) for p in params]
        if not all(states):          # the first step creates the state: torch's own step
            optimizer.step()
            return
        calls.append((group, params, states))
    for group, params, states in calls:
        steps = [st["step"] for st in states]
        # (a tensor 1 with alpha: the overload that does not wrap the scalar per tensor)
        torch._foreach_add_(steps, _ONE, alpha=1.0)
        kernel = torch._fused_adamw_ if group["decoupled_weight_decay"] else torch._fused_adam_
        beta1, beta2 = group["betas"]
        kernel(params, [p.grad for p in params], [st["exp_avg"] for st in states],
               [st["exp_avg_sq"] for st in states], [], steps, amsgrad=False, lr=group["lr"],
               beta1=beta1, beta2=beta2, weight_decay=group["weight_decay"], eps=group["eps"],
               maximize=False, grad_scale=None, found_inf=None)
    _bump_versions(optimizer, (), {})


def zero_grad(optimizer) -> None:
    """``optimizer.zero_grad()`` (which sets the gradients to None), without its wrapper."""
    if not enabled():
        optimizer.zero_grad()
        return
    for group in optimizer.param_groups:
        for p in group["params"]:
            p.grad = None


def clip_grad_norm_(params, max_norm: float) -> torch.Tensor:
    """``torch.nn.utils.clip_grad_norm_(params, max_norm)``: the total 2-norm of the gradients
    (returned) and the gradients scaled by ``min(1, max_norm / (norm + 1e-6))``.  On the fast
    path its foreach kernels are called directly (one CPU device, one dtype: the grouping it
    would do is one group), and an infinite ``max_norm`` (measure, do not clip) skips the
    multiplication by 1 while the norm is finite."""
    if not enabled():
        return torch.nn.utils.clip_grad_norm_(params, max_norm)
    grads = [p.grad for p in params if p.grad is not None]
    if not grads or len({(g.device, g.dtype) for g in grads}) > 1 or grads[0].device.type != "cpu":
        return torch.nn.utils.clip_grad_norm_(params, max_norm, foreach=True)
    with torch.no_grad():
        total = torch.linalg.vector_norm(torch.stack(torch._foreach_norm(grads, 2.0)), 2.0)
        # (an infinite bound multiplies by 1, unless the norm is not finite: then by NaN)
        if max_norm != math.inf or not torch.isfinite(total):
            torch._foreach_mul_(grads, torch.clamp(float(max_norm) / (total + 1e-6), max=1.0))
    return total


def _versions(net: torch.nn.Module) -> tuple:
    # Every in-place change of a tensor (an optimiser step, load_state_dict, an update of the
    # normaliser) bumps its version counter, so equal versions mean equal weights.
    return tuple(t._version for t in (*net.parameters(), *net.buffers()))


def snapshot(net: torch.nn.Module, kind=NumpyForward):
    """``kind(net)``, reused while none of ``net``'s tensors has changed since it was taken."""
    key = (kind, _versions(net))
    cached = net.__dict__.get("_numpy_snapshot")
    if cached is None or cached[0] != key:
        cached = (key, kind(net))
        net.__dict__["_numpy_snapshot"] = cached
    return cached[1]


__all__ = ["GaussianSampler", "NumpyForward", "adam", "adamw", "clip_grad_norm_", "disabled",
           "enabled", "on", "optimizer_step", "snapshot", "zero_grad"]
