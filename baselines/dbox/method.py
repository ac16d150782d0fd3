"""DBox's method interface: ``predict``, ``predict_report`` and ``provenance``."""

from __future__ import annotations

import os

import numpy as np
from odmd_bench_baselines.dbox.weights import OBSERVATIONS, _load, resolve_weights, verify_weights

from odmd_bench import DataError, Examples


def predict(
    examples: Examples,
    weights: str | os.PathLike[str] | None = None,
    formulation: str | None = None,
    chunk: int = 4096,
    config: str | None = None,
    selection: str = "overall",
    weights_sha256: str | None = None,
) -> np.ndarray:
    """DBox depth estimates for ``examples``.

    Missing detections are filled with :func:`odmd_bench.fill_missing`; the network
    runs on the CPU in batches of ``chunk`` without gradients.

    Args:
        examples: N examples of :data:`OBSERVATIONS` observations.
        weights: a checkpoint file (instead of ``config``).
        formulation: ``rel`` or ``abs``; default: from the weights' JSON record,
            else ``rel`` (the original release's checkpoint is f_Rel).
        chunk: examples per forward pass.
        config: shipped configuration (default: :func:`default_config`).
        selection: ``overall`` (one network) or ``per-set`` (the set's own checkpoint).
        weights_sha256: expected SHA-256 of ``weights``.

    Returns:
        (N,) float64 depth in metres.
    """
    return predict_report(
        examples,
        weights,
        formulation,
        chunk,
        config=config,
        selection=selection,
        weights_sha256=weights_sha256,
    )[0]


def predict_report(
    examples: Examples,
    weights: str | os.PathLike[str] | None = None,
    formulation: str | None = None,
    chunk: int = 4096,
    config: str | None = None,
    selection: str = "overall",
    weights_sha256: str | None = None,
) -> tuple[np.ndarray, dict[str, int | str]]:
    """:func:`predict`, how many examples had no detection at all, and which weights ran.

    Such an example has nothing to fill its boxes from; the network sees the boxes as
    stored (zeros in the original files) and its estimate means little. It is still
    estimated, as the original release did, and counted here as ``no_detection``.

    Returns:
        (depths, report): ``n``, ``no_detection`` (counts), and, as :func:`provenance`
        gives them, ``config``, ``selection``, ``weights`` and the verified
        ``weights_sha256`` (the ``baseline`` command prints them).
    """
    import torch
    from odmd_bench_baselines.dbox.model import predict_depth

    if examples.n_obs != OBSERVATIONS:
        raise DataError(f"DBox takes {OBSERVATIONS} observations per example, got {examples.n_obs}")
    path, described = resolve_weights(examples, config, weights, selection)
    model, form, sha = _load(path, weights_sha256, require_record=weights is None)
    if len(examples) == 0:
        depths = np.zeros(0, dtype=np.float64)
    else:
        depths = predict_depth(model, examples, formulation or form, torch.device("cpu"), chunk)
    report: dict[str, int | str] = {
        "n": len(examples),
        "no_detection": int((~examples.detected.any(axis=1)).sum()),
    }
    return depths, {**report, **described, "weights_sha256": sha, "formulation": formulation or form}


def provenance(
    examples: Examples,
    weights: str | os.PathLike[str] | None = None,
    config: str | None = None,
    selection: str = "overall",
    weights_sha256: str | None = None,
) -> dict[str, str]:
    """Which checkpoint :func:`predict` runs on ``examples`` with these options, verified.

    Returns:
        ``config`` (``custom`` for one's own file), ``selection``, ``weights`` (the file
        name of a shipped checkpoint, the path of one's own) and ``weights_sha256`` (the
        hash checked, to print into the predictions' provenance).

    Raises:
        UsageError, DataError: as :func:`predict` (unknown names, no such weights, a
            hash that does not match its record).
    """
    path, described = resolve_weights(examples, config, weights, selection)
    _, sha = verify_weights(path, weights_sha256, require_record=weights is None)
    return {**described, "weights_sha256": sha}
