"""SoftFlow's fast kernels: f and the trace of its Jacobian in one forward pass, no autograd.

Private to :mod:`dc_lesson.density.softflow`, whose docstring explains the idea: the Jacobian
of a concat-squash MLP is a product of per-layer factors diag(s_k) W_k, so its trace (exact) or
``e^T J e`` (Hutchinson) can be carried forward through the layers with the activations instead
of asking autograd for D vector-Jacobian products.  ``tests/test_softflow.py`` checks every
kernel against ``torch.func`` and the naive autograd loop.

**The activation.**  A flow's hidden tanh is torch's or, with ``tanh="numpy"`` (DC's choice),
NumPy's (:func:`tanh`): on this project's CPUs torch's float32 tanh costs about 3.5 ns an
element and NumPy's SIMD kernel about 0.4, and the tanh was half of evaluating log P_w.  Both
are accurate to about one unit in the last place, so they agree except in the last bit of
about a third of the values; the derivative is autograd's own (``tanh_backward``, from the
output).  ``dc_lesson.nn.fast.disabled()`` switches every flow to torch's kernel.
"""

from __future__ import annotations

import numpy as np
import torch

from dc_lesson.nn import fast as _fast

_ONE = torch.tensor(1.0)
KERNELS = ("torch", "numpy")   # a flow's tanh


class _NumpyTanh(torch.autograd.Function):
    """tanh by NumPy's kernel; the backward pass is autograd's TanhBackward (from the output)."""

    @staticmethod
    def forward(ctx, a):
        h = torch.empty_like(a)
        np.tanh(a.detach().numpy(), out=h.numpy())
        ctx.save_for_backward(h)
        return h

    @staticmethod
    def backward(ctx, grad):
        (h,) = ctx.saved_tensors
        return torch.ops.aten.tanh_backward(grad, h)


def tanh(a: torch.Tensor, inplace: bool = False, kernel: str = "numpy") -> torch.Tensor:
    """tanh by ``kernel``: ``"numpy"`` (differentiable; torch's under ``fast.disabled()``) or
    ``"torch"``.  ``inplace`` (only without autograd) may overwrite ``a``."""
    if kernel == "torch" or not _fast.enabled():
        return a.tanh_() if inplace else torch.tanh(a)
    if torch.is_grad_enabled() and a.requires_grad:
        return _NumpyTanh.apply(a)
    a = a.contiguous()
    out = a if inplace else torch.empty_like(a)
    np.tanh(a.numpy(), out=out.numpy())
    return out


def context(net, noise_in: torch.Tensor) -> list:
    """The noise level's part of every gate and hyper-bias, computed once per ODE solve.

    Per layer ``(gate_t, gate_rest, bias_t, bias_rest)`` so that at time t the gate is
    ``sigmoid(t * gate_t + gate_rest)`` and the hyper-bias ``t * bias_t + bias_rest``.  One
    noise level for all states gives (1, width) tensors that broadcast.
    """
    s = noise_in.reshape(-1, 1)
    out = []
    for layer in net.layers:
        wg, bg, wb = layer.hyper_gate.weight, layer.hyper_gate.bias, layer.hyper_bias.weight
        out.append((wg[:, 0], s * wg[:, 1] + bg, wb[:, 0], s * wb[:, 1]))
    return out

def evaluate(net, t: torch.Tensor, z: torch.Tensor, context: list, trace: str | None = None,
             probe: torch.Tensor | None = None, workspace: dict | None = None):
    """Returns ``(f, tr)``: f (B, D) and, per state, the exact trace of df/dz
    (``trace="exact"``), the estimate ``e^T (df/dz) e`` for the probe e
    (``trace="hutchinson"``), or None (``trace=None``).

    ``workspace``: a dict in which the exact trace keeps its (B, D, width) buffers from one
    call to the next, used only without autograd.  Reusing them matters: a fresh 9 MB tensor
    per layer and call (B = 2048, D = 17, width 64) is paged in by the kernel each time,
    which costs more than the arithmetic done on it.
    """
    inplace = workspace is not None and not torch.is_grad_enabled()
    # The forward pass, keeping what the derivatives need: per layer the matrix weff and
    # the per-state gate geff with d a_k / d h_{k-1} = diag(geff) weff, and per hidden layer
    # s_k = tanh'(a_k) * geff, so that d h_k / d h_{k-1} = diag(s_k) weff.
    weffs, geffs, slopes = [], [], []
    kernel = getattr(net, "tanh_kernel", "torch")
    h, n = z, len(net.layers)
    for k, (layer, (gt, gr, bt, br)) in enumerate(zip(net.layers, context)):
        w, b = layer.layer.weight, layer.layer.bias   # (out, in), (out,)
        gate = torch.sigmoid(gr + t * gt)              # (B or 1, out)
        shift = br + t * bt
        if gate.shape[0] == 1:
            # One noise level for every state (always so in log_prob): fold the gate into
            # the layer, (W h + b) * g + c = (g W) h + (g b + c): one addmm, no (B, out) ops.
            weff, geff = w * gate.reshape(-1, 1), None
            a = torch.addmm(b * gate + shift, h, weff.t())
        else:
            weff, geff = w, gate
            a = torch.addmm(b, h, w.t()) * gate + shift
        weffs.append(weff)
        geffs.append(geff)
        if k == n - 1:
            break
        h = tanh(a, inplace, kernel)
        if trace is not None:
            s = torch.addcmul(_ONE, h, h, value=-1.0)  # tanh' = 1 - h^2
            slopes.append(s if geff is None else s * geff)
    if trace is None:
        return a, None
    g_last = geffs[-1]
    if trace == "hutchinson":
        v = probe                                      # J e, one layer at a time
        for weff, s in zip(weffs[:-1], slopes):
            v = (v @ weff.t()) * s
        jv = v @ weffs[-1].t()
        return a, ((jv if g_last is None else jv * g_last) * probe).sum(-1)
    if inplace and all(g is None for g in geffs):
        return a, exact_trace_folded(weffs, slopes, workspace)
    return a, exact_trace_carry(weffs, slopes, g_last, workspace if inplace else None)



