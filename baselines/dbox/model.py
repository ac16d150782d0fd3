"""The DBox network (Griffin and Corso, CVPR 2021, section 3.2) and its input formulations.

The parameter layout is the original release's, so that its checkpoints load unchanged:
``W`` (7, 512), ``U`` (128, 512), ``bias`` (512,), ``V`` (128, 512) with the gate
order input, forget, cell, output, then ``linears.0`` (256, 198), ``linears.1`` ...
``linears.5`` (256, 326) and ``linears.6`` (1, 256).

Per observation ``t`` (``h`` and ``c`` start at zero)::

    g = x_t W + h U + bias                       (B, 512)
    i, f = sigmoid(g_i + c V_i), sigmoid(g_f + c V_f)
    c' = f * c + i * tanh(g_c + c V_c)
    o = sigmoid(g_o + c' V_o)                     (peephole on the new cell)
    h' = o * tanh(c')

then ``d = h``; six times ``d = relu(linears.k([d, X]))`` with ``X`` the whole input
flattened observation by observation (70 numbers); the output is ``linears.6(d)``.

The implementation computes exactly that, with a hand-written backward pass and
every matrix product in one call of a float32 kernel: plain torch products, or oneDNN's
where ``ODMD_BENCH_ONEDNN=1`` asks for it (see :func:`use_onednn`). Its speed against the original release's formulation, by CPU, is
in ``docs/dbox.md`` and ``benchmarks/results/``. :func:`reference_forward` is the
original's straightforward per-gate version, kept for tests and benchmarks and used for
an input that needs a gradient itself.

This module imports torch; ``import odmd_bench`` never does.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from odmd_bench_baselines.dbox.configs import OBSERVATIONS
from torch import nn

from odmd_bench import DataError, Examples, UsageError, fill_missing

#: Numbers per observation: x, y, w, h, dcx, dcy, dcz.
N_FEATURES = 7
HIDDEN = 128
FC_WIDTH = 256
N_FC = 6
N_OBS = OBSERVATIONS  # the network's observations per example (declared by the package)

FORMULATIONS = ("rel", "abs")


class DBox(nn.Module):
    """The DBox network in the original release's parameter layout.

    Args:
        n_obs: observations per example (10 for ODMD; fixes the FC input sizes).
        generator: optional torch generator for the initial weights (the original's
            init: LSTM parameters uniform in +-1/sqrt(128), linear layers PyTorch's
            default).
    """

    def __init__(self, n_obs: int = N_OBS, generator: torch.Generator | None = None) -> None:
        super().__init__()
        self.n_obs = n_obs
        cat = n_obs * N_FEATURES
        self.W = nn.Parameter(torch.empty(N_FEATURES, 4 * HIDDEN))
        self.U = nn.Parameter(torch.empty(HIDDEN, 4 * HIDDEN))
        self.bias = nn.Parameter(torch.empty(4 * HIDDEN))
        self.V = nn.Parameter(torch.empty(HIDDEN, 4 * HIDDEN))
        sizes = [HIDDEN + cat] + [FC_WIDTH + cat] * (N_FC - 1)
        layers = [nn.Linear(s, FC_WIDTH) for s in sizes] + [nn.Linear(FC_WIDTH, 1)]
        self.linears = nn.ModuleList(layers)
        self.reset_parameters(generator)

    def reset_parameters(self, generator: torch.Generator | None = None) -> None:
        """The original release's initialisation, drawn from ``generator``."""
        with torch.no_grad():
            stdv = 1.0 / math.sqrt(HIDDEN)
            for p in (self.W, self.U, self.bias, self.V):
                p.uniform_(-stdv, stdv, generator=generator)
            for layer in self.fc_layers():
                bound = 1.0 / math.sqrt(layer.in_features)
                # PyTorch's default Linear init (kaiming_uniform with a = sqrt(5)) is
                # uniform in +-1/sqrt(fan_in) for both weight and bias.
                layer.weight.uniform_(-bound, bound, generator=generator)
                layer.bias.uniform_(-bound, bound, generator=generator)

    def fc_layers(self) -> list[nn.Linear]:
        """``linears.0`` ... ``linears.6``."""
        return [layer for layer in self.linears if isinstance(layer, nn.Linear)]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Predict from normalised inputs.

        Args:
            x: (B, n_obs, 7), from :func:`make_inputs` (float32; float64 works too).

        Returns:
            (B,) the network output (relative or absolute depth by formulation).
        """
        params = (self.W, self.U, self.bias, self.V, *self.fc_parameters())
        if torch.is_grad_enabled():
            if x.requires_grad:  # the hand-written backward gives parameter gradients only
                return reference_forward(self, x)
            if any(p.requires_grad for p in params):
                out: torch.Tensor = _DBoxFunction.apply(x, *params)
                return out
        return _forward(x, _Packed(*params), keep=False)[0]

    def fc_parameters(self) -> list[torch.Tensor]:
        """``linears.0.weight``, ``linears.0.bias``, ... ``linears.6.bias``."""
        return [t for layer in self.fc_layers() for t in (layer.weight, layer.bias)]


# --- the fast implementation -------------------------------------------------------------
#
# Forward and backward are written out by hand (one autograd node for the whole network)
# so that every matrix product is one call and nothing is computed twice. On a float32 CPU
# tensor the products run either on oneDNN's matmul (``mkldnn._linear_pointwise``, which
# PyTorch's own compiler emits; it applies the gate sigmoid inside the product) or on
# plain torch products (MKL's SGEMM behind ``torch.addmm``). Which is faster depends on
# the CPU: oneDNN was faster on one AMD EPYC, slower on another and on an Intel Xeon
# (AVX-512, AMX). The kernel is never chosen by timing: a timed choice flips on a busy
# machine, and the two kernels differ at float32 rounding, so two runs of one command
# would train different weights. Plain products unless ``ODMD_BENCH_ONEDNN=1``; elsewhere
# (float64, CUDA, builds without oneDNN) the code runs on plain torch products.
#
# The LSTM runs feature-major, one contiguous (features, B) block per observation:
#
#     q[t] = [c_(t-1); h_(t-1); x_t; 1; c_t]                      (392, B)
#     sigmoid([i; f; 2 g]) = sigmoid(M1 @ q[t][:264])              M1 = [V; U; W; bias]^T of i, f, g
#     o = sigmoid(M2 @ q[t][128:])                                 M2 = [U; W; bias; V]^T of o
#
# so the input product, the bias and both peepholes are one product per gate group, every
# operand is read in the layout the kernel wants, and the weight gradients of a step are
# one product each, accumulated in place. tanh(z) is computed as 2 sigmoid(2z) - 1 (the
# factor 2 of the g rows sits in M1): three times faster than torch.tanh on AMD here.

_C0, _H0, _X0 = 0, HIDDEN, 2 * HIDDEN  # rows of c_(t-1), h_(t-1), x_t in q[t]
_ONE = _X0 + N_FEATURES  # the row of ones
_K = _ONE + 1  # 264: rows read by each gate group
_CT = _K  # rows of c_t
_Q = _CT + HIDDEN  # 392


#: Values of ``ODMD_BENCH_ONEDNN``: ``auto`` (the default: plain torch products), ``1``
#: (oneDNN where available), ``0`` (plain torch products).
KERNEL_SETTINGS = ("auto", "1", "0")
_forced: str | None = None  # set by kernels()


@functools.cache
def onednn_available() -> bool:
    """Whether oneDNN's fp32 matmul works in this torch build."""
    if not torch.backends.mkldnn.is_available():
        return False
    try:
        a = torch.arange(6.0).view(2, 3)
        w = torch.arange(12.0).view(4, 3)
        got = torch.ops.mkldnn._linear_pointwise(a, w, None, "none", [], "")
    except (AttributeError, RuntimeError, NotImplementedError):
        return False
    return bool(torch.equal(got, a @ w.t()))


