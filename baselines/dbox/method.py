"""DBox's method interface: ``predict``, ``predict_report`` and ``provenance``."""

from __future__ import annotations

import copy
import os
from pathlib import Path

import numpy as np
from odmd_bench_baselines.dbox.choice import SELECTIONS, default_config, lateral_examples, resolve_weights
from odmd_bench_baselines.dbox.configs import OBSERVATIONS
from odmd_bench_baselines.dbox.loading import _load
from odmd_bench_baselines.dbox.weights import CONFIGS, training_depth_range, verify_weights

from odmd_bench import DataError, Examples, implied_depth
from odmd_bench.methods import MethodOption

#: The options ``odmd-bench baseline`` and ``predict`` give it (see odmd_bench.methods).
OPTIONS = (
    MethodOption(
        "weights",
        Path,
        None,
        "Checkpoint file in the original release's layout (default: the shipped weights of --config).",
    ),
    MethodOption(
        "weights_sha256",
        str,
        None,
        "The SHA-256 the --weights file must have (refused otherwise); a file with a JSON record "
        "beside it, or the original release's checkpoint, is checked without it.",
        metavar="HEX",
    ),
    MethodOption(
        "config",
        str,
        None,
        "Shipped training configuration to run (default: p-z for z-only camera motion, as in "
        "ODMS, else p); not with --weights.",
        choices=CONFIGS,
    ),
    MethodOption(
        "selection",
        str,
        "overall",
        "overall: the checkpoint val chose for all sets; per-set: the one it chose for each set.",
        choices=SELECTIONS,
    ),
    MethodOption(
        "device",
        str,
        "cpu",
        "Where the network runs: cpu, cuda, or auto (cuda when torch sees a GPU).",
        choices=("cpu", "cuda", "auto"),
    ),
)

#: Absolute-depth configurations are said to be outside their training data where the
#: implied depth is beyond this factor of its range (the implied depth is a rough scale)
#: for more than :data:`RANGE_SHARE` of the examples (noisy sets of the right scale have
#: a few: 2.6 % of generated ``odmd`` examples with both perturbations, at most 2.3 % of
#: an ``odmd-paper`` test set).
RANGE_MARGIN = 1.5
RANGE_SHARE = 0.25


def predict(
    examples: Examples,
    weights: str | os.PathLike[str] | None = None,
    formulation: str | None = None,
    chunk: int = 4096,
    config: str | None = None,
    selection: str = "overall",
    weights_sha256: str | None = None,
    device: str = "cpu",
) -> np.ndarray:
    """DBox depth estimates for ``examples``.

    Missing detections are filled with :func:`odmd_bench.fill_missing`; the network
    runs on ``device`` in batches of ``chunk`` without gradients.

    Args:
        examples: N examples of :data:`OBSERVATIONS` observations.
        weights: a checkpoint file (instead of ``config``).
        formulation: ``rel`` or ``abs``; default: from the weights' JSON record,
            else ``rel`` (the original release's checkpoint is f_Rel).
        chunk: examples per forward pass.
        config: shipped configuration (default: :func:`default_config`).
        selection: ``overall`` (one network) or ``per-set`` (the set's own checkpoint).
        weights_sha256: expected SHA-256 of ``weights``.
        device: ``cpu`` (the default), ``cuda`` or ``auto`` (CUDA when torch sees one).
            The GPU's float32 products round differently from the CPU's: depths agree
            to about 1e-6 relative, not bit for bit.

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
        device=device,
    )[0]


def predict_report(
    examples: Examples,
    weights: str | os.PathLike[str] | None = None,
    formulation: str | None = None,
    chunk: int = 4096,
    config: str | None = None,
    selection: str = "overall",
    weights_sha256: str | None = None,
    device: str = "cpu",
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
    from odmd_bench_baselines.dbox.distributed import resolve_device
    from odmd_bench_baselines.dbox.formulations import predict_depth

    dev = resolve_device(device)  # a missing GPU is a usage error before the weights load
    if examples.n_obs != OBSERVATIONS:
        raise DataError(f"DBox takes {OBSERVATIONS} observations per example, got {examples.n_obs}")
    path, described = resolve_weights(examples, config, weights, selection)
    model, form, sha = _load(path, weights_sha256, require_record=weights is None, keep=True)
    if len(examples) == 0:
        depths = np.zeros(0, dtype=np.float64)
    elif dev.type == "cpu":
        depths = predict_depth(model, examples, formulation or form, dev, chunk)
    else:  # a copy on the device: the loaded model is kept (on the CPU) for later calls
        on_device = copy.deepcopy(model).to(dev)
        depths = predict_depth(on_device, examples, formulation or form, dev, chunk)
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


def input_warnings(
    examples: Examples, weights: str | os.PathLike[str] | None = None, config: str | None = None
) -> list[str]:
    """Where a configuration is used outside what it learnt (``odmd_bench.predict.checks``).

    - a z-only configuration (``p-z``, ``ns-z``, ``abs-z``) on examples whose camera
      moves sideways: named with its x, y, z twin;
    - an absolute-depth configuration (``abs``, ``abs-z``) on examples whose implied
      depth (:func:`odmd_bench.implied_depth`) is beyond :data:`RANGE_MARGIN` times the
      depth range of its training data (:func:`training_depth_range`) for more than
      :data:`RANGE_SHARE` of them: named with the relative-depth configuration, which
      is scale-free.

    A checkpoint of one's own (``weights=``) is not judged.
    """
    if weights is not None or len(examples) == 0:
        return []
    cfg = config or default_config(examples)
    n = len(examples)
    out = []
    if cfg.endswith("-z"):
        side = int(lateral_examples(examples).sum())
        if side:
            out.append(
                f"DBox config {cfg!r} was trained on camera motion along z only, but in {side} of {n} "
                f"examples the camera moves sideways (x or y more than a tenth of z): use --config "
                f"{cfg[:-2]} (trained on x, y, z motion)"
            )
    if cfg.startswith("abs"):
        lo, hi = training_depth_range(cfg)
        z = implied_depth(examples)
        far = np.isfinite(z) & ((z > hi * RANGE_MARGIN) | (z < lo / RANGE_MARGIN))
        if far.sum() > RANGE_SHARE * n:
            rel = "p-z" if cfg.endswith("-z") else "p"
            out.append(
                f"DBox config {cfg!r} learnt absolute depths from {lo:.3g} to {hi:.3g} m (its training "
                f"data), but the boxes and camera motion of {int(far.sum())} of {n} examples imply depths "
                f"of {float(np.nanmin(z[far])):.3g} to {float(np.nanmax(z[far])):.3g} m, far outside: its "
                f"answers there are wrong; use --config {rel} (relative depth, any scale)"
            )
    return out
