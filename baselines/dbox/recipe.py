"""DBox's training recipe: the learning-rate schedule, the optimizer, a step's forward pass, batches, val scores.

The paper's recipe (L1 loss on the formulation's target, Adam, learning rate 1e-3,
batches of 512 new examples per step) and the cosine schedule this package adds; the
pieces the training loop (:mod:`.loop`) and the run selection (:mod:`.select`) share.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import torch
from odmd_bench_baselines.dbox.formulations import make_inputs, predict_depth
from odmd_bench_baselines.dbox.model import DBox, reference_forward

from odmd_bench import Examples

BATCH_SIZE = 512
LEARNING_RATE = 1e-3
SCHEDULES = ("cosine", "constant")
#: ``fp32``: float32 throughout; ``bf16``: the forward pass under automatic mixed
#: precision (bfloat16 products), the loss, gradients, Adam and validation in float32.
PRECISIONS = ("fp32", "bf16")


def learning_rate(
    step: int, steps: int, schedule: str, min_lr_ratio: float, peak: float = LEARNING_RATE
) -> float:
    """The learning rate for step ``step`` (0-based) of ``steps``.

    ``cosine``: from ``peak`` (1e-3) down to ``peak * min_lr_ratio`` at the last step;
    ``constant``: ``peak`` throughout (the paper).
    """
    if schedule == "constant":
        return peak
    frac = min(step / max(steps - 1, 1), 1.0)
    low = peak * min_lr_ratio
    return low + 0.5 * (peak - low) * (1.0 + math.cos(math.pi * frac))


def make_optimizer(model: torch.nn.Module, lr: float = LEARNING_RATE) -> torch.optim.Adam:
    """The paper's optimizer, Adam, in PyTorch's fused implementation.

    One kernel for all parameters: the same update rule, equal to rounding, in a third of the time of the
    per-parameter loop on a CPU.
    """
    return torch.optim.Adam(model.parameters(), lr=lr, fused=True)


class TrainStep(torch.nn.Module):
    """The network's training forward pass, in the run's precision (what DDP wraps).

    ``bf16`` runs the original formulation (:func:`reference_forward`: autograd through
    plain torch operations, which autocast casts) under autocast; ``fp32`` the model
    itself, the same arithmetic as a one-process run without this wrapper.
    """

    def __init__(self, model: DBox, precision: str) -> None:
        super().__init__()
        self.model = model
        self.precision = precision

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The network output (B,) for ``x`` (B, n_obs, 7), float32."""
        if self.precision == "bf16":
            with torch.autocast(x.device.type, dtype=torch.bfloat16):
                return reference_forward(self.model, x).float()
        out: torch.Tensor = self.model(x)
        return out


def batch_tensors(
    examples: Examples, formulation: str, device: torch.device, rows: slice = slice(None)
) -> tuple[torch.Tensor, torch.Tensor, np.ndarray]:
    """Network input (B, n_obs, 7), target (B,) on ``device``, and scale (B,) float64.

    ``rows``: the rows of the batch this process trains on (all by default).
    """
    inp = make_inputs(examples, formulation)
    x = torch.from_numpy(inp.x[rows]).to(device, non_blocking=True)
    y = torch.from_numpy(inp.target[rows]).to(device, non_blocking=True)
    return x, y, inp.scale[rows]


def validation_scores(
    model: DBox, val_sets: Mapping[str, Examples], formulation: str, device: torch.device
) -> dict[str, float]:
    """Mean percent error per set, and ``all``: the mean of the sets' means."""
    scores: dict[str, float] = {}
    for name, ex in val_sets.items():
        pred = predict_depth(model, ex, formulation, device)
        scores[name] = float(np.mean(np.abs(ex.depth - pred) / ex.depth * 100.0))
    scores["all"] = float(np.mean([scores[n] for n in val_sets]))
    return scores