def use_onednn(train: bool) -> bool:
    """Whether float32 CPU products run on oneDNN (else plain torch products).

    The rule: ``ODMD_BENCH_ONEDNN=1`` oneDNN (where it works); unset, ``auto`` or ``0``:
    plain products, for training and inference alike. Nothing here depends on a timing or
    on the machine's load, so a run's weights and predictions depend only on its command,
    the package and the kind of CPU. (An earlier rule timed both kernels on the first
    training step and kept the faster: on a busy machine the choice flipped from run to
    run, and so did the weights.) Both kernels give the same numbers to float32 rounding;
    ``train`` is kept for callers that ask per use.

    Raises:
        UsageError: ``ODMD_BENCH_ONEDNN`` has another value.
    """
    del train  # the same rule for training and inference
    setting = _forced or os.environ.get("ODMD_BENCH_ONEDNN", "auto") or "auto"
    if setting not in KERNEL_SETTINGS:
        raise UsageError(f"ODMD_BENCH_ONEDNN={setting!r}: expected one of {', '.join(KERNEL_SETTINGS)}")
    return setting == "1" and onednn_available()


@contextlib.contextmanager
def kernels(setting: str) -> Iterator[None]:
    """Run the block with ``ODMD_BENCH_ONEDNN`` set to ``setting`` (for tests and benchmarks)."""
    global _forced
    if setting not in KERNEL_SETTINGS:
        raise UsageError(f"unknown kernel setting {setting!r}; expected one of {', '.join(KERNEL_SETTINGS)}")
    before, _forced = _forced, setting
    try:
        yield
    finally:
        _forced = before


