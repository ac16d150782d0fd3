"""DBox's input formulations: examples into the network's input, and its output into depth.

f_Rel (``rel``) normalises the camera motion by its length and predicts depth relative
to it; f_Abs (``abs``) predicts depth in metres from the positions as they are (the
paper's section 3.2, as the original release computes them, in float32).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from odmd_bench_baselines.dbox.configs import N_FEATURES
from odmd_bench_baselines.dbox.model import DBox

from odmd_bench import DataError, Examples, fill_missing

FORMULATIONS = ("rel", "abs")


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
