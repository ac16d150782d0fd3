"""Scoring: the last stage of evaluation, and :func:`evaluate`, which runs them all.

The pipeline, each stage a pure function but the loading of the sets:

1. :func:`~odmd_bench.evaluation.parse.parse_predictions` checks the file's text;
2. the sets of the file's benchmark and split are loaded
   (:func:`~odmd_bench.data.loading.read_split` verifies their hashes and pins; a
   missing split of a generated benchmark is generated first, the one step that writes);
3. :func:`~odmd_bench.evaluation.coverage.check_coverage` checks the rows against the
   sets' sizes;
4. :func:`score` computes the metrics.

A file is refused as a whole, naming every problem of stages 1 and 3 in one
:class:`~odmd_bench.errors.ValidationError`. Nothing here prints; formatting is
:mod:`odmd_bench.evaluation.report`'s job. Arrays are scored by
:func:`odmd_bench.evaluation.arrays.score_depths` (``odmd_bench.score``).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench._version import __version__
from odmd_bench.data.examples import Examples, set_problems
from odmd_bench.data.loading import read_split
from odmd_bench.data.manifests import is_pinned
from odmd_bench.data.registry import Benchmark, get_benchmark, resolve_benchmark
from odmd_bench.errors import DataError, ValidationError
from odmd_bench.evaluation.columns import OPTIONAL_COLUMNS, REQUIRED_COLUMNS
from odmd_bench.evaluation.coverage import check_coverage, check_sets
from odmd_bench.evaluation.metrics import all_sets_mean, set_metrics
from odmd_bench.evaluation.parse import ParsedPredictions, parse_predictions
from odmd_bench.evaluation.result import EvaluationResult, Predictions
from odmd_bench.evaluation.twin import twin_fit
from odmd_bench.evaluation.uncertainty import all_scores, set_scores
from odmd_bench.inputs.problems import SHOWN
from odmd_bench.inputs.source import Source

__all__ = [
    "OPTIONAL_COLUMNS",
    "REQUIRED_COLUMNS",
    "SHOWN",
    "EvaluationResult",
    "Predictions",
    "evaluate",
    "score",
]


def score(
    predictions: Predictions, examples: Mapping[str, Examples], *, bench: Benchmark | None = None
) -> EvaluationResult:
    """Score validated predictions against the sets they refer to.

    Args:
        predictions: from :func:`~odmd_bench.evaluation.coverage.check_coverage`.
        examples: ``{set: Examples}`` holding at least the sets of ``predictions.depths``.
        bench: the benchmark ``predictions.benchmark`` names, where the caller has it
            (else it is looked up by that name).

    Returns:
        The scores, with provenance.

    Raises:
        ValidationError: a set's size differs from its estimates', or an error statistic
            is not finite.
        DataError: a set cannot be scored against (:func:`~odmd_bench.data.examples.set_problems`:
            a true depth that is not finite and positive, for instance).
    """
    return _score(predictions, examples, bench if bench is not None else get_benchmark(predictions.benchmark))


def _score(predictions: Predictions, examples: Mapping[str, Examples], bench: Benchmark) -> EvaluationResult:
    """:func:`score` with the benchmark of ``predictions`` at hand."""
    per_set: dict[str, dict[str, Any]] = {}
    preds: dict[str, np.ndarray] = {}
    used: dict[str, Examples] = {}
    for s, depth in predictions.depths.items():
        ex = examples[s]
        if len(ex) != len(depth):
            raise ValidationError(
                f"{predictions.path} cannot be scored",
                [f"set {s!r} has {len(ex)} examples but {len(depth)} estimates"],
            )
        unusable = set_problems(ex)
        if unusable:
            raise DataError(
                f"{predictions.benchmark} {predictions.split} {s} cannot be scored against: "
                "the set is damaged or was not made by odmd-bench (regenerate or re-import it)",
                unusable,
            )
        per_set[s] = set_metrics(ex.depth, depth)
        if predictions.uncertainty:
            per_set[s].update(set_scores(ex.depth, depth, predictions.uncertainty[s], predictions.level))
        preds[s] = depth.copy()
        used[s] = ex
    bad = [s for s, m in per_set.items() if not all(np.isfinite(list(m["percent_error"].values())))]
    if bad:  # the parsers' bound on |depth| keeps this from happening
        raise ValidationError(
            f"{predictions.path} cannot be scored", [f"the errors of set {s!r} are not finite" for s in bad]
        )
    all_mean = all_sets_mean({s: m["percent_error"]["mean"] for s, m in per_set.items()})
    provenance = {
        "package": "odmd-bench",
        "version": __version__,
        "benchmark": predictions.benchmark,
        "split": predictions.split,
        "sets_content_sha256": {s: str(used[s].attrs.get("content_sha256", "")) for s in per_set},
        "predictions_file": Path(predictions.path).name,
        "predictions_sha256": predictions.sha256,
        "predictions_rows": predictions.n_rows,
        "ignored_columns": list(predictions.ignored_columns),
    }
    warnings = tuple(predictions.warnings) + _units_warning(preds, used)
    unpinned = [s for s in per_set if not is_pinned(bench, used[s].attrs)]
    if unpinned:
        provenance["unpinned_sets"] = unpinned
        warnings += (
            f"{predictions.benchmark} {predictions.split} {', '.join(unpinned)}: not the pinned "
            "version of the benchmark (imported with --allow-unknown, or written by other means); "
            "these scores do not compare with the paper's or the leaderboard's",
        )
    return EvaluationResult(
        benchmark=predictions.benchmark,
        split=predictions.split,
        sets=per_set,
        all_percent_error_mean=all_mean,
        provenance=provenance,
        warnings=warnings,
        predictions=preds,
        examples=used,
        uncertainty={s: dict(predictions.uncertainty[s]) for s in per_set} if predictions.uncertainty else {},
        all_uncertainty=all_scores(per_set) if predictions.uncertainty else {},
    )


#: Median ratios of estimate to truth that say "another unit", and the unit each suggests.
_UNITS = ((1000.0, "millimetres"), (100.0, "centimetres"), (0.001, "kilometres"))
_FAR_OFF = 20.0


def _units_warning(preds: Mapping[str, np.ndarray], used: Mapping[str, Examples]) -> tuple[str, ...]:
    """A warning when the estimates are a median factor of 20 or more off the truth (metres)."""
    ratios = [preds[s] / used[s].depth for s in preds]
    ratio = float(np.median(np.concatenate(ratios))) if ratios else 1.0
    if not (ratio >= _FAR_OFF or 0 < ratio <= 1 / _FAR_OFF):
        return ()
    factor, unit = min(_UNITS, key=lambda fu: abs(np.log(ratio / fu[0])))
    guess = f"; were they written in {unit}?" if abs(np.log(ratio / factor)) < np.log(2) else ""
    return (
        f"the depths are a median {ratio:.4g} times the true depths: depths are in metres{guess} "
        "(scored as given)",
    )


def evaluate(
    path: Source,
    *,
    benchmark: str | Benchmark | None = None,
    data_dir: str | os.PathLike[str] | None = None,
    sets: Sequence[str] | None = None,
    name: str | None = None,
) -> EvaluationResult:
    """Validate a predictions file and score it against the benchmark's sets.

    Args:
        path: the predictions CSV (docs/format.md): a path, its bytes or a binary file;
            gzip is recognised.
        benchmark: default the file's ``benchmark`` column, else ``odmd-v1``.
        data_dir: the data folder (default ``$ODMD_BENCH_DATA`` or the documented default).
        sets: score only these sets (default: all of the benchmark's).
        name: how messages and provenance name the file (default: the path).

    Returns:
        The scores, with provenance.

    Raises:
        ValidationError: the file cannot be scored (every problem named at once).
        DataError: the sets cannot be loaded.
        UsageError: unknown arguments.

    Example:
        >>> import tempfile
        >>> import odmd_bench
        >>> tmp = tempfile.TemporaryDirectory()  # a data folder of its own
        >>> sets = odmd_bench.load_split("val", "odmd-v1", data_dir=tmp.name)
        >>> depths = {s: 1.1 * ex.depth for s, ex in sets.items()}  # 10 % too deep
        >>> odmd_bench.write_predictions(f"{tmp.name}/preds.csv", "val", depths, "odmd-v1")
        >>> result = evaluate(f"{tmp.name}/preds.csv", data_dir=tmp.name)
        >>> list(result.sets), round(result.all_percent_error_mean, 6)
        (['normal', 'camera', 'object', 'robot'], 10.0)
        >>> tmp.cleanup()
    """
    from odmd_bench.data.store import generate_missing

    given = resolve_benchmark(benchmark) if benchmark is not None else None
    if given is not None and sets is not None:
        check_sets(sets, given)
    parsed = parse_predictions(path, name=name, benchmark=given, strict=False)
    if parsed.bench is not None and parsed.split is not None:
        if sets is not None:
            check_sets(sets, parsed.bench)
        generate_missing(parsed.bench, parsed.split, data_dir)  # the one step that writes
    return score_file(parsed, data_dir, sets=sets)


def score_file(
    parsed: ParsedPredictions,
    data_dir: str | os.PathLike[str] | None = None,
    *,
    sets: Sequence[str] | None = None,
) -> EvaluationResult:
    """Score a parsed predictions file against the verified sets in the data folder; writes nothing."""
    bench, split = parsed.bench, parsed.split
    if bench is None or split is None:
        raise parsed.problems.error(parsed.name)
    scope = check_sets(sets, bench) if sets is not None else None
    examples = read_split(bench, split, data_dir, scope)
    predictions = check_coverage(parsed, {s: len(ex) for s, ex in examples.items()}, sets=sets)
    result = _score(predictions, examples, bench)
    if not parsed.benchmark_column:
        fit = twin_fit(result, data_dir)
        if fit is not None and fit.far_better:
            said = (
                f"as asked (--benchmark {bench.name})"
                if parsed.benchmark_argument
                else "the default, as the file has no benchmark column"
            )
            result = dataclasses.replace(
                result,
                warnings=(
                    *result.warnings,
                    f"scored against {result.benchmark}, {said}, but the depths {fit.describe()}: "
                    f"if they were made for {fit.twin}, score them with --benchmark {fit.twin}",
                ),
            )
    return result