def _fast(x: torch.Tensor, train: bool) -> bool:
    return x.device.type == "cpu" and x.dtype == torch.float32 and use_onednn(train)


def _linear(
    x: torch.Tensor,
    w: torch.Tensor,
    bias: torch.Tensor | None = None,
    add: torch.Tensor | None = None,
    act: str = "none",
    fast: bool = False,
) -> torch.Tensor:
    """``act(x @ w.T + bias + add)``: one product with its epilogue.

    x (M, K), w (N, K), bias (N,), add (M, N); ``act`` is ``none``, ``relu`` or ``sigmoid`` (not with ``add``); ``fast``: on
    oneDNN's kernel (a float32 CPU tensor, oneDNN available).
    """
    if fast:
        # oneDNN reads a row-major block or a whole transposed matrix in place, but takes
        # its reference loop (about 1000x slower) for a transposed block: copy that one.
        x, w = (t if t.stride(-1) == 1 or t.t().is_contiguous() else t.contiguous() for t in (x, w))
        op = torch.ops.mkldnn._linear_pointwise
        if add is None:
            return op(x, w, bias, act, [], "")
        return op.binary(x, add, w, bias, "add")
    out = x @ w.t() if add is None else torch.addmm(add, x, w.t())
    if bias is not None:
        out = out + bias
    if act == "relu":
        return torch.relu_(out)
    return torch.sigmoid_(out) if act == "sigmoid" else out


def _tanh_from_sigmoid_(s: torch.Tensor) -> torch.Tensor:
    """tanh(z) in place of s = sigmoid(2 z)."""
    return s.mul_(2.0).sub_(1.0)


class _Packed:
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


def _forward(
    x: torch.Tensor, pk: _Packed, keep: bool, fast: bool | None = None
) -> tuple[torch.Tensor, dict[str, Any]]:
    """The network's output (B,) and, if ``keep``, what the backward pass needs.

    ``fast``: run the products on oneDNN (default: :func:`use_onednn` decides).
    """
    if fast is None:
        fast = _fast(x, train=keep)
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
        ifg = _linear(pk.m1_fwd, qt[:_K].t(), act="sigmoid", fast=fast)
        i, f, g = ifg[:hs], ifg[hs : 2 * hs], _tanh_from_sigmoid_(ifg[2 * hs :])
        c = torch.mul(i, g, out=qt[_CT:])
        if t:
            c.addcmul_(f, qt[_C0:_H0])
        o = _linear(pk.m2, qt[_H0:].t(), act="sigmoid", fast=fast)
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
        d = _linear(inp, pk.fc_w[k], pk.fc_b[k], act="relu", fast=fast)
    out = _linear(d, pk.fc_w[N_FC], pk.fc_b[N_FC], fast=fast).view(b)
    saved = {"q": q, "gates": gates, "ins": ins, "last": d} if keep else {}
    return out, saved


