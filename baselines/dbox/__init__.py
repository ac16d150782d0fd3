"""DBox (Griffin and Corso, CVPR 2021): an LSTM with peepholes over the observations.

``predict(examples)`` runs the shipped weights (``weights/dbox_p.pt``, trained here by
``odmd-bench train-dbox --config p``); ``predict(examples, weights=FILE)`` runs any
checkpoint in the original release's layout (a state dict with keys ``W``, ``U``,
``bias``, ``V``, ``linears.0.weight`` ... ``linears.6.bias``), such as the release's
``DBox_pretrained_paper.pt``. Files are read with ``torch.load(weights_only=True)``
(no code from a file is run) and checked key by key.

Importing this package does not import torch; the functions do.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DataError

if TYPE_CHECKING:
    from odmd_bench_baselines.dbox.model import DBox

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
#: The shipped weights by training configuration.
SHIPPED = {"p": WEIGHTS_DIR / "dbox_p.pt", "p-z": WEIGHTS_DIR / "dbox_p-z.pt"}
DEFAULT_WEIGHTS = SHIPPED["p"]


def load_model(weights: str | os.PathLike[str] | None = None) -> tuple[DBox, str]:
    """The DBox network with the given weights, and its input formulation.

    Args:
        weights: a checkpoint file in the original key layout; default: the shipped
            ``dbox_p.pt``. The formulation is ``rel`` unless a JSON record beside
            the file (same name, ``.json``) names another (``abs`` for ``--config abs``).

    Returns:
        (model in eval mode on the CPU, formulation).

    Raises:
        DataError: the file is missing, is not a torch checkpoint, or its keys or
            shapes are not the original layout (every difference is named).
    """
    import torch
    from odmd_bench_baselines.dbox.model import DBox

    path = Path(weights) if weights is not None else DEFAULT_WEIGHTS
    if not path.is_file():
        raise DataError(f"DBox weights not found: {path}")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch/pickle raise many kinds for a damaged or foreign file
        raise DataError(
            f"{path} is not a loadable DBox checkpoint (read with weights_only=True): "
            f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
        ) from None
    check_state_dict(state, str(path))
    model = DBox()
    model.load_state_dict({k: v.to(torch.float32) for k, v in state.items()})
    model.eval()
    return model, _formulation(path)


def check_state_dict(state: Any, where: str = "checkpoint") -> None:
    """Raise :class:`DataError` naming every key or shape that is not the original layout."""
    import torch
    from odmd_bench_baselines.dbox.model import checkpoint_shapes

    if not isinstance(state, dict):
        raise DataError(
            f"{where} is not a DBox state dict (got {type(state).__name__}); expected a dict "
            "with keys W, U, bias, V, linears.0.weight ... linears.6.bias"
        )
    expected = checkpoint_shapes()
    problems = []
    missing = [k for k in expected if k not in state]
    unexpected = [str(k) for k in state if k not in expected]
    if missing:
        problems.append(f"missing keys: {', '.join(missing)}")
    if unexpected:
        problems.append(f"unexpected keys: {', '.join(unexpected[:10])}")
    for key, shape in expected.items():
        value = state.get(key)
        if value is None:
            continue
        if not isinstance(value, torch.Tensor):
            problems.append(f"{key}: expected a tensor, got {type(value).__name__}")
        elif tuple(value.shape) != shape:
            problems.append(f"{key}: expected shape {shape}, got {tuple(value.shape)}")
        elif not value.is_floating_point():
            problems.append(f"{key}: expected floating point values, got {value.dtype}")
        elif not bool(torch.isfinite(value).all()):
            problems.append(f"{key}: contains NaN or infinite values")
    if problems:
        raise DataError(f"{where} is not a DBox checkpoint in the original layout", problems)


def _formulation(path: Path) -> str:
    record = path.with_suffix(".json")
    if record.is_file():
        try:
            config = json.loads(record.read_text(encoding="utf-8")).get("config", {})
        except (OSError, ValueError, AttributeError):
            return "rel"
        if isinstance(config, dict) and config.get("formulation") in ("rel", "abs"):
            return str(config["formulation"])
    return "rel"


def predict(
    examples: Examples,
    weights: str | os.PathLike[str] | None = None,
    formulation: str | None = None,
    chunk: int = 4096,
) -> np.ndarray:
    """DBox depth estimates for ``examples``.

    Missing detections are filled with :func:`odmd_bench.fill_missing`; the network
    runs on the CPU in batches of ``chunk`` without gradients.

    Args:
        examples: N examples of 10 observations.
        weights: checkpoint file (default: the shipped ``dbox_p.pt``).
        formulation: ``rel`` or ``abs``; default: from the weights' JSON record,
            else ``rel`` (the original release's checkpoint is f_Rel).
        chunk: examples per forward pass.

    Returns:
        (N,) float64 depth in metres.
    """
    import torch
    from odmd_bench_baselines.dbox.model import N_OBS, predict_depth

    if examples.n_obs != N_OBS:
        raise DataError(f"DBox takes {N_OBS} observations per example, got {examples.n_obs}")
    model, form = load_model(weights)
    if len(examples) == 0:
        return np.zeros(0, dtype=np.float64)
    return predict_depth(model, examples, formulation or form, torch.device("cpu"), chunk)


def predict_report(
    examples: Examples,
    weights: str | os.PathLike[str] | None = None,
    formulation: str | None = None,
) -> tuple[np.ndarray, dict[str, int]]:
    """:func:`predict`, and how many examples had no detection at all.

    Such an example has nothing to fill its boxes from; the network sees the boxes as
    stored (zeros in the original files) and its estimate means little. It is still
    estimated, as the original release did, and counted here as ``no_detection``.
    """
    depths = predict(examples, weights=weights, formulation=formulation)
    return depths, {"n": len(examples), "no_detection": int((~examples.detected.any(axis=1)).sum())}


__all__ = ["DEFAULT_WEIGHTS", "SHIPPED", "check_state_dict", "load_model", "predict", "predict_report"]
