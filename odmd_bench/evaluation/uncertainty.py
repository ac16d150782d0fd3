"""Depth with error bars: the optional uncertainty columns and the rules that score them.

A predictions file may carry, beside ``depth``, a central interval ``depth_lo``,
``depth_hi`` with its nominal coverage ``level`` (the same on every row), and/or
``depth_std``, the standard deviation of a normal predictive distribution centred on
``depth`` (docs/format.md, "Uncertainty"; docs/uncertainty.md explains each rule with a
worked example). This module holds the columns' checks and the scores, pure functions
over arrays; every score is in percent of the true depth ``Z``, as the percent error is:

- **coverage**: the share of examples with ``depth_lo <= Z <= depth_hi``, and its
  distance from ``level`` (too narrow intervals cover less than they claim);
- **sharpness**: the interval's width ``(hi - lo) / Z * 100``;
- **interval score** (Gneiting and Raftery 2007, eq. 43), with ``a = 1 - level``:
  ``((hi - lo) + 2/a (lo - Z)+ + 2/a (Z - hi)+) / Z * 100``: the width, plus a penalty
  for every miss that grows with its distance; proper, so a forecaster scores best by
  stating its true quantiles (too wide pays in width, too narrow in misses);
- **CRPS** of the normal ``N(depth, depth_std^2)`` (Gneiting and Raftery 2007, eq. 5;
  closed form of Gneiting et al. 2005): ``s (u (2 Phi(u) - 1) + 2 phi(u) - 1/sqrt(pi))``
  with ``u = (Z - depth) / s``, in percent of ``Z``; with ``s = 0`` it is the absolute
  error.

Why by hand: scipy (a dev-only dependency, the tests' cross-check) is not a dependency
of the evaluator, and these are a few lines of numpy; ``Phi`` comes from the standard
library's ``math.erf``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from odmd_bench.errors import UsageError
from odmd_bench.evaluation.metrics import summarize
from odmd_bench.inputs.bounds import MAX_ABS_DEPTH
from odmd_bench.inputs.problems import Problems, plural

#: The optional uncertainty columns, in the order they are written.
INTERVAL_COLUMNS: tuple[str, ...] = ("depth_lo", "depth_hi", "level")
SPREAD_COLUMNS: tuple[str, ...] = ("depth_std",)
UNCERTAINTY_COLUMNS: tuple[str, ...] = INTERVAL_COLUMNS + SPREAD_COLUMNS
#: The levels of the reliability diagram (coverage of the normal's central intervals).
RELIABILITY_LEVELS: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99)

_erf = np.frompyfunc(math.erf, 1, 1)


def header_problems(cols: Mapping[str, int], problems: Problems) -> None:
    """Add a problem for every incomplete set of uncertainty columns in a header."""
    have = [c for c in INTERVAL_COLUMNS if c in cols]
    if have and len(have) < len(INTERVAL_COLUMNS):
        lacking = [c for c in INTERVAL_COLUMNS if c not in cols]
        problems.add(
            f"the interval columns come together: the header has {', '.join(have)} but not "
            f"{', '.join(lacking)} (depth_lo, depth_hi and level, the interval's nominal coverage)"
        )


def check_values(values: Mapping[str, np.ndarray], lines: np.ndarray, problems: Problems) -> float | None:
    """Check the uncertainty cells of every row; return the interval's level (None: no interval).

    Args:
        values: ``{column: (R,) float64}`` of the columns present, NaN where a cell is
            not a number (already reported by the reader).
        lines: (R,) each row's line in the file.
        problems: where each problem is added, located by line (``at`` its first line).

    Returns:
        The one level of the file, or None without interval columns or when the level
        is wrong (a problem then says why).
    """
    for c in ("depth_lo", "depth_hi", "depth_std"):
        if c not in values:
            continue
        v = values[c]
        _add(problems, f"{c} is NaN or infinite", np.isinf(v), lines, v)
        _add(problems, f"{c} is negative", v < 0, lines, v)
        _add(
            problems,
            f"{c} is out of range (> {MAX_ABS_DEPTH:.0e} m)",
            np.isfinite(v) & (v > MAX_ABS_DEPTH),
            lines,
            v,
        )
    if "level" not in values:
        return None
    lo, hi, level = values["depth_lo"], values["depth_hi"], values["level"]
    _add(problems, "depth_lo is above depth_hi (an inverted interval)", lo > hi, lines, None, (lo, hi))
    outside = ~np.isnan(level) & ~((level > 0) & (level < 1))
    _add(
        problems, "level is outside (0, 1) (the interval's nominal coverage, e.g. 0.9)", outside, lines, level
    )
    good = level[(level > 0) & (level < 1)]
    if good.size == 0:
        return None
    found, first, counts = np.unique(good, return_index=True, return_counts=True)
    if found.size > 1:
        at = lines[(level > 0) & (level < 1)]
        order = np.argsort(first)
        parts = [
            f"{float(found[k])!r} ({plural(int(counts[k]), 'row')}, first on line {int(at[first[k]])})"
            for k in order
        ]
        problems.add(
            f"level varies between rows: {', '.join(parts[:5])}" + (", ..." if len(parts) > 5 else ""),
            note="a file states one level, the same on every row",
            at=int(at[first[order[1]]]),
        )
        return None
    return float(found[0])


def _add(
    problems: Problems,
    kind: str,
    mask: np.ndarray,
    lines: np.ndarray,
    cells: np.ndarray | None,
    pair: tuple[np.ndarray, np.ndarray] | None = None,
) -> None:
    """Count the rows of ``mask`` as ``kind``, the first three located with their cells."""
    hit = np.flatnonzero(mask)
    if not hit.size:
        return
    for i in hit[:3]:
        if pair is not None:
            shown = f"{float(pair[0][i])!r} > {float(pair[1][i])!r}"
        else:
            shown = repr(float(cells[i])) if cells is not None else ""
        problems.add(kind, f"line {int(lines[i])} ({shown})", at=int(lines[hit[0]]))
    if hit.size > 3:
        problems.add(kind, count=int(hit.size - 3))


# --- the scores ---------------------------------------------------------------------


def _check(y_true: Any, *arrays: Any) -> list[np.ndarray]:
    t = np.asarray(y_true, dtype=np.float64)
    out = [t] + [np.asarray(a, dtype=np.float64) for a in arrays]
    if t.ndim != 1 or any(a.shape != t.shape for a in out):
        raise UsageError(f"arrays must be 1-D of one length, got shapes {[a.shape for a in out]}")
    if not np.isfinite(t).all() or (t.size and t.min() <= 0):
        raise UsageError("true depths must be finite and > 0")
    if not all(np.isfinite(a).all() for a in out[1:]):
        raise UsageError("the predicted values must be finite")
    return out


def _alpha(level: float) -> float:
    if not 0 < level < 1:
        raise UsageError(f"level must be in (0, 1), got {level!r}")
    return 1.0 - level


def interval_score(y_true: Any, lo: Any, hi: Any, level: float) -> np.ndarray:
    """Per-example interval score (Gneiting and Raftery 2007), in percent of the true depth.

    ``((hi - lo) + 2/a (lo - Z)+ + 2/a (Z - hi)+) / Z * 100`` with ``a = 1 - level``.

    Example:
        >>> interval_score([10.0, 10.0, 10.0], [9.0, 11.0, 8.0], [11.0, 12.0, 9.0], 0.9).round(9).tolist()
        [20.0, 210.0, 210.0]
    """
    z, lo_, hi_ = _check(y_true, lo, hi)
    a = _alpha(level)
    penalty = (2.0 / a) * (np.maximum(lo_ - z, 0.0) + np.maximum(z - hi_, 0.0))
    return ((hi_ - lo_) + penalty) / z * 100.0


def interval_width(y_true: Any, lo: Any, hi: Any) -> np.ndarray:
    """Per-example width ``(hi - lo) / Z * 100`` (sharpness: smaller is sharper).

    Example:
        >>> interval_width([10.0], [9.0], [11.0]).tolist()
        [20.0]
    """
    z, lo_, hi_ = _check(y_true, lo, hi)
    return (hi_ - lo_) / z * 100.0


def covered(y_true: Any, lo: Any, hi: Any) -> np.ndarray:
    """Per example, whether ``lo <= Z <= hi`` (bounds included).

    Example:
        >>> covered([10.0, 10.0, 10.0], [9.0, 10.0, 11.0], [11.0, 12.0, 12.0]).tolist()
        [True, True, False]
    """
    z, lo_, hi_ = _check(y_true, lo, hi)
    return (lo_ <= z) & (z <= hi_)


def normal_cdf(u: np.ndarray) -> np.ndarray:
    """``Phi(u)``, the standard normal distribution function, elementwise (``math.erf``)."""
    u = np.asarray(u, dtype=np.float64)
    erf = np.asarray(_erf(u / math.sqrt(2.0)), dtype=np.float64)
    return 0.5 * (1.0 + erf)


def crps_normal(y_true: Any, mean: Any, std: Any) -> np.ndarray:
    """Per-example CRPS of ``N(mean, std^2)`` at the true depth, in percent of it.

    ``std * (u (2 Phi(u) - 1) + 2 phi(u) - 1/sqrt(pi))``, ``u = (Z - mean) / std``;
    the absolute error where ``std`` is 0.

    Example:
        >>> crps_normal([10.0, 10.0], [10.0, 9.0], [1.0, 0.0]).round(9).tolist()
        [2.336949773, 10.0]
    """
    z, mu, s = _check(y_true, mean, std)
    if (s < 0).any():
        raise UsageError("std must be >= 0")
    pos = s > 0
    safe = np.where(pos, s, 1.0)
    u = (z - mu) / safe
    phi = np.exp(-0.5 * u * u) / math.sqrt(2.0 * math.pi)
    crps = safe * (u * (2.0 * normal_cdf(u) - 1.0) + 2.0 * phi - 1.0 / math.sqrt(math.pi))
    return np.where(pos, crps, np.abs(z - mu)) / z * 100.0


def normal_quantile(p: float) -> float:
    """``Phi^-1(p)`` for ``0 < p < 1``, by bisection on :func:`normal_cdf` (to 1e-12).

    Example:
        >>> round(normal_quantile(0.95), 6)
        1.644854
    """
    if not 0 < p < 1:
        raise UsageError(f"p must be in (0, 1), got {p!r}")
    lo, hi = -40.0, 40.0
    while hi - lo > 1e-12:
        mid = 0.5 * (lo + hi)
        if 0.5 * (1.0 + math.erf(mid / math.sqrt(2.0))) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def reliability(
    y_true: Any, mean: Any, std: Any, levels: tuple[float, ...] = RELIABILITY_LEVELS
) -> list[float]:
    """Coverage of the normal's central interval at each level (the reliability diagram's points).

    A calibrated spread covers ``level`` of the examples at every level.

    Example:
        >>> reliability([10.0, 10.0], [10.0, 12.0], [1.0, 1.0], (0.5, 0.99))
        [0.5, 1.0]
    """
    z, mu, s = _check(y_true, mean, std)
    u = np.abs(z - mu)
    return [float(np.mean(u <= normal_quantile(0.5 + p / 2) * s)) for p in levels]


def set_scores(
    y_true: np.ndarray, depth: np.ndarray, columns: Mapping[str, np.ndarray], level: float | None
) -> dict[str, Any]:
    """The uncertainty scores of one set (the keys beside ``percent_error`` in its result).

    Args:
        y_true: (N,) true depths.
        depth: (N,) the point estimates (the normal's centre).
        columns: ``{column: (N,)}`` of the uncertainty columns present.
        level: the interval's level, or None without an interval.

    Returns:
        ``coverage`` (``level``, ``observed``, ``error`` = observed - level, ``below``
        and ``above``: the shares missed on each side), ``sharpness``, ``interval_score``
        (each summarised as the percent error is), with an interval; ``crps`` with a spread.
    """
    z = np.asarray(y_true, dtype=np.float64)
    out: dict[str, Any] = {}
    per_example: dict[str, np.ndarray] = {}  # each summarised below, as the percent error is
    # The columns were checked by the reader (finite, >= 0, lo <= hi): computed here at
    # once, without the public functions' checks of every array (the same formulas).
    if level is not None:
        lo, hi = columns["depth_lo"], columns["depth_hi"]
        below, above = z < lo, z > hi
        observed = float(np.count_nonzero(~(below | above))) / z.size
        out["coverage"] = {
            "level": level,
            "observed": observed,
            "error": observed - level,
            "below": float(np.count_nonzero(below)) / z.size,
            "above": float(np.count_nonzero(above)) / z.size,
        }
        width = hi - lo
        miss = np.maximum(lo - z, 0.0)
        miss += np.maximum(z - hi, 0.0)
        per_example["sharpness"] = width / z * 100.0
        per_example["interval_score"] = (width + (2.0 / _alpha(level)) * miss) / z * 100.0
    if "depth_std" in columns:
        per_example["crps"] = crps_normal(z, depth, columns["depth_std"])
    for name, errors in per_example.items():
        out[name] = summarize(errors)
    return out


def all_scores(sets: Mapping[str, Mapping[str, Any]]) -> dict[str, float]:
    """``All`` of the uncertainty scores: the unweighted mean over the sets, as for percent error.

    Example:
        >>> s = {"a": {"crps": {"mean": 1.0}}, "b": {"crps": {"mean": 3.0}}}
        >>> all_scores(s)
        {'crps_mean': 2.0}
    """
    first = next(iter(sets.values()), {})
    out: dict[str, float] = {}
    if "coverage" in first:
        out["coverage"] = float(np.mean([m["coverage"]["observed"] for m in sets.values()]))
        out["coverage_error"] = out["coverage"] - float(first["coverage"]["level"])
        out["sharpness_mean"] = float(np.mean([m["sharpness"]["mean"] for m in sets.values()]))
        out["interval_score_mean"] = float(np.mean([m["interval_score"]["mean"] for m in sets.values()]))
    if "crps" in first:
        out["crps_mean"] = float(np.mean([m["crps"]["mean"] for m in sets.values()]))
    return out
