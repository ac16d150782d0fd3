"""Error bars for any method, calibrated on the val split only: split conformal prediction.

A method gives a depth ``Z^`` per example and, if it can, a *spread* ``s`` (its own
relative uncertainty: ``predict_spread(examples, **options) -> (N,)``, positive and
unitless, e.g. the posterior standard deviation of ``log Z``; a method without one has
``s = 1`` everywhere). The calibration runs the method on the **val** sets, never test,
and takes the relative residuals scaled by the spread::

    r_i = |Z_i - Z^_i| / (|Z^_i| s_i)

For a level ``L`` (0.9 for a 90 % interval) the calibrated factor ``q`` is the
``ceil((n + 1) L)``-th smallest of the ``n`` val residuals of a set (split conformal
prediction: Vovk et al. 2005; Lei et al. 2018, "Distribution-free predictive inference
for regression"), and the interval of a new example is::

    depth_lo = max(Z^ (1 - q s), 0)        depth_hi = Z^ (1 + q s)

When the val and test examples of a set are exchangeable (drawn alike, as the seeded
ODMD sets are), the interval covers the true depth with probability at least ``L``
(and at most ``L + 1 / (n + 1)`` with continuous residuals): an honest interval without
any model of the errors. The spread only decides how the width is shared among the
examples (wider where the method itself is unsure), which makes intervals sharper
without touching the guarantee. ``depth_std``, the standard deviation of the stated
normal, is the one whose central interval at ``L`` has the same half-width:
``q s |Z^| / Phi^-1((1 + L) / 2)``.

A factor is fitted per set (for benchmark runs, where a test set has its val twin) and
pooled over all val sets (``"all"``, for a user's own data). For a method with a spread,
each set (and the pool) keeps the spread or drops it (``s = 1``), whichever gives the
lower mean interval score on its val examples: a spread that does not follow the
method's errors (a model of the box sizes alone, say, for a method that reads parallax
too) would only make the intervals wider where they need not be. That choice is made
on val as well, so test is never looked at. An estimate of 0 (a
method's fallback) gets the interval ``[0, 0]``: it has no scale to be relative to.

Why by hand: the method is a quantile of residuals (a few lines of numpy); the
conformal libraries (MAPIE, crepes) wrap scikit-learn estimators, which a method here
is not.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odmd_bench.errors import UsageError

#: The key of the factor pooled over every val set.
POOLED = "all"


def conformal_quantile(scores: Any, level: float) -> float:
    """The ``ceil((n + 1) level)``-th smallest of ``n`` scores (split conformal prediction).

    Raises:
        UsageError: ``level`` not in (0, 1), or too few scores for it
            (``ceil((n + 1) level) > n``).

    Example:
        >>> conformal_quantile([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9], 0.8)
        0.8
    """
    r = np.sort(np.asarray(scores, dtype=np.float64).ravel())
    if not 0 < level < 1:
        raise UsageError(f"level must be in (0, 1), got {level!r}")
    k = math.ceil((r.size + 1) * level)
    if k > r.size:
        raise UsageError(f"{r.size} calibration examples are too few for level {level:g} (need {k})")
    return float(r[k - 1])


def relative_residuals(truth: Any, depth: Any, spread: Any) -> np.ndarray:
    """``|Z - Z^| / (|Z^| s)`` per example; infinite where ``Z^`` is 0.

    Example:
        >>> relative_residuals([10.0, 10.0], [8.0, 0.0], [0.5, 1.0]).tolist()
        [0.5, inf]
    """
    z, d, s = (np.asarray(a, dtype=np.float64) for a in (truth, depth, spread))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.abs(z - d) / (np.abs(d) * s)
    return np.where(np.isnan(r), np.inf, r)


@dataclass(frozen=True)
class IntervalCalibration:
    """Factors of the conformal intervals of one method at one level (see the module docstring).

    Attributes:
        level: the nominal coverage.
        factors: ``{set: q}`` per val set, and ``"all"`` pooled.
        sizes: ``{set: n}`` the val examples each factor was fitted on.
        source: what it was fitted on, e.g. ``"odmd-v1 val"``.
        spread: ``{set: True}`` where the method's spread is used, False where ``s = 1``.
        content_sha256: ``{set: SHA-256}`` of the val sets' content.
    """

    level: float
    factors: dict[str, float]
    sizes: dict[str, int]
    source: str
    spread: dict[str, bool] = field(default_factory=dict)
    content_sha256: dict[str, str] = field(default_factory=dict)

    def intervals(self, depth: Any, spread: Any = None, key: str = POOLED) -> dict[str, np.ndarray]:
        """``{"depth_lo", "depth_hi", "depth_std"}`` (N,) for estimates ``depth`` (N,).

        Args:
            depth: (N,) the method's depths.
            spread: (N,) its spread (None: 1).
            key: the set whose factor applies (default: pooled; a set the calibration
                does not have gets the pooled factor).
        """
        key = key if key in self.factors else POOLED
        d = np.asarray(depth, dtype=np.float64)
        use = spread is not None and self.spread.get(key, False)
        s = np.asarray(spread, dtype=np.float64) if use else np.ones_like(d)
        q = self.factors[key]
        half = q * s * np.abs(d)
        lo = np.maximum(d - half, 0.0)
        hi = np.maximum(d + half, 0.0)
        z = _normal_quantile(0.5 + self.level / 2)
        return {"depth_lo": lo, "depth_hi": hi, "depth_std": half / z}

    def describe(self) -> str:
        """One line: the level, the source and the factors."""
        parts = ", ".join(
            f"{k} {v:.4g}{' x spread' if self.spread.get(k) else ''}" for k, v in self.factors.items()
        )
        return f"{self.level:g} intervals calibrated on {self.source}: factors {parts}"


def _normal_quantile(p: float) -> float:
    from odmd_bench.evaluation.uncertainty import normal_quantile

    return normal_quantile(p)


def fit_calibration(
    truth: Mapping[str, Any],
    depth: Mapping[str, Any],
    spread: Mapping[str, Any] | None,
    level: float,
    *,
    source: str,
) -> IntervalCalibration:
    """Fit the factors on val sets: ``{set: (N,)}`` true depths, estimates and spreads.

    Example:
        >>> z = {"a": np.full(9, 10.0)}
        >>> c = fit_calibration(z, {"a": np.arange(6.0, 15.0)}, None, 0.8, source="toy")
        >>> c.factors, c.intervals(np.array([10.0]), key="a")["depth_hi"].tolist()
        ({'a': 0.42857142857142855, 'all': 0.42857142857142855}, [14.285714285714285])
    """
    factors, sizes, used = {}, {}, {}
    for k in [*depth, POOLED]:
        z, d = _joined(truth, depth, k), _joined(depth, depth, k)
        choices = [(False, np.ones(np.shape(d)))]
        if spread is not None:
            choices.append((True, _joined(spread, depth, k)))
        best: tuple[float, float, bool] | None = None
        for uses, sp in choices:
            q = conformal_quantile(relative_residuals(z, d, sp), level)
            score = _val_interval_score(z, d, q * sp, level)
            if best is None or score < best[0]:
                best = (score, q, uses)
        if best is not None:
            _, factors[k], used[k] = best
        sizes[k] = int(np.size(d))
    return IntervalCalibration(level, factors, sizes, source, used)


def _joined(values: Mapping[str, Any], sets: Mapping[str, Any], key: str) -> np.ndarray:
    """``values[key]``, or every set's values end to end for the pooled key."""
    if key == POOLED:
        return np.concatenate([np.asarray(values[s], dtype=np.float64) for s in sets])
    return np.asarray(values[key], dtype=np.float64)


