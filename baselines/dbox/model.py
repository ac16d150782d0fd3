"""The DBox network (Griffin and Corso, CVPR 2021, section 3.2).

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

:class:`DBox` computes exactly that with the hand-written passes of :mod:`.kernels`;
their speed against the original release's formulation, by CPU, is in ``docs/dbox.md``
and ``benchmarks/results/``. :func:`reference_forward` is the original's straightforward
per-gate version, kept for tests and benchmarks and used for an input that needs a
gradient itself. The input formulations are :mod:`.formulations`.

This module imports torch; ``import odmd_bench`` never does.
"""

from __future__ import annotations

import math

import torch
from odmd_bench_baselines.dbox.configs import FC_WIDTH, HIDDEN, N_FC, N_FEATURES, OBSERVATIONS
from odmd_bench_baselines.dbox.kernels import DBoxFunction, Packed, forward_pass
from torch import nn

N_OBS = OBSERVATIONS  # the network's observations per example (declared by the package)

__all__ = [
    "DBox",
    "FC_WIDTH",
    "HIDDEN",
    "N_FC",
    "N_FEATURES",
    "N_OBS",
    "checkpoint_shapes",
    "reference_forward",
]


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
            x: (B, n_obs, 7), from :func:`.formulations.make_inputs` (float32; float64 works too).

        Returns:
            (B,) the network output (relative or absolute depth by formulation).
        """
        params = (self.W, self.U, self.bias, self.V, *self.fc_parameters())
        if torch.is_grad_enabled():
            if x.requires_grad:  # the hand-written backward gives parameter gradients only
                return reference_forward(self, x)
            if any(p.requires_grad for p in params):
                out: torch.Tensor = DBoxFunction.apply(x, *params)
                return out
        return forward_pass(x, Packed(*params), keep=False)[0]

    def fc_parameters(self) -> list[torch.Tensor]:
        """``linears.0.weight``, ``linears.0.bias``, ... ``linears.6.bias``."""
        return [t for layer in self.fc_layers() for t in (layer.weight, layer.bias)]


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
