"""What evaluation produces: validated predictions and their scores, as data.

Formatting for people is :mod:`odmd_bench.evaluation.report`'s job; here are the result
objects, their JSON dictionary and, for pandas users, their DataFrames (pandas is
imported only when a frame is asked for).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from odmd_bench.data.examples import Examples, fill_missing
from odmd_bench.evaluation.metrics import STATS, absolute_error, percent_error

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

#: Columns of the per-example table, in order.
PER_EXAMPLE_COLUMNS: tuple[str, ...] = (
    "set",
    "index",
    "prediction",
    "truth",
    "percent_error",
    "absolute_error",
    "n_detected",
    "camera_move",
    "box_w",
    "box_h",
    "box_area_mean",
)


@dataclass(frozen=True)
class Predictions:
    """Validated predictions, ready to score.

    Attributes:
        path: the file as given (or a name for arrays).
        sha256: SHA-256 of the CSV bytes (for arrays: of the CSV ``write_predictions``
            writes for them).
        benchmark: the benchmark.
        split: the split.
        depths: ``{set: (N,) float64}``, the estimate of example ``i`` at position ``i``,
            for the sets in scope.
        n_rows: number of data rows in the file.
        ignored_columns: columns other than the required and optional ones.
        warnings: legal but suspicious things (zero or negative depths, rows of sets
            that were not asked for), one line each.
        uncertainty: ``{set: {column: (N,) float64}}`` of the uncertainty columns the
            file has (:mod:`~odmd_bench.evaluation.uncertainty`), placed as ``depths``;
            empty without them.
        level: the interval's nominal coverage, or None without an interval.
    """

    path: str
    sha256: str
    benchmark: str
    split: str
    depths: dict[str, np.ndarray]
    n_rows: int
    ignored_columns: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    uncertainty: dict[str, dict[str, np.ndarray]] = field(default_factory=dict, repr=False)
    level: float | None = None


@dataclass(frozen=True)
class EvaluationResult:
    """Scores of one set of predictions, with what is needed to reproduce them.

    Attributes:
        benchmark: the benchmark scored.
        split: the split scored.
        sets: ``{set: {"n", "percent_error": {mean, median, min, max, std},
            "absolute_error": {...}}}`` in the benchmark's set order.
        all_percent_error_mean: ``All``, the mean of the sets' mean percent errors.
        provenance: package version, benchmark, split, each set's content SHA-256, the
            predictions' SHA-256 and name.
        warnings: one line each (see :class:`Predictions`).
        predictions: ``{set: (N,)}`` the estimates scored.
        examples: ``{set: Examples}`` the sets scored (truth and what explains errors).
        uncertainty: ``{set: {column: (N,)}}`` the uncertainty columns scored (empty
            without them); their scores are in ``sets`` (``coverage``, ``sharpness``,
            ``interval_score``, ``crps``) and ``all_uncertainty``.
        all_uncertainty: ``All`` of the uncertainty scores (the mean over the sets);
            empty without uncertainty columns.
    """

    benchmark: str
    split: str
    sets: dict[str, dict[str, Any]]
    all_percent_error_mean: float
    provenance: dict[str, Any]
    warnings: tuple[str, ...] = ()
    predictions: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    examples: dict[str, Examples] = field(default_factory=dict, repr=False)
    uncertainty: dict[str, dict[str, np.ndarray]] = field(default_factory=dict, repr=False)
    all_uncertainty: dict[str, float] = field(default_factory=dict)

    def percent_errors(self) -> dict[str, np.ndarray]:
        """``{set: (N,)}`` per-example percent errors."""
        return {s: percent_error(self.examples[s].depth, self.predictions[s]) for s in self.sets}

    def errors(self, metric: str = "percent_error", who: str = "the result") -> dict[str, np.ndarray]:
        """``{set: (N,)}`` per-example ``metric``: ``"percent_error"`` or ``"interval_score"``.

        Raises:
            UsageError: an unknown metric, or ``"interval_score"`` without an interval.
        """
        from odmd_bench.errors import UsageError
        from odmd_bench.evaluation.uncertainty import interval_score

        if metric == "percent_error":
            return self.percent_errors()
        if metric != "interval_score":
            raise UsageError(f"unknown metric {metric!r}; expected percent_error or interval_score")
        if not self.uncertainty or "coverage" not in next(iter(self.sets.values())):
            raise UsageError(
                f"{who} has no interval (columns depth_lo, depth_hi, level) to compare on interval_score"
            )
        return {
            s: interval_score(
                self.examples[s].depth,
                self.uncertainty[s]["depth_lo"],
                self.uncertainty[s]["depth_hi"],
                self.sets[s]["coverage"]["level"],
            )
            for s in self.sets
        }

    def to_dict(self) -> dict[str, Any]:
        """The JSON object ``evaluate --format json`` prints (docs/format.md), plus ``warnings``."""
        return {
            "benchmark": self.benchmark,
            "split": self.split,
            "sets": {s: dict(m) for s, m in self.sets.items()},
            "all": {
                "percent_error_mean": self.all_percent_error_mean,
                **self.all_uncertainty,
                "sets": list(self.sets),
            },
            "provenance": dict(self.provenance),
            "warnings": list(self.warnings),
        }

    def to_frame(self) -> pd.DataFrame:
        """One row per set, then ``All``, indexed by set name (needs pandas).

        Columns: ``n``, ``percent_error_<stat>`` and ``absolute_error_<stat>`` for each
        statistic (mean, median, min, max, std). The ``All`` row has the total ``n`` and
        ``percent_error_mean`` = All; its other cells are NaN.
        """
        import pandas as pd

        cols = ["n"] + [f"{e}_{k}" for e in ("percent_error", "absolute_error") for k in STATS]
        rows = [
            [m["n"]] + [m[e][k] for e in ("percent_error", "absolute_error") for k in STATS]
            for m in self.sets.values()
        ]
        total = sum(m["n"] for m in self.sets.values())
        rows.append([total, self.all_percent_error_mean] + [np.nan] * (len(cols) - 2))
        frame = pd.DataFrame(rows, columns=cols, index=pd.Index([*self.sets, "All"], name="set"))
        return frame.astype({"n": "int64"})

    def per_example(self) -> dict[str, np.ndarray]:
        """The per-example columns (:data:`PER_EXAMPLE_COLUMNS`) as ``(N_total,)`` arrays.

        With uncertainty columns, these follow: the file's ``depth_lo``, ``depth_hi``,
        ``depth_std``, and ``covered`` (1 or 0), ``interval_score`` and ``crps`` (percent
        of the true depth), each where the file has what it needs.

        ``camera_move`` is ``|c_1 - c_n|``, the distance in metres between the first and
        the last camera position. ``box_w`` and ``box_h`` are the last observation's box
        width and height (divided by the image width and height), taken from the nearest
        observation with a detection when the last has none (the shared missing-detection
        rule; 0 when the example has no detection at all). ``box_area_mean`` is the mean
        of ``w * h`` over the observations with a detection (0 when there is none).
        """
        parts: dict[str, list[np.ndarray]] = {c: [] for c in PER_EXAMPLE_COLUMNS}
        for s in self.sets:
            ex, pred = self.examples[s], self.predictions[s]
            n_det = ex.detected.sum(axis=1)
            boxes = fill_missing(ex.boxes, ex.detected)
            last = np.where((n_det > 0)[:, None], boxes[:, -1, 2:4], 0.0)
            area = ex.boxes[:, :, 2] * ex.boxes[:, :, 3]
            columns = {
                "set": np.full(len(ex), s, dtype=object),
                "index": np.arange(len(ex)),
                "prediction": pred,
                "truth": ex.depth,
                "percent_error": percent_error(ex.depth, pred),
                "absolute_error": absolute_error(ex.depth, pred),
                "n_detected": n_det,
                "camera_move": np.linalg.norm(ex.camera[:, 0, :] - ex.camera[:, -1, :], axis=1),
                "box_w": last[:, 0],
                "box_h": last[:, 1],
                "box_area_mean": np.where(
                    n_det > 0, (area * ex.detected).sum(axis=1) / np.maximum(n_det, 1), 0.0
                ),
            }
            if self.uncertainty:
                columns.update(_per_example_uncertainty(ex.depth, pred, self.uncertainty[s], self.sets[s]))
            for c in columns:
                parts.setdefault(c, []).append(columns[c])
        return {c: np.concatenate(v) if v else np.empty(0) for c, v in parts.items()}

    def per_example_frame(self) -> pd.DataFrame:
        """The per-example table (:meth:`per_example`) as a DataFrame (needs pandas)."""
        import pandas as pd

        cols = self.per_example()
        return pd.DataFrame(cols, columns=list(cols))


def _per_example_uncertainty(
    truth: np.ndarray, pred: np.ndarray, columns: dict[str, np.ndarray], metrics: dict[str, Any]
) -> dict[str, np.ndarray]:
    """The per-example uncertainty columns of one set (see :meth:`EvaluationResult.per_example`)."""
    from odmd_bench.evaluation.uncertainty import covered, crps_normal, interval_score

    out: dict[str, np.ndarray] = {
        c: columns[c] for c in ("depth_lo", "depth_hi", "depth_std") if c in columns
    }
    if "coverage" in metrics:
        lo, hi = columns["depth_lo"], columns["depth_hi"]
        out["covered"] = covered(truth, lo, hi).astype(np.int64)
        out["interval_score"] = interval_score(truth, lo, hi, metrics["coverage"]["level"])
    if "depth_std" in columns:
        out["crps"] = crps_normal(truth, pred, columns["depth_std"])
    return out
