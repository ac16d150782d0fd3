"""Which DBox configuration and checkpoint run on given data.

The data decide what is not asked for by name: the benchmark named in
``examples.attrs`` when it is known, else the camera motion (z-only or not); the
benchmark also decides which val split's selection runs (:func:`selection_benchmark`).
:func:`resolve_weights` turns the options into one checkpoint of the registry
(:mod:`.weights`) and says how it was chosen. Nothing here imports torch.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from odmd_bench_baselines.dbox.weights import (
    CONFIGS,
    per_set_names,
    per_set_path,
    shipped,
    shipped_name,
    weights_path,
)

from odmd_bench import DataError, Examples, UsageError

#: ``overall``: one network chosen on val All; ``per-set``: one per set, chosen on that set.
SELECTIONS = ("overall", "per-set")
#: Benchmarks whose camera moves along z only.
Z_ONLY_BENCHMARKS = ("odms-detection",)
#: Camera motion is z-only when no x or y offset exceeds this fraction of the largest z offset.
Z_ONLY_RATIO = 0.1


def selection_benchmark(examples: Examples) -> str | None:
    """The benchmark whose val split selects weights for ``examples``, when it is known.

    ``odms-detection`` for the z-only benchmarks, ``odmd-v1`` for the ODMD ones
    (``odmd-paper``'s sets are the same task), None for data that name no benchmark.
    """
    benchmark = examples.attrs.get("benchmark")
    if benchmark in Z_ONLY_BENCHMARKS:
        return str(benchmark)
    if isinstance(benchmark, str) and benchmark.startswith("odmd"):
        return "odmd-v1"
    return None


def lateral_examples(examples: Examples) -> np.ndarray:
    """(N,) bool: the camera moves sideways (an x or y offset above :data:`Z_ONLY_RATIO` of the z offsets)."""
    cam = np.asarray(examples.camera, dtype=np.float64)
    if cam.size == 0:
        return np.zeros(len(examples), dtype=bool)
    z = np.abs(cam[..., 2]).max(axis=1)
    return np.asarray(np.abs(cam[..., :2]).max(axis=(1, 2)) > Z_ONLY_RATIO * z, dtype=bool)


def is_z_only(examples: Examples) -> bool:
    """Whether the camera moves along z only (x, y offsets at most 10 % of the z offsets)."""
    if len(examples) == 0:
        return False
    cam = np.asarray(examples.camera, dtype=np.float64)
    z = float(np.abs(cam[..., 2]).max())
    return z > 0 and float(np.abs(cam[..., :2]).max()) <= Z_ONLY_RATIO * z


def default_config(examples: Examples) -> str:
    """``p-z`` for a z-only benchmark or z-only camera motion, else ``p``.

    The benchmark named in ``examples.attrs["benchmark"]`` decides when it is known
    (``odms-detection`` is z-only, ``odmd-*`` is not); other data are judged by their
    camera motion (:func:`is_z_only`).
    """
    benchmark = examples.attrs.get("benchmark")
    if benchmark in Z_ONLY_BENCHMARKS:
        return "p-z"
    if isinstance(benchmark, str) and benchmark.startswith("odmd"):
        return "p"
    return "p-z" if is_z_only(examples) else "p"


def resolve_weights(
    examples: Examples,
    config: str | None = None,
    weights: str | os.PathLike[str] | None = None,
    selection: str = "overall",
) -> tuple[Path, dict[str, str]]:
    """The checkpoint to run on ``examples`` and how it was chosen.

    Args:
        examples: one set (``selection="per-set"`` reads its name from ``attrs["set"]``).
        config: a shipped configuration (default: :func:`default_config`); not with
            ``weights``.
        weights: a checkpoint file of one's own.
        selection: ``overall`` or ``per-set`` (with ``weights``: the file's per-set
            sibling ``<stem>.<set>.pt``, as ``train-dbox`` writes them).

    Returns:
        (checkpoint path, provenance: ``config``, ``selection``, ``weights`` (the path
        inside the shipped weights folder, or one's own file's path)).

    Raises:
        UsageError: an unknown configuration or selection, or both ``config`` and
            ``weights``.
        DataError: no shipped weights for the configuration (the shipped ones are
            listed), or no per-set checkpoint for the set.
    """
    problems = []
    if selection not in SELECTIONS:
        problems.append(f"unknown DBox selection {selection!r}; expected one of {', '.join(SELECTIONS)}")
    if config is not None and weights is not None:
        problems.append("give DBox either a configuration or a weights file, not both")
    if config is not None and config not in CONFIGS:
        problems.append(f"unknown DBox configuration {config!r}; expected one of {', '.join(CONFIGS)}")
    set_name = examples.attrs.get("set")
    if selection == "per-set" and not isinstance(set_name, str):
        problems.append(
            "per-set selection needs to know which set the examples are (examples.attrs['set']): "
            "use it with odmd-bench baseline, or load them with odmd_bench.load_split"
        )
    if len(problems) == 1:
        raise UsageError(problems[0])
    if problems:
        raise UsageError("DBox cannot run with these options", problems)
    if weights is not None:
        path = Path(weights)
        if selection == "per-set":
            path = per_set_path(path, str(set_name))
            if not path.is_file():
                raise DataError(f"no per-set checkpoint for set {set_name!r} beside {weights}: {path}")
        return path, {"config": "custom", "selection": selection, "weights": str(path)}
    name = config if config is not None else default_config(examples)
    available = shipped()
    if name not in available:
        listed = ", ".join(available) or "none"
        raise DataError(
            f"no shipped weights for DBox configuration {name!r} (shipped: {listed})",
            [f"train them with: odmd-bench train-dbox --config {name} --out DIR, then pass --weights"],
        )
    path = weights_path(name)
    on = selection_benchmark(examples)
    if weights_path(name, selected_on=on).is_file():
        path = weights_path(name, selected_on=on)  # selected on the val of the data's benchmark
    if selection == "per-set":
        # the per-set files selected on the same val as the overall one, beside it
        sets = per_set_names(path, name)
        if str(set_name) not in sets:
            where = shipped_name(path.parent)
            raise DataError(
                f"DBox configuration {name!r} has no per-set checkpoint for set {set_name!r} "
                f"(per-set checkpoints{'' if where == '.' else ' in ' + where + '/'}: "
                f"{', '.join(sets) or 'none'}); use selection 'overall'"
            )
        path = per_set_path(path, str(set_name))
    return path, {"config": name, "selection": selection, "weights": shipped_name(path)}