def _backward(
    grad: torch.Tensor, saved: dict[str, Any], pk: _Packed, fast: bool | None = None
) -> list[torch.Tensor]:
    """Gradients of W, U, bias, V, linears.0.weight ... linears.6.bias from d loss / d out (B,)."""
    q, gates, ins, last = saved["q"], saved["gates"], saved["ins"], saved["last"]
    if fast is None:
        fast = _fast(q, train=True)
    n, _, b = q.shape
    hs = HIDDEN
    # the fully connected head, row-major as the original
    g_out = grad.reshape(b, 1)
    fc_grads = [_linear(g_out.t(), last.t(), fast=fast), g_out.sum(0)]  # linears.6
    dd = g_out * pk.fc_w[N_FC]  # (B, 256)
    for k in reversed(range(N_FC)):
        relu_out = last if k == N_FC - 1 else ins[k + 1][:, :FC_WIDTH]
        dz = dd.mul_(relu_out > 0)
        fc_grads[:0] = [_linear(dz.t(), ins[k].t(), fast=fast), dz.sum(0)]
        dd = _linear(dz, pk.fc_w[k][:, : ins[k].shape[1] - N_FEATURES * n].t(), fast=fast)
    # the LSTM, backwards through the observations
    dh = dd.t().contiguous()  # (128, B)
    dc: torch.Tensor | None = None  # d loss / d c_t through step t + 1
    g_m1: torch.Tensor | None = None
    g_m2: torch.Tensor | None = None
    m1t, m2t = pk.m1.t().contiguous(), pk.m2.t().contiguous()  # oneDNN wants x contiguous
    for t in reversed(range(n)):
        qt, (ifg, o, th) = q[t], gates[t]
        i, f, g = ifg[:hs], ifg[hs : 2 * hs], ifg[2 * hs :]
        dz_o = (dh * th).mul_(o - o * o)  # o = sigmoid(z_o), h = o tanh(c_t)
        d_q2 = _linear(m2t, dz_o.t(), fast=fast)  # (264, B): h_(t-1); x_t; 1; c_t
        dct = (dh * o).mul_(1.0 - th * th).add_(d_q2[_CT - _H0 :])
        if dc is not None:
            dct.add_(dc)
        dz = q.new_empty(3 * hs, b)  # c_t = f c_(t-1) + i g
        torch.mul(dct * g, i - i * i, out=dz[:hs])
        torch.mul(dct * qt[_C0:_H0], f - f * f, out=dz[hs : 2 * hs])
        torch.mul(dct * i, 1.0 - g * g, out=dz[2 * hs :])
        g_m1 = _linear(dz, qt[:_K], add=g_m1, fast=fast)  # (384, 264)
        g_m2 = _linear(dz_o, qt[_H0:], add=g_m2, fast=fast)  # (128, 264)
        if t:
            d_q1 = _linear(m1t, dz.t(), fast=fast)  # (264, B): c_(t-1); h_(t-1); x_t; 1
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


class _DBoxFunction(torch.autograd.Function):
    """The whole network as one autograd node (gradients for the parameters, not the input)."""

    @staticmethod
    def forward(ctx: Any, x: torch.Tensor, *params: torch.Tensor) -> torch.Tensor:
        packed = _Packed(*params)
        ctx.fast = _fast(x, train=True)
        out, saved = _forward(x, packed, keep=True, fast=ctx.fast)
        ctx.saved = saved
        ctx.packed = packed
        return out

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[torch.Tensor | None, ...]:
        grads = _backward(grad, ctx.saved, ctx.packed, fast=ctx.fast)
        del ctx.saved, ctx.packed
        return (None, *grads)


def reference_forward(model: DBox, x: torch.Tensor) -> torch.Tensor:
    """The original release's forward pass, written as it was (for tests and benchmarks).

    Args:
        model: a :class:`DBox`.
        x: (B, n_obs, 7) float32.

    Returns:
        (B,) the network output.
    """
    b, n, _ = x.shape
    hs = HIDDEN
    h = torch.zeros(b, hs, dtype=x.dtype, device=x.device)
    c = torch.zeros(b, hs, dtype=x.dtype, device=x.device)
    for t in range(n):
        x_t = x[:, t, :]
        gates = x_t @ model.W + h @ model.U + model.bias + c @ model.V
        i = torch.sigmoid(gates[:, :hs])
        f = torch.sigmoid(gates[:, hs : 2 * hs])
        g = torch.tanh(gates[:, 2 * hs : 3 * hs])
        c = f * c + i * g
        gates = x_t @ model.W + h @ model.U + model.bias + c @ model.V
        o = torch.sigmoid(gates[:, 3 * hs :])
        h = o * torch.tanh(c)
    x_cat = x.reshape(b, n * N_FEATURES)
    d = h
    fc = model.fc_layers()
    for layer in fc[:-1]:
        d = torch.relu(layer(torch.cat((d, x_cat), 1)))
    return fc[-1](d).view(b)


