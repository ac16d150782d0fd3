"""Scoring a predictions file: the last stage of evaluation, the warnings its scores give, and :func:`evaluate`.

The pipeline, each stage a pure function but the loading of the sets:

1. :func:`~odmd_bench.evaluation.parse.parse_predictions` checks the file's text;
2. :func:`evaluate` generates a missing split of a generated benchmark
   (:func:`~odmd_bench.data.store.generate_missing`, the one step that writes);
3. :func:`score_file`, which writes nothing, loads the sets of the file's benchmark and
   split (:func:`~odmd_bench.data.loading.read_split` verifies their hashes and pins),
   checks the rows against the sets' sizes
   (:func:`~odmd_bench.evaluation.coverage.check_coverage`), and :func:`score` computes
   the metrics.

A file is refused as a whole, naming every problem of stages 1 and 3 in one
:class:`~odmd_bench.errors.ValidationError`. Nothing here prints; formatting is
:mod:`odmd_bench.evaluation.report`'s job. Arrays are scored by
:func:`odmd_bench.evaluation.arrays.score_depths` (``odmd_bench.score``).

Scores that look wrong are scored as given, with a warning: depths a median factor of 20
or more off the truth (written in another unit), and depths made for the other ODMD
benchmark. ``odmd-v1`` and ``odmd-paper`` have the same sets of the same sizes, so a file
made for one passes every check of the other, and a file without a ``benchmark`` column
is scored against ``odmd-v1`` by default. Its numbers are then those of depths for other
examples: meaningless, yet plausible enough to be copied into a paper. When the other
benchmark is in the data folder, :func:`twin_fit` scores the same depths against it; on
the sets whose content differs, depths made for the other benchmark fit it several
times better, which no method's depths do by chance over thousands of examples.
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
from odmd_bench.data.registry import BENCHMARKS, Benchmark, get_benchmark, resolve_benchmark
from odmd_bench.errors import DataError, OdmdError, ValidationError
from odmd_bench.evaluation.columns import OPTIONAL_COLUMNS, REQUIRED_COLUMNS
from odmd_bench.evaluation.coverage import check_coverage, check_sets
from odmd_bench.evaluation.metrics import all_sets_mean, percent_error, set_metrics
from odmd_bench.evaluation.parse import ParsedPredictions, parse_predictions
from odmd_bench.evaluation.result import EvaluationResult, Predictions
from odmd_bench.evaluation.uncertainty import all_scores, set_scores
from odmd_bench.inputs.problems import SHOWN
from odmd_bench.inputs.source import Source

__all__ = [
    "OPTIONAL_COLUMNS",
    "REQUIRED_COLUMNS",
    "SHOWN",
    "EvaluationResult",
    "Predictions",
    "TwinFit",
    "evaluate",
    "score",
    "score_file",
    "twin_fit",
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


#: The benchmark whose sets have the same names and sizes, for each that has one.
TWINS: dict[str, Benchmark] = {"odmd-v1": BENCHMARKS["odmd-paper"], "odmd-paper": BENCHMARKS["odmd-v1"]}
#: The other benchmark fits "far better" when its mean percent error is below this
#: fraction of the scored one's.
FAR_BETTER = 0.5


@dataclasses.dataclass(frozen=True)
class TwinFit:
    """The same depths' mean percent error on the scored benchmark and on its twin.

    Attributes:
        benchmark: the benchmark scored.
        twin: the other one.
        sets: the sets compared (those whose content differs between the two).
        scored: mean over ``sets`` of each set's mean percent error on ``benchmark``.
        other: the same on ``twin``.
    """

    benchmark: str
    twin: str
    sets: tuple[str, ...]
    scored: float
    other: float

    @property
    def far_better(self) -> bool:
        """Whether the depths fit the twin far better than the benchmark scored."""
        return self.other < FAR_BETTER * self.scored

    def describe(self) -> str:
        """``fit odmd-paper far better (... on normal, camera, object)``."""
        return (
            f"fit {self.twin} far better than {self.benchmark} (mean percent error "
            f"{self.other:.2f} against {self.scored:.2f} on {', '.join(self.sets)})"
        )


def twin_fit(result: EvaluationResult, data_dir: str | os.PathLike[str] | None = None) -> TwinFit | None:
    """How the depths of ``result`` fit the twin of the benchmark they were scored against.

    None where there is nothing to compare: no twin, the twin's split is not in the data
    folder (it is never generated or imported for this), it cannot be loaded or scored
    against, or no set scored differs between the two (the robot sets are the same).
    """
    other_bench = TWINS.get(result.benchmark)
    if other_bench is None:
        return None
    depths, examples = result.predictions, result.examples
    try:  # a missing split raises MissingDataError, as any other that cannot be loaded
        other = read_split(other_bench, result.split, data_dir, sets=list(depths))
        names = tuple(
            s
            for s in other
            if len(other[s]) == len(examples[s])
            and other[s].attrs.get("content_sha256") != examples[s].attrs.get("content_sha256")
        )
        there = [float(np.mean(percent_error(other[s].depth, depths[s]))) for s in names]
    except OdmdError:
        return None
    if not names:
        return None
    here = [result.sets[s]["percent_error"]["mean"] for s in names]
    return TwinFit(result.benchmark, other_bench.name, names, float(np.mean(here)), float(np.mean(there)))


def score_file(
    parsed: ParsedPredictions,
    data_dir: str | os.PathLike[str] | None = None,
    *,
    sets: Sequence[str] | None = None,
) -> EvaluationResult:
    """Score a parsed predictions file against its verified sets in the data folder; nothing is written.

    The sets of the file's benchmark and split are read and verified
    (:func:`~odmd_bench.data.loading.read_split`), the rows checked against their sizes
    (:func:`~odmd_bench.evaluation.coverage.check_coverage`) and scored (:func:`score`);
    a file without a ``benchmark`` column whose depths fit the twin benchmark far better
    (:func:`twin_fit`) gets a warning. A missing split is refused, with the command that
    makes it: generating it is the step of :func:`evaluate`.

    Args:
        parsed: from :func:`~odmd_bench.evaluation.parse.parse_predictions` (``strict=False``:
            its problems are reported with the coverage's); it carries its benchmark.
        data_dir: the data folder (default ``$ODMD_BENCH_DATA`` or the documented default).
        sets: score only these sets (default: all of the benchmark's).

    Returns:
        The scores, with provenance.

    Raises:
        ValidationError: the file cannot be scored (every problem named at once).
        MissingDataError: the split is not in the data folder.
        DataError: the sets cannot be loaded, or scored against.
        UsageError: unknown ``sets``.
    """
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
                if parsed.benchmark_asked
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


def evaluate(
    path: Source,
    *,
    benchmark: str | Benchmark | None = None,
    data_dir: str | os.PathLike[str] | None = None,
    sets: Sequence[str] | None = None,
    name: str | None = None,
) -> EvaluationResult:
    """Validate a predictions file and score it against the benchmark's sets.

    The benchmark is resolved once and the file parsed; a missing split of a generated
    benchmark is then generated (logged: the one step that writes), and the file scored
    by :func:`score_file`, which writes nothing.

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
