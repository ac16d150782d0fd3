"""``baseline``: run a baseline method on every set of a split and write predictions.

The methods live in the top-level ``baselines`` package, one module each, and are
imported only when asked for, so that ``torch`` is loaded for ``dbox`` alone and a method
that is not installed gives a clear error instead of breaking the whole command line.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType
from typing import Any

import click
import numpy as np

from odmd_bench.data.registry import BENCHMARKS, DATA_DIR_ENV, DEFAULT_BENCHMARK, SPLITS
from odmd_bench.errors import UsageError

#: Command-line name -> (module under ``baselines``, what it needs beyond numpy).
BASELINES: dict[str, tuple[str, str]] = {
    "box-ls": ("box_ls", ""),
    "parallax": ("parallax", "the camera intrinsics"),
    "expansion": ("expansion", ""),
    "dbox": ("dbox", "torch"),
    "robust": ("robust", "the camera intrinsics"),
}


def _import_method(name: str) -> ModuleType:
    module_name = f"odmd_bench_baselines.{BASELINES[name][0]}"
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as e:
        if e.name == "torch":
            raise UsageError(
                f"baseline {name!r} needs PyTorch, which is not installed (pip install torch)"
            ) from None
        if e.name is not None and (module_name == e.name or module_name.startswith(e.name + ".")):
            raise UsageError(
                f"baseline {name!r} is not available: module {module_name} is not installed "
                "(install odmd-bench from a checkout of its repository, which includes baselines/)"
            ) from None
        raise
    if not callable(getattr(module, "predict", None)):
        raise UsageError(f"baseline {name!r} is not available: {module_name} has no predict() function")
    return module


def _run(method: ModuleType, examples: Any, kwargs: dict[str, Any]) -> tuple[np.ndarray, dict[str, int]]:
    """Depths and counted fallbacks, from ``predict_report`` where the method has one."""
    report = getattr(method, "predict_report", None)
    if report is not None:
        depths, counts = report(examples, **kwargs)
    else:
        depths, counts = method.predict(examples, **kwargs), {}
    return np.asarray(depths, dtype=np.float64), dict(counts)


def default_output(name: str, benchmark: str, split: str) -> Path:
    """``preds-<name>-<benchmark>-<split>.csv`` in the current folder."""
    return Path(f"preds-{name}-{benchmark}-{split}.csv")


@click.command()
@click.argument("name", type=click.Choice(list(BASELINES)))
@click.option(
    "--benchmark",
    default=DEFAULT_BENCHMARK,
    show_default=True,
    type=click.Choice(list(BENCHMARKS)),
    help="Benchmark whose sets are estimated.",
)
@click.option(
    "--split", default="test", show_default=True, type=click.Choice(SPLITS), help="Split to run on."
)
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Predictions CSV to write (default: preds-NAME-BENCHMARK-SPLIT.csv here).",
)
@click.option(
    "--data-dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help=f"Data folder (default: ${DATA_DIR_ENV}, else ~/.local/share/odmd-bench).",
)
@click.option(
    "--weights",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="dbox only: checkpoint to load (also the original release's layout).",
)
@click.option(
    "--mode",
    type=click.Choice(["full", "scale"]),
    default=None,
    help="robust only: 'full' (reprojection of every box coordinate; needs intrinsics) or "
    "'scale' (box sizes only: for sets without intrinsics, e.g. odms-detection).",
)
def baseline(
    name: str,
    benchmark: str,
    split: str,
    output: Path | None,
    data_dir: Path | None,
    weights: Path | None,
    mode: str | None,
) -> None:
    """Run baseline NAME on every set of a split and write a predictions CSV.

    NAME is one of box-ls (the paper's n-observation least squares), parallax and
    expansion (two-observation analytical solutions of the supplementary material),
    dbox (the paper's network; needs torch) and robust.
    """
    from odmd_bench import load_split
    from odmd_bench.evaluation.predictions import write_predictions

    if weights is not None and name != "dbox":
        raise UsageError(f"--weights applies to dbox only, not to {name!r}")
    if mode is not None and name != "robust":
        raise UsageError(f"--mode applies to robust only, not to {name!r}")
    method = _import_method(name)
    kwargs: dict[str, Any] = {"weights": weights} if weights is not None else {}
    if mode is not None:
        kwargs["mode"] = mode

    sets = load_split(split, benchmark, data_dir)
    depths: dict[str, np.ndarray] = {}
    fallbacks: dict[str, dict[str, int]] = {}
    for set_name, examples in sets.items():
        depths[set_name], fallbacks[set_name] = _run(method, examples, kwargs)
        # Every method promises one finite depth per example; anything else is its bug.
        if depths[set_name].shape != (len(examples),):
            raise RuntimeError(
                f"baseline {name} returned shape {depths[set_name].shape} for {len(examples)} examples"
            )
        if not np.isfinite(depths[set_name]).all():
            bad = int((~np.isfinite(depths[set_name])).sum())
            raise RuntimeError(f"baseline {name} returned {bad} non-finite depths on set {set_name}")

    path = output if output is not None else default_output(name, benchmark, split)
    write_predictions(path, split, depths, benchmark=benchmark)
    n = sum(len(v) for v in depths.values())
    click.echo(f"{name} on {benchmark} {split}: wrote {n} predictions ({', '.join(depths)}) to {path}")
    for set_name, counts in fallbacks.items():
        used = {k: v for k, v in counts.items() if k != "n" and v}
        summary = ", ".join(f"{k} {v}" for k, v in used.items()) if used else "none"
        click.echo(f"  {set_name}: fallbacks: {summary}")
    hint = f"odmd-bench evaluate {path}"
    if benchmark != DEFAULT_BENCHMARK:
        hint += f" --benchmark {benchmark}"
    if data_dir is not None:
        hint += f" --data-dir {data_dir}"
    click.echo(f"score it with: {hint}")


COMMANDS: list[click.Command] = [baseline]
