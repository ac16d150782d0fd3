"""Scoring arrays from Python, as strictly as a predictions file: ``odmd_bench.score``.

:func:`score_depths` takes ``{set: depths in index order}`` and checks them as the CSV
reader checks a file: every set of the benchmark present (or those asked for), no
unknown set, one 1-D numeric array per set of the set's length, every depth finite and
of a sane size. Every problem is named in one :class:`~odmd_bench.errors.ValidationError`,
located by set and index. The result equals that of
:func:`~odmd_bench.evaluation.scoring.evaluate` on the CSV
:func:`~odmd_bench.evaluation.predictions.write_predictions` writes for the same arrays,
hash included: ``sha256`` and ``n_rows`` are those of the CSV of the scored sets, in the
mapping's order (only the warnings' locations read ``set index`` instead of ``line``).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from odmd_bench.data.registry import Benchmark, check_split, resolve_benchmark
from odmd_bench.errors import UsageError
from odmd_bench.evaluation.coverage import check_sets, nonpositive_warning
from odmd_bench.evaluation.kinds import MAX_ABS_DEPTH, NONFINITE, OUT_OF_RANGE
from odmd_bench.evaluation.predictions import format_predictions
from odmd_bench.evaluation.result import EvaluationResult, Predictions
from odmd_bench.evaluation.scoring import score
from odmd_bench.inputs.problems import SHOWN, Problems, closest, show


def _located(problems: Problems, kind: str, s: str, values: np.ndarray, where: np.ndarray) -> None:
    rows = np.flatnonzero(where)
    for i in rows[:SHOWN]:
        problems.add(kind, f"{s} {i} ({float(values[i])!r})")
    if rows.size > SHOWN:
        problems.add(kind, count=int(rows.size - SHOWN))


def _check_array(s: str, given: Any, n: int, problems: Problems) -> np.ndarray | None:
    """``(n,)`` float64 depths of set ``s``, or None with its problems added."""
    try:
        arr = np.asarray(given)
    except (ValueError, TypeError) as e:
        problems.add(f"set {s!r}: the depths are not an array ({str(e)[:100]})")
        return None
    if arr.dtype.kind not in "iuf":
        problems.add(f"set {s!r}: the depths must be real numbers, got dtype {arr.dtype}")
        return None
    if arr.ndim != 1:
        problems.add(f"set {s!r}: the depths must be a 1-D array in index order, got shape {arr.shape}")
        return None
    if arr.shape[0] != n:
        problems.add(f"set {s!r} has {n} examples but {arr.shape[0]} depths were given")
        return None
    values = arr.astype(np.float64)
    finite = np.isfinite(values)
    _located(problems, NONFINITE, s, values, ~finite)
    _located(problems, OUT_OF_RANGE, s, values, finite & (np.abs(values) > MAX_ABS_DEPTH))
    return values


def _set_names(
    depths: Mapping[Any, Any], bench: Benchmark, scope: tuple[str, ...], problems: Problems
) -> None:
    for k in depths:
        if k not in bench.sets:
            text = str(k)
            problems.add(
                f"unknown set {show(text)} for benchmark {bench.name!r}{closest(text, bench.sets)}",
                note=f"expected one of {', '.join(bench.sets)}",
            )
    for s in scope:
        if s not in depths:
            others = [x for x in scope if x != s]
            problems.add(
                f"set {s!r} of benchmark {bench.name!r} has no depths (to score only some sets, "
                f"name them, e.g. sets={others!r})"
            )


def score_depths(
    benchmark: str | Benchmark,
    split: str,
    depths: Mapping[str, Any],
    *,
    data_dir: str | os.PathLike[str] | None = None,
    sets: Sequence[str] | None = None,
    name: str = "<arrays>",
) -> EvaluationResult:
    """Score ``{set: (N,) depths}`` of one split, the estimate of example ``i`` at ``i``.

    Exported as ``odmd_bench.score``.

    Expected input format (checked: every problem is named in one error)::

        depths = {
            "normal": np.array([1.337, 0.603, ...]),  # (N_normal,) metres
            "camera": ...,  # one entry per set of the benchmark:
            "object": ...,  #   odmd-v1, odmd-paper: normal, camera, object, robot
            "robot": ...,   #   odms-detection: normal, perturb, robot, driving
        }                   #   kitti-tracking: vehicle, person

    - keys: the benchmark's set names, each once (or those of ``sets``); no other key;
    - values: 1-D array-likes of real numbers (int or float dtype), one per example of
      the set, **in index order**: ``depths[s][i]`` is the estimated depth ``Z_n`` at
      the last observation of example ``i`` of ``load_split(split, benchmark)[s]``,
      in metres; so ``len(depths[s]) == len(load_split(split, benchmark)[s])``;
    - every value finite and at most ``1e12`` in size; zero or negative depths are
      scored as given, with a warning.

    Args:
        benchmark: e.g. ``"odmd-v1"``.
        split: ``"val"`` or ``"test"``.
        depths: ``{set: array-like (N_set,)}`` of real numbers, for every set of the
            benchmark (or those of ``sets``).
        data_dir: the data folder (default ``$ODMD_BENCH_DATA`` or the documented default).
        sets: score only these sets; depths of other sets are ignored, with a warning.
        name: how messages and provenance name the predictions.

    Returns:
        The same result as ``evaluate`` of the CSV these arrays make.

    Raises:
        ValidationError: every problem with the arrays, in one error.
        UsageError: unknown benchmark, split or sets, or ``depths`` not a mapping.
        DataError: the sets cannot be loaded.

    Example:
        >>> import tempfile
        >>> import odmd_bench
        >>> tmp = tempfile.TemporaryDirectory()  # a data folder of its own
        >>> sets = odmd_bench.load_split("val", "odmd-v1", data_dir=tmp.name)
        >>> depths = {s: ex.depth for s, ex in sets.items()}  # the true depths
        >>> odmd_bench.score("odmd-v1", "val", depths, data_dir=tmp.name).all_percent_error_mean
        0.0
        >>> tmp.cleanup()
    """
    from odmd_bench.data.store import load_split

    bench = resolve_benchmark(benchmark)
    check_split(split)
    scope = check_sets(sets, bench) if sets is not None else bench.sets
    if not isinstance(depths, Mapping):
        raise UsageError(f"depths must be a mapping {{set: (N,) array}}, got {type(depths).__name__}")
    examples = load_split(split, bench, data_dir, list(scope) if sets is not None else None)
    problems = Problems(unit="value")
    _set_names(depths, bench, scope, problems)
    checked = {s: _check_array(s, depths[s], len(examples[s]), problems) for s in scope if s in depths}
    if problems:
        raise problems.error(name)
    values = {s: v for s, v in checked.items() if v is not None}
    warnings = []
    located = [(s, i, float(values[s][i])) for s in scope for i in np.flatnonzero(values[s] <= 0)[:SHOWN]]
    count = sum(int(np.count_nonzero(values[s] <= 0)) for s in scope)
    if count:
        warnings.append(nonpositive_warning(count, [f"{s} {i}: {v!r}" for s, i, v in located[:SHOWN]]))
    ignored = [k for k in depths if k not in scope]
    if ignored:
        parts = ", ".join(f"{k} ({np.size(depths[k])} values)" for k in ignored)
        warnings.append(f"ignored depths of sets not asked for: {parts}")
    # The CSV write_predictions writes for the scored sets, in the mapping's order.
    text = format_predictions(split, {k: values[k] for k in depths if k in values})
    predictions = Predictions(
        path=name,
        sha256=hashlib.sha256(text.encode()).hexdigest(),
        benchmark=bench.name,
        split=split,
        depths=values,
        n_rows=text.count("\n") - 1,
        warnings=tuple(warnings),
    )
    return score(predictions, examples, bench=bench)
