"""Reading a verified DBox checkpoint into the network.

The bytes verified by :func:`.weights.verify_weights` are read with
``torch.load(weights_only=True)`` (no code from a file is run), checked key by key
against the original release's layout, and the checkpoint's input formulation is read
from its configuration or its record. Nothing here imports torch at import time;
loading does.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from odmd_bench_baselines.dbox.configs import CONFIGS as TRAIN_CONFIGS
from odmd_bench_baselines.dbox.weights import DEFAULT_WEIGHTS, shipped_config, verify_weights

from odmd_bench import MAX_ABS_WEIGHT, DataError

if TYPE_CHECKING:
    from odmd_bench_baselines.dbox.model import DBox


def load_model(
    weights: str | os.PathLike[str] | None = None,
    weights_sha256: str | None = None,
    require_record: bool = False,
) -> tuple[DBox, str]:
    """The DBox network with the given weights, and its input formulation.

    Args:
        weights: a checkpoint file in the original key layout; default: the shipped
            ``dbox_p.pt`` (whose record is then required). The formulation is ``rel``
            unless a JSON record beside the file (same name, ``.json``) names another.
        weights_sha256: expected hash of the file (see :func:`verify_weights`).
        require_record: refuse a file without a record to check it against.

    Returns:
        (model in eval mode on the CPU, formulation).

    Raises:
        DataError: the file is missing, fails its hash check, is not a torch checkpoint,
            or its keys or shapes are not the original layout (every difference is named).
    """
    model, form, _ = _load(weights, weights_sha256, require_record or weights is None)
    return model, form


def _load(
    weights: str | os.PathLike[str] | None,
    weights_sha256: str | None,
    require_record: bool,
    keep: bool = False,
) -> tuple[DBox, str, str]:
    """(network, formulation, SHA-256); ``keep``: reuse and keep the network (for prediction only)."""
    import torch
    from odmd_bench_baselines.dbox.model import DBox

    path = Path(weights) if weights is not None else DEFAULT_WEIGHTS
    data, sha = verify_weights(path, weights_sha256, require_record)
    model = _LOADED.get(sha) if keep else None
    if model is None:
        try:
            state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
        except Exception as e:  # torch/pickle raise many kinds for a damaged or foreign file
            raise DataError(
                f"{path} is not a loadable DBox checkpoint (read with weights_only=True): {load_failure(e)}"
            ) from None
        check_state_dict(state, str(path))
        model = DBox()
        model.load_state_dict({k: v.to(torch.float32) for k, v in state.items()})
        model.eval()
        if keep:
            # For prediction only (which never changes a network): kept by the SHA-256 of
            # the bytes just verified (always read and hashed again), so that runs of one
            # checkpoint on several sets or entries (leaderboard audit) build it once.
            while len(_LOADED) >= _KEEP_LOADED:
                _LOADED.pop(next(iter(_LOADED)))
            _LOADED[sha] = model
    return model, _formulation(path, sha), sha


#: Built networks by checkpoint SHA-256 (at most ``_KEEP_LOADED``, the oldest dropped first).
_LOADED: dict[str, DBox] = {}
_KEEP_LOADED = 8


def load_failure(e: BaseException) -> str:
    """Why ``torch.load(..., weights_only=True)`` failed, in one line.

    torch's own text advises loading again with ``weights_only=False``, which runs any
    code the file holds; it is replaced by what it means.
    """
    text = str(e).strip()
    if "Weights only load failed" in text:
        return "it holds Python objects besides tensors, which a safe load refuses (a DBox checkpoint holds tensors only)"
    first = text.splitlines()[0][:200] if text else "the file ends early or is empty"
    return f"{type(e).__name__}: {first}"


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
        elif value.numel() and float(value.abs().max()) > MAX_ABS_WEIGHT:
            problems.append(
                f"{key}: holds values up to {float(value.abs().max()):.3g}, beyond {MAX_ABS_WEIGHT:g} "
                "(the bound on a weight; trained DBox weights stay below 10)"
            )
    if problems:
        raise DataError(f"{where} is not a DBox checkpoint in the original layout", problems)


def _formulation(path: Path, sha: str) -> str:
    """The input formulation of the checkpoint at ``path`` (SHA-256 ``sha``).

    A shipped checkpoint's comes from its configuration, named by its file name, never
    from its record alone; a copy of one, found by its hash, likewise. Any other's comes
    from the record beside it, which must name a formulation its configuration trains;
    without a record it is ``rel`` (the original release's checkpoint is f_Rel).

    Raises:
        DataError: a record that names no valid formulation, or one that disagrees with
            its configuration or with the shipped file's.
    """
    from odmd_bench_baselines.dbox.formulations import FORMULATIONS

    shipped = shipped_config(path, sha)
    record = path.with_suffix(".json")
    named = None
    if record.is_file():
        try:
            config = json.loads(record.read_text(encoding="utf-8")).get("config")
        except (OSError, ValueError, AttributeError) as e:
            raise DataError(f"cannot read the record {record}: {type(e).__name__}") from None
        named = config.get("formulation") if isinstance(config, dict) else None
        name = config.get("name") if isinstance(config, dict) else None
        problems = []
        if named not in FORMULATIONS:
            problems.append(f"config.formulation is {named!r}, not one of {', '.join(FORMULATIONS)}")
        elif name in TRAIN_CONFIGS and TRAIN_CONFIGS[name].formulation != named:
            problems.append(
                f"configuration {name} trains formulation {TRAIN_CONFIGS[name].formulation}, not {named}"
            )
        elif shipped is not None and TRAIN_CONFIGS[shipped].formulation != named:
            problems.append(
                f"these are the shipped {shipped} weights, of formulation {TRAIN_CONFIGS[shipped].formulation}"
            )
        if problems:
            raise DataError(
                f"the record {record} does not fit its weights; restore it or reinstall odmd-bench", problems
            )
    if shipped is not None:
        return TRAIN_CONFIGS[shipped].formulation
    return str(named) if named is not None else "rel"
