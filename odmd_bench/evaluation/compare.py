"""Paired comparison of two methods on the same examples.

For each set, and for ``All``, the difference in mean percent error ``A - B`` (negative:
A is better), a seeded paired bootstrap interval for it, and a paired sign-flip
permutation test of "no difference". Both methods are scored on the very same examples,
so the comparison works on per-example differences ``d_i = e_A,i - e_B,i``:

- bootstrap: resample examples with replacement (the same resample for A and B), take
  the mean of ``d``; the interval is the 2.5 and 97.5 percentiles of those means. For
  ``All`` (the mean of the sets' means) each set is resampled within itself (stratified)
  and the resampled set means are averaged, as ``All`` is.
- test: under "no difference" each ``d_i`` is as likely to be ``+d_i`` as ``-d_i``;
  flipping signs at random gives the null distribution of the mean (of ``All``,
  flipping within every set). ``p = (1 + #{|T*| >= |T|}) / (1 + resamples)``.

The verdict is "A better" or "B better" only when the interval excludes 0 *and*
``p < 1 - confidence``; otherwise "not distinguishable". The test's smallest p-value is
``1 / (1 + resamples)``: settings where that is not below ``1 - confidence`` could never
find a difference, however large, so they are refused (:func:`resolution_problem`)
rather than answered "not distinguishable" beside an interval far from 0. Every set draws from its own
random stream, made from ``seed`` and the set's name, so a set's result does not depend
on which other sets are compared, and the same call gives the same numbers everywhere.
The leaderboard forms its rank groups with :func:`compare_errors`.
"""

from __future__ import annotations

import os
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.evaluation.result import EvaluationResult
from odmd_bench.evaluation.scoring import evaluate
from odmd_bench.inputs.source import Source

A_BETTER = "A better"
B_BETTER = "B better"
TIE = "not distinguishable"

#: Resamples are drawn this many at a time, to bound memory (chunk x N indices).
_CHUNK = 250
#: The most resamples a comparison draws (p-values to 1e-6; two float64 arrays of 8 MB).
MAX_RESAMPLES = 1_000_000


def smallest_p(n_resamples: int) -> float:
    """The smallest p-value the sign-flip test can give with ``n_resamples`` flips."""
    return 1 / (1 + n_resamples)


def minimum_resamples(confidence: float) -> int:
    """The fewest resamples whose smallest p-value is below ``1 - confidence`` (the test's threshold).

    Examples:
        >>> minimum_resamples(0.95), minimum_resamples(0.99), minimum_resamples(0.9999)
        (19, 99, 10000)
    """
    alpha = 1.0 - confidence
    n = max(1, int(1 / alpha) - 1)
    while smallest_p(n) >= alpha:  # the same comparison as the verdict's, float for float
        n += 1
    while n > 1 and smallest_p(n - 1) < alpha:
        n -= 1
    return n


def resolution_problem(n_resamples: int, confidence: float) -> str | None:
    r"""Why a comparison with these settings could never find a difference (None: it can).

    The verdict needs ``p < 1 - confidence`` and ``p`` is at least ``1 / (1 + n_resamples)``:
    when that floor is not below the threshold, every verdict would be "not distinguishable"
    whatever the interval says, and a gate resting on it could never fail.

    Examples:
        >>> resolution_problem(2000, 0.95) is None
        True
        >>> print(resolution_problem(10, 0.95).replace(": ", ":\n").replace("; ", ";\n"))
        10 resamples at confidence 0.95 can never find a difference:
        the test's smallest p-value, 1/(1 + 10) = 0.0909, is not below 1 - confidence = 0.05;
        use at least 19 resamples or a lower confidence
    """
    alpha = 1.0 - confidence
    if smallest_p(n_resamples) < alpha:
        return None
    return (
        f"{n_resamples} resamples at confidence {confidence:g} can never find a difference: the test's "
        f"smallest p-value, 1/(1 + {n_resamples}) = {smallest_p(n_resamples):.3g}, is not below "
        f"1 - confidence = {alpha:.3g}; use at least {minimum_resamples(confidence)} resamples or a "
        "lower confidence"
    )


@dataclass(frozen=True)
class PairedDifference:
    """The paired comparison of A and B on one set (or ``All``).

    Attributes:
        n: examples compared.
        mean_a, mean_b: mean percent error of A and B (for ``All``: mean of set means).
        difference: ``mean_a - mean_b``; negative when A's error is lower.
        ci_low, ci_high: bootstrap interval of ``difference`` at the chosen confidence.
        p_value: paired sign-flip permutation test of "no difference".
        verdict: ``"A better"``, ``"B better"`` or ``"not distinguishable"``.
    """

    n: int
    mean_a: float
    mean_b: float
    difference: float
    ci_low: float
    ci_high: float
    p_value: float
    verdict: str


