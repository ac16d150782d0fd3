"""The benchmark's metrics (docs/format.md, "Metrics"): pure functions over arrays.

``*_error`` means lower is better. Every function checks its inputs the same way
(:func:`check_depths`), returns new arrays or plain floats, and never changes its
arguments. Percent error is ``|Z - Z_hat| / Z * 100``, absolute error ``|Z - Z_hat|``
(metres); per set each is summarised by mean, median, min, max and the population
standard deviation (``ddof = 0``, as in the paper's tables). ``All`` is the mean of the
sets' mean percent errors (the paper's "All Sets"), not the mean over all examples.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from odmd_bench.errors import UsageError

#: The summary statistics reported for every error, in table order.
STATS: tuple[str, ...] = ("mean", "median", "min", "max", "std")


def check_depths(y_true: Any, y_pred: Any) -> tuple[np.ndarray, np.ndarray]:
    """Return ``y_true`` and ``y_pred`` as 1-D float64 arrays of the same length.

    Args:
        y_true: (N,) true depths, finite and strictly positive.
        y_pred: (N,) estimated depths, finite (zero and negative estimates are legal).

    Raises:
        UsageError: the shapes differ, an array is not 1-D, a value is not finite, or a
            true depth is not positive.
    """
    t = np.asarray(y_true, dtype=np.float64)
    p = np.asarray(y_pred, dtype=np.float64)
    problems = []
    if t.ndim != 1 or p.ndim != 1:
        problems.append(f"depths must be 1-D, got shapes {t.shape} and {p.shape}")
    elif t.shape != p.shape:
        problems.append(f"y_true has {t.shape[0]} values, y_pred {p.shape[0]}")
    if not np.isfinite(t).all() or (t.size and np.min(t) <= 0):
        problems.append("true depths must be finite and > 0")
    if not np.isfinite(p).all():
        problems.append("estimated depths must be finite")
    if problems:
        raise UsageError("cannot compute depth errors", problems)
    return t, p


def absolute_error(y_true: Any, y_pred: Any) -> np.ndarray:
    """Per-example absolute depth error ``|Z - Z_hat|`` in metres, (N,) from two (N,) arrays.

    Example:
        >>> absolute_error([2.0, 1.0], [1.5, 1.25]).tolist()
        [0.5, 0.25]
    """
    t, p = check_depths(y_true, y_pred)
    return np.abs(t - p)


def percent_error(y_true: Any, y_pred: Any) -> np.ndarray:
    """Per-example percent depth error ``|Z - Z_hat| / Z * 100``, (N,) from two (N,) arrays.

    Example:
        >>> percent_error([2.0, 1.0], [1.5, 1.25]).tolist()
        [25.0, 25.0]
        >>> percent_error([1.0], [-1.0]).tolist()  # a negative estimate is a legal (bad) one
        [200.0]
    """
    t, p = check_depths(y_true, y_pred)
    return np.abs(t - p) / t * 100.0


def summarize(errors: Any) -> dict[str, float]:
    """Mean, median, min, max and population std (``ddof = 0``) of per-example errors.

    Args:
        errors: (N,) errors, N >= 1.

    Returns:
        ``{"mean", "median", "min", "max", "std"}`` as Python floats.

    Example:
        >>> summarize([0.0, 1.0, 2.0, 5.0])
        {'mean': 2.0, 'median': 1.5, 'min': 0.0, 'max': 5.0, 'std': 1.8708286933869707}
    """
    e = np.asarray(errors, dtype=np.float64)
    if e.ndim != 1 or e.size == 0:
        raise UsageError(f"errors must be a non-empty 1-D array, got shape {e.shape}")
    return {
        "mean": float(np.mean(e)),
        "median": float(np.median(e)),
        "min": float(np.min(e)),
        "max": float(np.max(e)),
        "std": float(np.std(e, ddof=0)),
    }


def set_metrics(y_true: Any, y_pred: Any) -> dict[str, Any]:
    """Everything reported for one set: size and both errors summarised.

    Args:
        y_true: (N,) true depths.
        y_pred: (N,) estimated depths.

    Returns:
        ``{"n": N, "percent_error": summary, "absolute_error": summary}`` with each
        summary as returned by :func:`summarize`.

    Example:
        >>> m = set_metrics([1.0, 2.0], [1.1, 2.0])
        >>> m["n"], round(m["percent_error"]["mean"], 12), m["absolute_error"]["min"]
        (2, 5.0, 0.0)
    """
    t, p = check_depths(y_true, y_pred)
    return {
        "n": int(t.size),
        "percent_error": summarize(percent_error(t, p)),
        "absolute_error": summarize(absolute_error(t, p)),
    }


def all_sets_mean(set_means: Mapping[str, float]) -> float:
    """``All``: the unweighted mean of the sets' mean percent errors (the paper's "All Sets").

    Args:
        set_means: set name -> that set's mean percent error.

    Example:
        >>> all_sets_mean({"normal": 0.0, "camera": 4.0, "object": 20.0, "robot": 20.0})
        11.0
    """
    if not set_means:
        raise UsageError("All needs at least one set")
    return float(np.mean(np.asarray(list(set_means.values()), dtype=np.float64)))