def exact_trace_carry(weffs: list, slopes: list, g_last, workspace: dict | None):
    """tr(df/dz) by carrying the Jacobian forward: M_k[b, d, :] = d h_k / d z_d, (B, D, width),
    M_1 = W_1^T * s_1, M_k = (M_{k-1} @ W_k^T) * s_k, tr = sum_i g_i <W_L[i], M[:, i, :]>.
    Differentiable (training with the exact trace); with ``workspace``, in place."""
    s1, w1 = slopes[0], weffs[0]
    bsz, d = s1.shape[0], w1.shape[1]
    if workspace is not None:
        carry = torch.mul(w1.t().unsqueeze(0), s1.unsqueeze(1),
                          out=_buffer(workspace, 0, (bsz, d, w1.shape[0])))
    else:
        carry = w1.t().unsqueeze(0) * s1.unsqueeze(1)
    for k in range(1, len(slopes)):
        w, s = weffs[k], slopes[k]
        flat = carry.reshape(bsz * d, -1)     # one 2-D product for the batch (faster than 3-D)
        if workspace is not None:
            nxt = _buffer(workspace, k, (bsz, d, w.shape[0]))
            torch.mm(flat, w.t(), out=nxt.view(bsz * d, -1))
            carry = nxt.mul_(s.unsqueeze(1))
        else:
            carry = torch.mm(flat, w.t()).view(bsz, d, -1) * s.unsqueeze(1)
    w_last = weffs[-1]
    r = (carry.mul_(w_last) if workspace is not None else carry * w_last).sum(-1)   # (B, D)
    return (r if g_last is None else r * g_last).sum(-1)


def exact_trace_folded(weffs: list, slopes: list, workspace: dict) -> torch.Tensor:
    """tr(df/dz) without autograd when every gate is folded into its layer (one noise level).

    The same products as :func:`exact_trace_carry`, grouped so that the first and the last two
    layers each become one (B, width) x (width, D * width) matrix product against a small
    constant tensor (and the per-state diagonal s_k in between):

        tr = sum_{d, e} s_{m-1, e} * (s_1 @ K_1)[d, e] * (s_m @ K_L)[d, e]       (m = 3)

    with K_1[a, (d, e)] = W_1[a, d] W_2[e, a] and K_L[h, (d, e)] = W_L[d, h] W_m[h, e], m the
    number of hidden layers; more hidden layers carry M forward in between.  Same arithmetic
    as the carry, fewer passes over (B, D, width) memory: about 1.3x faster here.
    """
    m, s1 = len(slopes), slopes[0]
    w1, w_last = weffs[0], weffs[-1]
    bsz, d = s1.shape[0], w1.shape[1]
    if m == 1:          # tr = sum_a s_1a sum_d W_2[d, a] W_1[a, d]
        return s1 @ (w_last.t() * w1).sum(1)
    w_m = weffs[m - 1]                                              # (H_m, H_{m-1})
    k_last = (w_last.t().unsqueeze(2) * w_m.unsqueeze(1)).reshape(w_m.shape[0], -1)
    q = torch.mm(slopes[-1], k_last, out=_buffer(workspace, "q", (bsz, k_last.shape[1])))
    q = q.view(bsz, d, -1)                                          # (B, D, H_{m-1})
    if m == 2:          # tr = sum_e s_1e sum_d W_1[e, d] q[d, e]
        return (q.mul_(w1.t()).sum(1) * s1).sum(-1)
    w2 = weffs[1]
    k_first = (w1.unsqueeze(2) * w2.t().unsqueeze(1)).reshape(w1.shape[0], -1)
    carry = torch.mm(s1, k_first, out=_buffer(workspace, "p", (bsz, k_first.shape[1])))
    carry = carry.view(bsz, d, -1)                                  # d a_2 / d z, (B, D, H_2)
    for k in range(1, m - 2):   # through hidden layers 2 .. m-2
        carry.mul_(slopes[k].unsqueeze(1))
        w = weffs[k + 1]
        nxt = _buffer(workspace, k, (bsz, d, w.shape[0]))
        torch.mm(carry.view(bsz * d, -1), w.t(), out=nxt.view(bsz * d, -1))
        carry = nxt
    return (carry.mul_(q).sum(1) * slopes[m - 2]).sum(-1)


def _buffer(workspace: dict, key, shape) -> torch.Tensor:
    buf = workspace.get(key)
    if buf is None or buf.shape != shape:
        buf = workspace[key] = torch.empty(shape)
    return buf