@dataclass(frozen=True)
class Comparison:
    """Per-set and ``All`` comparisons plus how they were made."""

    sets: dict[str, PairedDifference]
    all: PairedDifference
    n_resamples: int
    seed: int
    confidence: float
    benchmark: str = ""
    split: str = ""
    provenance: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON object that ``compare --format json`` prints."""
        return {
            "benchmark": self.benchmark,
            "split": self.split,
            "metric": "percent_error_mean",
            "difference": "A - B",
            "sets": {s: asdict(d) for s, d in self.sets.items()},
            "all": asdict(self.all),
            "method": {
                "interval": "paired percentile bootstrap (stratified by set for All)",
                "test": "paired sign-flip permutation test (within each set for All)",
                "n_resamples": self.n_resamples,
                "seed": self.seed,
                "confidence": self.confidence,
            },
            "provenance": dict(self.provenance),
        }


def _rng(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(name.encode())])


def _draws(d: np.ndarray, n_resamples: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Bootstrap means and sign-flipped means of ``d``, each (n_resamples,)."""
    n = d.shape[0]
    boot = np.empty(n_resamples)
    flip = np.empty(n_resamples)
    for start in range(0, n_resamples, _CHUNK):
        k = min(_CHUNK, n_resamples - start)
        idx = rng.integers(0, n, size=(k, n), dtype=np.int32)
        boot[start : start + k] = d[idx].mean(axis=1)
        signs = rng.integers(0, 2, size=(k, n), dtype=np.int8).astype(np.float64) * 2.0 - 1.0
        flip[start : start + k] = signs @ d / n
    return boot, flip


def _summary(
    n: int,
    mean_a: float,
    mean_b: float,
    observed: float,
    boot: np.ndarray,
    flip: np.ndarray,
    confidence: float,
) -> PairedDifference:
    alpha = 1.0 - confidence
    lo, hi = np.quantile(boot, [alpha / 2, 1 - alpha / 2])
    # Ties with the observed statistic count as "as extreme" (up to rounding).
    tol = 1e-12 * max(1.0, abs(observed))
    p = (1 + int(np.count_nonzero(np.abs(flip) >= abs(observed) - tol))) / (1 + flip.shape[0])
    if hi < 0 and p < alpha:
        verdict = A_BETTER
    elif lo > 0 and p < alpha:
        verdict = B_BETTER
    else:
        verdict = TIE
    return PairedDifference(
        n=n,
        mean_a=mean_a,
        mean_b=mean_b,
        difference=observed,
        ci_low=float(lo),
        ci_high=float(hi),
        p_value=float(p),
        verdict=verdict,
    )


def compare_errors(
    errors_a: Mapping[str, Any],
    errors_b: Mapping[str, Any],
    *,
    n_resamples: int = 2000,
    seed: int = 0,
    confidence: float = 0.95,
) -> Comparison:
    """Compare two methods' per-example errors, set by set and for ``All``.

    Args:
        errors_a: ``{set name: (N_set,) errors}`` of A, per example (e.g. percent errors).
        errors_b: The same for B, on the same examples in the same order and the same sets.
        n_resamples: Number of bootstrap resamples and of sign flips.
        seed: Seed of the random streams (results are reproducible).
        confidence: Level of the interval, and ``1 -`` the test's threshold.

    Returns:
        The per-set and ``All`` comparison.

    Raises:
        UsageError: If the sets differ, an array is empty, not 1-D, of another shape or
            not finite, ``n_resamples`` or ``confidence`` is out of range, or together
            they could never find a difference (:func:`resolution_problem`).

    Example:
        >>> import numpy as np
        >>> a = {"normal": np.full(50, 1.0)}
        >>> b = {"normal": np.full(50, 1.0) + np.linspace(0.5, 1.5, 50)}
        >>> c = compare_errors(a, b)
        >>> c.sets["normal"].verdict, round(c.sets["normal"].difference, 6)
        ('A better', -1.0)
        >>> compare_errors(a, a).all.verdict
        'not distinguishable'
    """
    if list(errors_a) != list(errors_b):
        raise UsageError(f"A and B must cover the same sets; A has {list(errors_a)}, B has {list(errors_b)}")
    if not errors_a:
        raise UsageError("nothing to compare: no sets")
    if not 1 <= n_resamples <= MAX_RESAMPLES:
        raise UsageError(f"n_resamples must be between 1 and {MAX_RESAMPLES:,}, got {n_resamples}")
    if seed < 0:
        raise UsageError(f"seed must be >= 0, got {seed}")
    if not 0 < confidence < 1:
        raise UsageError(f"confidence must be between 0 and 1, got {confidence}")
    unable = resolution_problem(n_resamples, confidence)
    if unable is not None:
        raise UsageError(unable)
    per_set: dict[str, PairedDifference] = {}
    boots, flips, means_a, means_b = [], [], [], []
    for s in errors_a:
        ea = np.asarray(errors_a[s], dtype=np.float64)
        eb = np.asarray(errors_b[s], dtype=np.float64)
        if ea.ndim != 1 or ea.shape != eb.shape or ea.size == 0:
            raise UsageError(
                f"set {s!r}: A and B need the same non-empty 1-D errors, got {ea.shape} and {eb.shape}"
            )
        if not (np.isfinite(ea).all() and np.isfinite(eb).all()):
            raise UsageError(f"set {s!r}: errors must be finite")
        d = ea - eb
        boot, flip = _draws(d, n_resamples, _rng(seed, s))
        ma, mb = float(ea.mean()), float(eb.mean())
        per_set[s] = _summary(ea.size, ma, mb, float(d.mean()), boot, flip, confidence)
        boots.append(boot)
        flips.append(flip)
        means_a.append(ma)
        means_b.append(mb)
    all_a, all_b = float(np.mean(means_a)), float(np.mean(means_b))
    observed = float(np.mean([per_set[s].difference for s in per_set]))
    overall = _summary(
        sum(p.n for p in per_set.values()),
        all_a,
        all_b,
        observed,
        np.mean(boots, axis=0),
        np.mean(flips, axis=0),
        confidence,
    )
    return Comparison(sets=per_set, all=overall, n_resamples=n_resamples, seed=seed, confidence=confidence)


