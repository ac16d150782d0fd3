"""DBox's fast forward and backward passes, written out by hand on plain torch products.

The network (:mod:`.model`) is one autograd node whose forward and backward are written
here, so that every matrix product is one call and nothing is computed twice. No library
does this for DBox: ``torch.nn.LSTM`` has no peepholes and no fully connected head fed
with the whole input, and autograd through the original's per-gate formulation
(:func:`.model.reference_forward`) computes every gate block twice per observation
(1.7-2.1 times slower, ``benchmarks/bench_dbox.py``). Every product is a plain torch
product (MKL's SGEMM behind ``torch.addmm`` on a CPU); the same code runs in float64 and
on CUDA.

The LSTM runs feature-major, one contiguous (features, B) block per observation::

    q[t] = [c_(t-1); h_(t-1); x_t; 1; c_t]                      (392, B)
    sigmoid([i; f; 2 g]) = sigmoid(M1 @ q[t][:264])              M1 = [V; U; W; bias]^T of i, f, g
    o = sigmoid(M2 @ q[t][128:])                                 M2 = [U; W; bias; V]^T of o

so the input product, the bias and both peepholes are one product per gate group, every
operand is read in the layout the kernel wants, and the weight gradients of a step are
one product each, accumulated in place. tanh(z) is computed as 2 sigmoid(2z) - 1 (the
factor 2 of the g rows sits in M1): three times faster than torch.tanh on AMD here.

An opt-in path through oneDNN's matmul (``torch.ops.mkldnn._linear_pointwise``, a private
torch operator, with ``ODMD_BENCH_ONEDNN=1``) was dropped (issue 44); its gain and the
loss measured when dropping it are in ``docs/speed.md``. The setting is still read so
that a recorded command keeps its meaning: every value it took (``auto``, ``1``, ``0``)
runs these products, as ``1`` did on a torch build without oneDNN, and any other value
is refused as before (:func:`check_setting`).
"""

from __future__ import annotations

import os
from typing import Any

import torch
from odmd_bench_baselines.dbox.configs import FC_WIDTH, HIDDEN, N_FC, N_FEATURES

from odmd_bench import DataError, UsageError

_C0, _H0, _X0 = 0, HIDDEN, 2 * HIDDEN  # rows of c_(t-1), h_(t-1), x_t in q[t]
_ONE = _X0 + N_FEATURES  # the row of ones
_K = _ONE + 1  # 264: rows read by each gate group
_CT = _K  # rows of c_t
_Q = _CT + HIDDEN  # 392

#: Values of ``ODMD_BENCH_ONEDNN`` (all run the same plain products; others are refused).
KERNEL_SETTINGS = ("auto", "1", "0")


def check_setting() -> None:
    """Refuse an unknown ``ODMD_BENCH_ONEDNN``: a value a recorded command never had.

    Unset, ``auto``, ``0`` and ``1`` all run plain torch products, for training and
    inference alike (``1`` once asked for oneDNN's kernel, now dropped). Nothing here
    depends on a timing or on the machine's load.

    Raises:
        UsageError: ``ODMD_BENCH_ONEDNN`` has another value.
    """
    setting = os.environ.get("ODMD_BENCH_ONEDNN", "auto") or "auto"
    if setting not in KERNEL_SETTINGS:
        raise UsageError(f"ODMD_BENCH_ONEDNN={setting!r}: expected one of {', '.join(KERNEL_SETTINGS)}")


def cpu_kernels() -> str:
    """The kernel of the float32 CPU products, for a training record: always ``plain`` (see :func:`check_setting`)."""
    check_setting()
    return "plain"


def _linear(
    x: torch.Tensor,
    w: torch.Tensor,
    bias: torch.Tensor | None = None,
    add: torch.Tensor | None = None,
    act: str = "none",
) -> torch.Tensor:
    """``act(x @ w.T + bias + add)``: one product with its epilogue.

    x (M, K), w (N, K), bias (N,), add (M, N); ``act`` is ``none``, ``relu`` or ``sigmoid``.
    """
    out = x @ w.t() if add is None else torch.addmm(add, x, w.t())
    if bias is not None:
        out = out + bias
    if act == "relu":
        return torch.relu_(out)
    return torch.sigmoid_(out) if act == "sigmoid" else out