@dataclass(frozen=True)
class Inputs:
    """Network inputs for a batch of examples.

    Attributes:
        x: (N, n_obs, 7) float32 network input.
        scale: (N,) float64: the network output times ``scale`` is the depth in
            metres (L = |c_1 - c_n| for ``rel``, 1 for ``abs``).
        target: (N,) float32 training target (``depth / scale``).
    """

    x: np.ndarray
    scale: np.ndarray
    target: np.ndarray


def make_inputs(examples: Examples, formulation: str = "rel") -> Inputs:
    """Turn examples into DBox's normalised input, as the original release did.

    Missing detections are first filled with the shared rule
    (:func:`odmd_bench.fill_missing`). Boxes stay as stored. For ``rel`` (f_Rel) the
    camera positions (relative to the last observation) are divided by
    ``L = |c_1 - c_n|`` and turned into increments ``c_i - c_(i-1)`` (first
    increment 0); the target is ``Z_n / L``. For ``abs`` (f_Abs) the positions are
    used as they are and the target is ``Z_n``. Arithmetic in float32, as the
    original.

    Args:
        examples: N examples.
        formulation: ``"rel"`` or ``"abs"``.

    Returns:
        :class:`Inputs`.

    Raises:
        DataError: for ``rel``, when an example's first camera position equals the
            last (L = 0: depth is not defined relative to the motion).
    """
    if formulation not in FORMULATIONS:
        raise DataError(
            f"unknown DBox formulation {formulation!r}; expected one of {', '.join(FORMULATIONS)}"
        )
    boxes = fill_missing(examples.boxes, examples.detected).astype(np.float32)
    cam = examples.camera.astype(np.float32)
    n = len(examples)
    x = np.empty((n, examples.n_obs, N_FEATURES), dtype=np.float32)
    x[:, :, :4] = boxes
    if formulation == "rel":
        norm = np.linalg.norm(cam[:, 0], axis=1)
        bad = np.flatnonzero(~(norm > 0) | ~np.isfinite(norm))
        if bad.size:
            raise DataError(
                "DBox (f_Rel) needs camera motion: the first camera position equals the "
                f"last (or is not finite) in {bad.size} example(s)",
                [f"example indices (first 10): {bad[:10].tolist()}"],
            )
        rel = cam / norm[:, None, None]
        x[:, 0, 4:] = 0.0
        x[:, 1:, 4:] = np.diff(rel, axis=1)
        scale = norm.astype(np.float64)
    else:
        x[:, :, 4:] = cam
        scale = np.ones(n, dtype=np.float64)
    target = (examples.depth.astype(np.float32) / scale.astype(np.float32)).astype(np.float32)
    return Inputs(x=x, scale=scale, target=target)


def predict_depth(
    model: DBox, examples: Examples, formulation: str, device: torch.device, chunk: int = 4096
) -> np.ndarray:
    """Depth in metres (N,) float64 for ``examples``, in chunks, without gradients."""
    inp = make_inputs(examples, formulation)
    out = np.empty(len(examples), dtype=np.float64)
    was_training = model.training
    model.eval()
    with torch.no_grad():
        for start in range(0, len(examples), chunk):
            x = torch.from_numpy(inp.x[start : start + chunk]).to(device)
            out[start : start + chunk] = model(x).double().cpu().numpy()
    model.train(was_training)
    return out * inp.scale


def checkpoint_shapes(n_obs: int = N_OBS) -> dict[str, tuple[int, ...]]:
    """The original release's state-dict keys and their shapes."""
    cat = n_obs * N_FEATURES
    shapes: dict[str, tuple[int, ...]] = {
        "W": (N_FEATURES, 4 * HIDDEN),
        "U": (HIDDEN, 4 * HIDDEN),
        "bias": (4 * HIDDEN,),
        "V": (HIDDEN, 4 * HIDDEN),
    }
    for k in range(N_FC):
        shapes[f"linears.{k}.weight"] = (FC_WIDTH, (HIDDEN if k == 0 else FC_WIDTH) + cat)
        shapes[f"linears.{k}.bias"] = (FC_WIDTH,)
    shapes[f"linears.{N_FC}.weight"] = (1, FC_WIDTH)
    shapes[f"linears.{N_FC}.bias"] = (1,)
    return shapes