def compare_results(
    a: EvaluationResult,
    b: EvaluationResult,
    *,
    n_resamples: int = 2000,
    seed: int = 0,
    confidence: float = 0.95,
) -> Comparison:
    """Compare two evaluations of the same benchmark, split and sets (percent error)."""
    problems = []
    if (a.benchmark, a.split) != (b.benchmark, b.split):
        problems.append(f"A is {a.benchmark} {a.split}, B is {b.benchmark} {b.split}")
    if list(a.sets) != list(b.sets):
        problems.append(f"A covers the sets {', '.join(a.sets)}, B covers {', '.join(b.sets)}")
    ha, hb = a.provenance.get("sets_content_sha256", {}), b.provenance.get("sets_content_sha256", {})
    if not problems and ha != hb:
        problems.append("A and B were scored against different data (set content hashes differ)")
    if problems:
        raise UsageError("A and B cannot be compared", problems)
    c = compare_errors(
        a.percent_errors(), b.percent_errors(), n_resamples=n_resamples, seed=seed, confidence=confidence
    )
    provenance = {
        "version": a.provenance.get("version"),
        "sets_content_sha256": ha,
        "a": {k: a.provenance.get(k) for k in ("predictions_file", "predictions_sha256")},
        "b": {k: b.provenance.get(k) for k in ("predictions_file", "predictions_sha256")},
    }
    return Comparison(
        sets=c.sets,
        all=c.all,
        n_resamples=n_resamples,
        seed=seed,
        confidence=confidence,
        benchmark=a.benchmark,
        split=a.split,
        provenance=provenance,
    )


def compare_files(
    path_a: Source,
    path_b: Source,
    *,
    benchmark: str | None = None,
    data_dir: str | os.PathLike[str] | None = None,
    sets: Sequence[str] | None = None,
    n_resamples: int = 2000,
    seed: int = 0,
    confidence: float = 0.95,
    names: tuple[str | None, str | None] = (None, None),
) -> tuple[Comparison, EvaluationResult, EvaluationResult]:
    """Validate and score two predictions files, then compare them.

    Both files are validated before anything is compared; a :class:`ValidationError`
    names the problems of both, each line prefixed with ``A`` or ``B``. Each file is
    a path, bytes or a binary file (see :func:`~odmd_bench.evaluation.scoring.evaluate`);
    ``names`` name them in messages and provenance (default: the paths).

    Returns:
        ``(comparison, result of A, result of B)``.

    Raises:
        ValidationError: Naming the problems of both files.
        UsageError: If the two results cannot be compared (:func:`compare_results`).
    """
    results: list[EvaluationResult] = []
    problems: list[str] = []
    for label, path, name in (("A", path_a, names[0]), ("B", path_b, names[1])):
        try:
            results.append(evaluate(path, benchmark=benchmark, data_dir=data_dir, sets=sets, name=name))
        except ValidationError as e:
            shown = name or (str(path) if isinstance(path, (str, os.PathLike)) else "<input>")
            problems.extend(f"{label} ({shown}): {p}" for p in (e.problems or [e.message]))
    if problems:
        raise ValidationError("the predictions cannot be compared", problems)
    a, b = results
    c = compare_results(a, b, n_resamples=n_resamples, seed=seed, confidence=confidence)
    return c, a, b