def _tanh_from_sigmoid_(s: torch.Tensor) -> torch.Tensor:
    """tanh(z) in place of s = sigmoid(2 z)."""
    return s.mul_(2.0).sub_(1.0)


class Packed:
    """The parameters arranged for the products (see the layout above)."""

    def __init__(
        self, w: torch.Tensor, u: torch.Tensor, bias: torch.Tensor, v: torch.Tensor, *fc: torch.Tensor
    ) -> None:
        h3 = 3 * HIDDEN
        b = bias.unsqueeze(0)
        # (384, 264) and (128, 264), each row one gate unit
        self.m1 = torch.cat([v[:, :h3], u[:, :h3], w[:, :h3], b[:, :h3]], 0).t().contiguous()
        self.m2 = torch.cat([u[:, h3:], w[:, h3:], b[:, h3:], v[:, h3:]], 0).t().contiguous()
        self.m1_fwd = self.m1.clone()
        self.m1_fwd[2 * HIDDEN :] *= 2.0  # sigmoid(2 z) gives tanh(z)
        self.fc_w = list(fc[0::2])
        self.fc_b = list(fc[1::2])


def forward_pass(x: torch.Tensor, pk: Packed, keep: bool) -> tuple[torch.Tensor, dict[str, Any]]:
    """The network's output (B,) for ``x`` (B, n_obs, 7) and, if ``keep``, what :func:`backward_pass` needs."""
    if x.device.type == "cpu" and x.dtype == torch.float32:
        check_setting()  # where the setting once chose the kernel
    b, n, nf = x.shape
    if n < 1:
        raise DataError("DBox needs at least one observation")
    hs = HIDDEN
    q = x.new_empty(n if keep else 1, _Q, b)
    q[:, _ONE] = 1.0
    q[0, :_X0] = 0.0  # h and c start at zero
    if keep:
        q[:, _X0:_ONE] = x.permute(1, 2, 0)
    gates: list[tuple[torch.Tensor, ...]] = []  # per step: i; f; g (384, B), o, tanh(c_t) (128, B)
    # Without a backward pass, temporaries live in buffers reused from step to step:
    # fresh memory costs as much as the arithmetic here (page faults).
    th_buf = None if keep else x.new_empty(hs, b)
    h = q[0, _H0:_X0]
    for t in range(n):
        qt = q[t] if keep else q[0]
        if not keep:
            qt[_X0:_ONE] = x[:, t].t()
            if t:
                qt[_C0:_H0] = qt[_CT:]
        ifg = _linear(pk.m1_fwd, qt[:_K].t(), act="sigmoid")
        i, f, g = ifg[:hs], ifg[hs : 2 * hs], _tanh_from_sigmoid_(ifg[2 * hs :])
        c = torch.mul(i, g, out=qt[_CT:])
        if t:
            c.addcmul_(f, qt[_C0:_H0])
        o = _linear(pk.m2, qt[_H0:].t(), act="sigmoid")
        th = _tanh_from_sigmoid_(
            torch.sigmoid_(c.mul(2.0) if th_buf is None else torch.mul(c, 2.0, out=th_buf))
        )
        if keep:
            h = o * th
            gates.append((ifg, o, th))
            if t + 1 < n:
                q[t + 1, _C0:_H0] = c
                q[t + 1, _H0:_X0] = h
        else:  # h_(t-1) has been read: h_t takes its rows
            h = torch.mul(o, th, out=qt[_H0:_X0])
    flat = x.reshape(b, n * nf)
    ins: list[torch.Tensor] = []
    d = h.t()
    fc_in = None if keep else x.new_empty(b, FC_WIDTH + n * nf)
    if fc_in is not None:
        fc_in[:, FC_WIDTH:] = flat
    for k in range(N_FC):
        width = d.shape[1]
        if fc_in is None:
            inp = torch.cat([d, flat], 1)  # the original's [d, X]
            ins.append(inp)
        else:
            inp = fc_in[:, FC_WIDTH - width :]
            inp[:, :width] = d
        d = _linear(inp, pk.fc_w[k], pk.fc_b[k], act="relu")
    out = _linear(d, pk.fc_w[N_FC], pk.fc_b[N_FC]).view(b)
    saved = {"q": q, "gates": gates, "ins": ins, "last": d} if keep else {}
    return out, saved