def _val_interval_score(truth: np.ndarray, depth: np.ndarray, rel_half: np.ndarray, level: float) -> float:
    """Mean interval score on the val examples of the intervals ``depth (1 -+ rel_half)``."""
    from odmd_bench.evaluation.uncertainty import interval_score

    with np.errstate(invalid="ignore"):
        half = rel_half * np.abs(depth)
    if not np.isfinite(half).all():
        return math.inf
    lo, hi = np.maximum(depth - half, 0.0), np.maximum(depth + half, 0.0)
    return float(np.mean(interval_score(truth, lo, hi, level)))


def method_spread(method: Any, examples: Any, options: Mapping[str, Any]) -> np.ndarray | None:
    """The method's spread (N,) on ``examples`` (never the truth), or None if it gives none.

    Raises:
        RuntimeError: a spread that is not (N,), finite and positive (a bug of the method).
    """
    if method.spread is None:
        return None
    s = np.asarray(method.spread(examples.without_truth(), **options), dtype=np.float64)
    if s.shape != (len(examples),) or not np.isfinite(s).all() or (s <= 0).any():
        raise RuntimeError(f"method {method.name!r} gave a spread that is not (N,), finite and positive")
    return s


def calibrate_method(
    method: Any,
    options: Mapping[str, Any],
    benchmark: Any,
    level: float,
    data_dir: str | os.PathLike[str] | None = None,
) -> IntervalCalibration:
    """Run ``method`` on the **val** sets of ``benchmark`` and fit its interval factors there.

    The sets are loaded (their content hashes verified) and the method sees them without
    their true depths, as ``odmd-bench baseline`` runs it; the true depths enter only the
    residuals.
    """
    from odmd_bench.data.store import load_split

    sets = load_split("val", benchmark, data_dir)
    truth, depth, spread = {}, {}, {}
    for s, ex in sets.items():
        depth[s], _ = method.run(ex, **options)
        truth[s] = ex.depth
        spread[s] = method_spread(method, ex, options)
    given = None if any(v is None for v in spread.values()) else spread
    name = getattr(benchmark, "name", benchmark)
    c = fit_calibration(truth, depth, given, level, source=f"{name} val")
    hashes = {s: str(ex.attrs.get("content_sha256", "")) for s, ex in sets.items()}
    return IntervalCalibration(c.level, c.factors, c.sizes, c.source, c.spread, hashes)


__all__ = [
    "POOLED",
    "IntervalCalibration",
    "calibrate_method",
    "conformal_quantile",
    "fit_calibration",
    "method_spread",
    "relative_residuals",
]
