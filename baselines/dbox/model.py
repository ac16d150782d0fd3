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

The implementation computes exactly that with fewer operations than the original
release: ``x W + bias`` for all observations in one matrix product, the peephole of
the input, forget and cell gates and that of the output gate as two products with
the two column blocks of ``V`` (the original computes all four gate blocks twice),
and ``[d, X] A^T`` as ``d A_d^T + X A_X^T`` with the six ``X A_X^T`` in one product.
:func:`reference_forward` is the straightforward per-gate version, kept for tests and
benchmarks.

This module imports torch; ``import odmd_bench`` never does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from odmd_bench.errors import DataError
from odmd_bench.examples import Examples, fill_missing

#: Numbers per observation: x, y, w, h, dcx, dcy, dcz.
N_FEATURES = 7
HIDDEN = 128
FC_WIDTH = 256
N_FC = 6
N_OBS = 10

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
            x: (B, n_obs, 7) float32, from :func:`make_inputs`.

        Returns:
            (B,) the network output (relative or absolute depth by formulation).
        """
        b, n, _ = x.shape
        h4 = 4 * HIDDEN
        xw = torch.addmm(self.bias, x.transpose(0, 1).reshape(n * b, N_FEATURES), self.W)
        h = _lstm(xw.view(n, b, h4), self.U, self.V)
        flat = x.reshape(b, n * N_FEATURES)
        fc = self.fc_layers()
        # [d, X] A^T = d A_d^T + X A_X^T, with the six X A_X^T in one matrix product.
        cat = n * N_FEATURES
        w_d = [layer.weight[:, : layer.in_features - cat] for layer in fc[:N_FC]]
        w_x = torch.cat([layer.weight[:, layer.in_features - cat :] for layer in fc[:N_FC]], 0)
        b_all = torch.cat([layer.bias for layer in fc[:N_FC]])
        xparts = torch.addmm(b_all, flat, w_x.t()).split(FC_WIDTH, dim=1)
        d = h
        for k in range(N_FC):
            d = torch.relu(torch.addmm(xparts[k], d, w_d[k].t()))
        out = fc[N_FC](d)
        return out.view(b)


def _tanh(x: torch.Tensor) -> torch.Tensor:
    # tanh(x) = 2 sigmoid(2x) - 1: the same function, three times faster than
    # torch.tanh on this class of CPU (MKL's tanh takes a slow path on AMD).
    return torch.sigmoid(2.0 * x).mul(2.0).sub(1.0)


def _lstm(xw: torch.Tensor, u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """The peephole LSTM over all observations; returns the final ``h``.

    Args:
        xw: (n, B, 512) ``x W + bias`` per observation.
        u: (128, 512) ``U``.
        v: (128, 512) ``V``.

    Returns:
        (B, 128) the hidden state after the last observation.
    """
    h3 = 3 * HIDDEN
    # unbind and split (not indexing) keep the backward pass free of zero-filled
    # full-size gradient buffers.
    v_ifc, v_o = v.split([h3, HIDDEN], dim=1)
    h = c = None
    for xw_t in xw.unbind(0):
        if h is not None and c is not None:
            g_ifc, g_o = torch.addmm(xw_t, h, u).split([h3, HIDDEN], dim=1)
            ifc = torch.addmm(g_ifc, c, v_ifc)
        else:
            ifc, g_o = xw_t.split([h3, HIDDEN], dim=1)
        i_f, cand = ifc.split([2 * HIDDEN, HIDDEN], dim=1)
        i, f = torch.sigmoid(i_f).chunk(2, dim=1)
        ic = i * _tanh(cand)
        c = ic if c is None else torch.addcmul(ic, f, c)
        o = torch.sigmoid(torch.addmm(g_o, c, v_o))
        h = o * _tanh(c)
    if h is None:
        raise DataError("DBox needs at least one observation")
    return h


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
    h = torch.zeros(b, hs, dtype=x.dtype)
    c = torch.zeros(b, hs, dtype=x.dtype)
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