def backward_pass(grad: torch.Tensor, saved: dict[str, Any], pk: Packed) -> list[torch.Tensor]:
    """Gradients of W, U, bias, V, linears.0.weight ... linears.6.bias from d loss / d out (B,)."""
    q, gates, ins, last = saved["q"], saved["gates"], saved["ins"], saved["last"]
    n, _, b = q.shape
    hs = HIDDEN
    # the fully connected head, row-major as the original
    g_out = grad.reshape(b, 1)
    fc_grads = [_linear(g_out.t(), last.t()), g_out.sum(0)]  # linears.6
    dd = g_out * pk.fc_w[N_FC]  # (B, 256)
    for k in reversed(range(N_FC)):
        relu_out = last if k == N_FC - 1 else ins[k + 1][:, :FC_WIDTH]
        dz = dd.mul_(relu_out > 0)
        fc_grads[:0] = [_linear(dz.t(), ins[k].t()), dz.sum(0)]
        dd = _linear(dz, pk.fc_w[k][:, : ins[k].shape[1] - N_FEATURES * n].t())
    # the LSTM, backwards through the observations
    dh = dd.t().contiguous()  # (128, B)
    dc: torch.Tensor | None = None  # d loss / d c_t through step t + 1
    g_m1: torch.Tensor | None = None
    g_m2: torch.Tensor | None = None
    m1t, m2t = pk.m1.t().contiguous(), pk.m2.t().contiguous()
    for t in reversed(range(n)):
        qt, (ifg, o, th) = q[t], gates[t]
        i, f, g = ifg[:hs], ifg[hs : 2 * hs], ifg[2 * hs :]
        dz_o = (dh * th).mul_(o - o * o)  # o = sigmoid(z_o), h = o tanh(c_t)
        d_q2 = _linear(m2t, dz_o.t())  # (264, B): h_(t-1); x_t; 1; c_t
        dct = (dh * o).mul_(1.0 - th * th).add_(d_q2[_CT - _H0 :])
        if dc is not None:
            dct.add_(dc)
        dz = q.new_empty(3 * hs, b)  # c_t = f c_(t-1) + i g
        torch.mul(dct * g, i - i * i, out=dz[:hs])
        torch.mul(dct * qt[_C0:_H0], f - f * f, out=dz[hs : 2 * hs])
        torch.mul(dct * i, 1.0 - g * g, out=dz[2 * hs :])
        g_m1 = _linear(dz, qt[:_K], add=g_m1)  # (384, 264)
        g_m2 = _linear(dz_o, qt[_H0:], add=g_m2)  # (128, 264)
        if t:
            d_q1 = _linear(m1t, dz.t())  # (264, B): c_(t-1); h_(t-1); x_t; 1
            dc = dct.mul_(f).add_(d_q1[_C0:_H0])
            dh = d_q1[_H0:_X0].add_(d_q2[: _X0 - _H0])
    if g_m1 is None or g_m2 is None:
        raise DataError("DBox needs at least one observation")
    # unpack M1 = [V; U; W; bias]^T (gates i, f, g) and M2 = [U; W; bias; V]^T (gate o)
    o2 = _H0  # offset of q[t][_H0:] in M2's columns
    g_w = torch.cat([g_m1[:, _X0:_ONE], g_m2[:, _X0 - o2 : _ONE - o2]]).t()
    g_u = torch.cat([g_m1[:, _H0:_X0], g_m2[:, : _X0 - o2]]).t()
    g_b = torch.cat([g_m1[:, _ONE], g_m2[:, _ONE - o2]])
    g_v = torch.cat([g_m1[:, _C0:_H0], g_m2[:, _CT - o2 :]]).t()
    return [g_w, g_u, g_b, g_v, *fc_grads]


class DBoxFunction(torch.autograd.Function):
    """The whole network as one autograd node (gradients for the parameters, not the input)."""

    @staticmethod
    def forward(ctx: Any, x: torch.Tensor, *params: torch.Tensor) -> torch.Tensor:
        """The output (B,) of ``x`` (B, n_obs, 7); ``params``: W, U, bias, V, linears.0.weight ... linears.6.bias."""
        packed = Packed(*params)
        out, saved = forward_pass(x, packed, keep=True)
        ctx.saved = saved
        ctx.packed = packed
        return out

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[torch.Tensor | None, ...]:
        """No gradient for the input; the parameters' from ``grad`` (B,)."""
        grads = backward_pass(grad, ctx.saved, ctx.packed)
        del ctx.saved, ctx.packed
        return (None, *grads)
