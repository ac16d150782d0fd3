"""Error against true depth, binned: the numbers behind ``odmd-bench plot``.

Pure computation over arrays (no matplotlib, no files): :func:`bin_edges` chooses the
bins, :func:`binned_errors` summarises one method's per-example errors in each bin,
:func:`error_curves` does both for scored predictions files of one set, and
:func:`format_curves_csv` writes the numbers so that a figure can be checked and redrawn.
Drawing is :mod:`odmd_bench.evaluation.plot`'s job.

Bins are closed on the left and open on the right, except the last, which is closed
(so the deepest example of a set falls in the last equal-width bin).

>>> edges = bin_edges([1.0, 2.0, 5.0], 2)
>>> edges.tolist()
[1.0, 3.0, 5.0]
>>> b = binned_errors([1.0, 2.0, 5.0], [0.5, 1.5, 4.0], edges)
>>> b.counts.tolist(), b.mean.tolist()
([2, 1], [1.0, 4.0])
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from odmd_bench.errors import UsageError
from odmd_bench.evaluation.metrics import absolute_error, percent_error
from odmd_bench.evaluation.result import EvaluationResult

#: The error kinds: name -> (per-example function of (truth, estimate), unit).
ERRORS: dict[str, tuple[Callable[[Any, Any], np.ndarray], str]] = {
    "absolute": (absolute_error, "m"),
    "percent": (percent_error, "%"),
}

#: Default number of equal-width bins.
DEFAULT_BINS = 10
#: The most bins a figure shows (``--bins``).
MAX_BINS = 200

#: Columns of :func:`format_curves_csv`, in order.
CSV_COLUMNS: tuple[str, ...] = (
    "label",
    "benchmark",
    "split",
    "set",
    "error",
    "unit",
    "bin",
    "depth_low",
    "depth_high",
    "n",
    "mean",
    "median",
    "q25",
    "q75",
)


@dataclass(frozen=True)
class DepthBins:
    """One method's errors summarised per true-depth bin.

    Attributes:
        edges: ``(B + 1,)`` increasing bin edges in metres.
        counts: ``(B,)`` examples per bin.
        mean, median, q25, q75: ``(B,)`` mean, median and quartiles of the errors in each
            bin (linear interpolation between order statistics); NaN where a bin is empty.
        outside: examples whose depth lies outside ``[edges[0], edges[-1]]`` (possible
            with explicit edges only); they are in no bin.
    """

    edges: np.ndarray
    counts: np.ndarray
    mean: np.ndarray
    median: np.ndarray
    q25: np.ndarray
    q75: np.ndarray
    outside: int = 0

    @property
    def centres(self) -> np.ndarray:
        """``(B,)`` the middle of each bin, in metres."""
        return (self.edges[:-1] + self.edges[1:]) / 2.0


@dataclass(frozen=True)
class ErrorCurve:
    """One predictions file's binned errors on one set, with what names it.

    Attributes:
        label: the method's name in the legend and the CSV.
        bins: the binned errors.
        set_mean: the mean error over the whole set (all bins and outside).
        n: examples in the set.
    """

    label: str
    bins: DepthBins
    set_mean: float
    n: int


def parse_bins(text: str) -> int | tuple[float, ...]:
    """Read ``--bins``: a number of equal-width bins, or comma-separated edges in metres.

    Raises:
        UsageError: not a positive integer, nor at least two finite increasing edges.

    Example:
        >>> parse_bins("8"), parse_bins("0, 10,20.5")
        (8, (0.0, 10.0, 20.5))
    """
    value = text.strip()
    if "," not in value:
        try:
            n = int(value)
        except ValueError:
            n = 0
        if n < 1:
            raise UsageError(
                f"--bins {text!r} is neither a positive number of bins nor comma-separated "
                "edges in metres (e.g. 10, or 0,10,20,40,70)"
            )
        if n > MAX_BINS:
            raise UsageError(f"--bins {text!r}: at most {MAX_BINS} bins fit a figure")
        return n
    try:
        edges = tuple(float(v) for v in value.split(","))
    except ValueError:
        raise UsageError(f"--bins {text!r}: every edge must be a number (metres)") from None
    _check_edges(edges, f"--bins {text!r}")
    if len(edges) > MAX_BINS + 1:
        raise UsageError(
            f"--bins: {len(edges)} edges given; at most {MAX_BINS + 1} ({MAX_BINS} bins) fit a figure"
        )
    return edges


def _check_edges(edges: Sequence[float], what: str) -> None:
    problems = []
    if len(edges) < 2:
        problems.append(f"{len(edges)} edge given; at least two are needed (one bin)")
    if not all(np.isfinite(edges)):
        problems.append("every edge must be finite")
    elif any(b <= a for a, b in zip(edges, edges[1:], strict=False)):
        problems.append("the edges must be strictly increasing")
    if problems:
        raise UsageError(f"{what} are not usable bin edges", problems)


def bin_edges(depth: Any, bins: int | Sequence[float] = DEFAULT_BINS) -> np.ndarray:
    """Bin edges over true depths.

    Args:
        depth: ``(N,)`` true depths in metres, finite, N >= 1.
        bins: a number of equal-width bins spanning ``[min(depth), max(depth)]`` (when
            every depth is the same, the span is that depth +- 0.5 m), or the edges
            themselves (strictly increasing, at least two).

    Returns:
        ``(B + 1,)`` float64 edges.

    Raises:
        UsageError: no depths, a depth that is not finite, or unusable ``bins``.
    """
    if not isinstance(bins, (int, np.integer)):
        edges = np.asarray(bins, dtype=np.float64)
        _check_edges(edges.tolist(), "the bins")
        return edges.copy()
    if bins < 1:
        raise UsageError(f"the number of bins must be at least 1, not {bins}")
    z = np.asarray(depth, dtype=np.float64).ravel()
    if z.size == 0 or not np.isfinite(z).all():
        raise UsageError("bin edges need at least one true depth, and finite ones")
    lo, hi = float(z.min()), float(z.max())
    if hi == lo:
        lo, hi = lo - 0.5, hi + 0.5
    edges = np.linspace(lo, hi, int(bins) + 1)
    edges[0], edges[-1] = lo, hi  # exact ends: the extreme depths are never outside
    return edges


def binned_errors(depth: Any, errors: Any, edges: Any) -> DepthBins:
    """Summarise per-example errors in bins of true depth.

    Args:
        depth: ``(N,)`` true depths in metres.
        errors: ``(N,)`` each example's error (any unit).
        edges: ``(B + 1,)`` strictly increasing edges, e.g. from :func:`bin_edges`.

    Returns:
        Counts, mean, median and quartiles per bin (NaN for an empty bin).

    Raises:
        UsageError: shapes that differ, values that are not finite, unusable edges.
    """
    z = np.asarray(depth, dtype=np.float64).ravel()
    e = np.asarray(errors, dtype=np.float64).ravel()
    edges = np.asarray(edges, dtype=np.float64)
    if z.shape != e.shape:
        raise UsageError(f"{z.size} depths but {e.size} errors; expected one error per depth")
    if not (np.isfinite(z).all() and np.isfinite(e).all()):
        raise UsageError("depths and errors must be finite")
    _check_edges(edges.tolist(), "the bins")
    n_bins = edges.size - 1
    which = np.searchsorted(edges, z, side="right") - 1
    which[z == edges[-1]] = n_bins - 1  # the last bin is closed on the right
    inside = (which >= 0) & (which < n_bins)
    counts = np.bincount(which[inside], minlength=n_bins).astype(np.int64)
    stats = np.full((4, n_bins), np.nan)
    for b in np.flatnonzero(counts):
        vals = e[inside & (which == b)]
        stats[:, b] = [vals.mean(), *np.quantile(vals, [0.5, 0.25, 0.75])]
    return DepthBins(
        edges=edges.copy(),
        counts=counts,
        mean=stats[0],
        median=stats[1],
        q25=stats[2],
        q75=stats[3],
        outside=int((~inside).sum()),
    )


def error_curves(
    results: Sequence[EvaluationResult],
    labels: Sequence[str],
    set_name: str,
    *,
    error: str = "absolute",
    bins: int | Sequence[float] = DEFAULT_BINS,
) -> list[ErrorCurve]:
    """Binned errors of scored predictions on one set, all on the same bins.

    Args:
        results: scored predictions of one benchmark and split, each holding ``set_name``.
        labels: one name per result.
        set_name: the set whose examples are binned.
        error: ``"absolute"`` (metres) or ``"percent"``.
        bins: a number of equal-width bins over the set's depth range, or the edges.

    Returns:
        One curve per result, in order.

    Raises:
        UsageError: an unknown ``error``, no results, a label count that differs, results
            of different benchmarks or splits, or a result without ``set_name``.
    """
    if error not in ERRORS:
        raise UsageError(f"unknown error {error!r}; expected one of {', '.join(ERRORS)}")
    if not results:
        raise UsageError("no predictions to plot")
    if len(labels) != len(results):
        raise UsageError(f"{len(labels)} labels for {len(results)} predictions files; give one per file")
    problems = [
        f"{r.provenance.get('predictions_file', i + 1)} has no estimates for set {set_name!r}"
        for i, r in enumerate(results)
        if set_name not in r.sets
    ]
    kinds = {(r.benchmark, r.split) for r in results}
    if len(kinds) > 1:
        problems.append(
            "the files are for different benchmarks or splits: "
            + ", ".join(f"{b} {s}" for b, s in sorted(kinds))
        )
    if problems:
        raise UsageError("cannot plot these predictions together", problems)
    func, _ = ERRORS[error]
    depth = results[0].examples[set_name].depth
    edges = bin_edges(depth, bins)
    curves = []
    for label, r in zip(labels, results, strict=True):
        truth = r.examples[set_name].depth
        errs = func(truth, r.predictions[set_name])
        curves.append(
            ErrorCurve(
                label=label,
                bins=binned_errors(truth, errs, edges),
                set_mean=float(errs.mean()),
                n=int(truth.size),
            )
        )
    return curves


def format_curves_csv(
    curves: Sequence[ErrorCurve], *, benchmark: str, split: str, set_name: str, error: str
) -> str:
    """The binned numbers as CSV (:data:`CSV_COLUMNS`), one row per curve and bin.

    Floats are written with ``repr`` precision, so the numbers read back exactly; an
    empty bin's statistics are empty cells.
    """
    unit = ERRORS[error][1]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for c in curves:
        b = c.bins
        for i in range(b.counts.size):
            stats = [b.mean[i], b.median[i], b.q25[i], b.q75[i]]
            w.writerow(
                [
                    c.label,
                    benchmark,
                    split,
                    set_name,
                    error,
                    unit,
                    i,
                    repr(float(b.edges[i])),
                    repr(float(b.edges[i + 1])),
                    int(b.counts[i]),
                ]
                + ["" if np.isnan(v) else repr(float(v)) for v in stats]
            )
    return out.getvalue()


__all__ = [
    "CSV_COLUMNS",
    "DEFAULT_BINS",
    "ERRORS",
    "DepthBins",
    "ErrorCurve",
    "MAX_BINS",
    "bin_edges",
    "binned_errors",
    "error_curves",
    "format_curves_csv",
    "parse_bins",
]
