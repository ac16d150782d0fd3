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
rather than answered "not distinguishable" beside an interval far from 0. Every set draws
from its own random stream, made from ``seed`` and the set's name: a set's result does not
depend on which other sets are compared, and a call gives the same numbers everywhere.
The leaderboard forms its rank groups with :class:`Resampled`: the comparison of
:func:`compare_errors`, its draws made once for every pair of methods (and once for every
board of the same sets). The draws, p-values and intervals are the resampling engine's
(:mod:`odmd_bench.evaluation.resampling`); this module makes the verdicts.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.evaluation.resampling import (  # the engine; the names with noqa stay importable from here
    MAX_RESAMPLES,  # noqa: F401
    SharedDraws,
    minimum_resamples,  # noqa: F401
    named_stream,
    paired_draws,
    paired_means,
    percentile_interval,
    resolution_problem,
    sign_flip_p,
    smallest_p,  # noqa: F401
)
from odmd_bench.evaluation.result import EvaluationResult
from odmd_bench.evaluation.scoring import evaluate
from odmd_bench.inputs.source import Source

A_BETTER = "A better"
B_BETTER = "B better"
TIE = "not distinguishable"


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
    metric: str = "percent_error_mean"

    def to_dict(self) -> dict[str, Any]:
        """The JSON object that ``compare --format json`` prints."""
        return {
            "benchmark": self.benchmark,
            "split": self.split,
            "metric": self.metric,
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


def _summary(
    n: int, a: float, b: float, diff: float, boot: np.ndarray, flip: np.ndarray, confidence: float
) -> PairedDifference:
    alpha = 1.0 - confidence
    lo, hi = percentile_interval(boot, confidence)
    p = sign_flip_p(flip, diff)
    if hi < 0 and p < alpha:
        verdict = A_BETTER
    elif lo > 0 and p < alpha:
        verdict = B_BETTER
    else:
        verdict = TIE
    return PairedDifference(n, a, b, diff, float(lo), float(hi), float(p), verdict)


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
    _check_settings(errors_a, n_resamples, seed, confidence)
    per_set: dict[str, PairedDifference] = {}
    boots, flips = [], []
    for s in errors_a:
        ea, eb = _errors(s, errors_a[s], errors_b[s])
        d = ea - eb
        boot, flip = paired_draws(d, n_resamples, named_stream(seed, s))
        per_set[s] = _summary(
            ea.size, float(ea.mean()), float(eb.mean()), float(d.mean()), boot, flip, confidence
        )
        boots.append(boot)
        flips.append(flip)
    return _combine(per_set, boots, flips, n_resamples, seed, confidence)


def _check_settings(sets: Mapping[str, Any], n_resamples: int, seed: int, confidence: float) -> None:
    if not sets:
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


def _errors(s: str, *arrays: Any) -> list[np.ndarray]:
    """The errors of one set as float64, every array the same non-empty 1-D shape and finite."""
    out = [np.asarray(a, dtype=np.float64) for a in arrays]
    if any(e.ndim != 1 or e.shape != out[0].shape or e.size == 0 for e in out):
        shapes = " and ".join(str(e.shape) for e in out)
        who = "A and B need" if len(out) == 2 else "the methods need"
        raise UsageError(f"set {s!r}: {who} the same non-empty 1-D errors, got {shapes}")
    if not all(np.isfinite(e).all() for e in out):
        raise UsageError(f"set {s!r}: errors must be finite")
    return out


def _combine(
    per_set: dict[str, PairedDifference],
    boots: list[np.ndarray],
    flips: list[np.ndarray],
    n_resamples: int,
    seed: int,
    confidence: float,
) -> Comparison:
    """The comparison of ``All`` (stratified: the sets' resampled means averaged) beside the sets'."""
    overall = _summary(
        sum(p.n for p in per_set.values()),
        float(np.mean([p.mean_a for p in per_set.values()])),
        float(np.mean([p.mean_b for p in per_set.values()])),
        float(np.mean([p.difference for p in per_set.values()])),
        np.mean(boots, axis=0),
        np.mean(flips, axis=0),
        confidence,
    )
    return Comparison(sets=per_set, all=overall, n_resamples=n_resamples, seed=seed, confidence=confidence)


def compare_pairs(
    errors: Mapping[str, Mapping[str, Any]],
    pairs: Sequence[tuple[str, str]],
    *,
    n_resamples: int = 2000,
    seed: int = 0,
    confidence: float = 0.95,
) -> dict[tuple[str, str], Comparison]:
    """:func:`compare_errors` of ``errors[a]`` and ``errors[b]`` for each pair ``(a, b)``, drawn once.

    The bootstrap indices and sign flips depend only on the seed, the set and its size,
    never on the errors: each chunk is drawn once per set, as :func:`compare_errors` draws
    it, and applied to every pair at once (a resample's mean is its counts of each example
    times the differences, one matrix product for all pairs). The draws are the same, so
    the results equal :func:`compare_errors`'s up to floating-point rounding (the order of
    the sums), for one draw per set instead of one per pair.

    Args:
        errors: ``{method: {set name: (N_set,) errors}}``, the same sets and sizes for all.
        pairs: the ``(A, B)`` methods to compare.
        n_resamples: as :func:`compare_errors`.
        seed: as :func:`compare_errors`.
        confidence: as :func:`compare_errors`.

    Returns:
        ``{(a, b): Comparison}``, in the order of ``pairs``.

    Raises:
        UsageError: As :func:`compare_errors`.

    Example:
        >>> import numpy as np
        >>> e = {"x": {"s": np.linspace(1, 2, 40)}, "y": {"s": np.linspace(1, 2, 40) + 0.5}}
        >>> c = compare_pairs(e, [("x", "y")])[("x", "y")]
        >>> c.all.verdict, round(c.all.difference, 6), c.all.p_value == compare_errors(e["x"], e["y"]).all.p_value
        ('A better', -0.5, True)
    """
    pairs = list(dict.fromkeys(pairs))
    if not pairs:
        return {}
    used = list(dict.fromkeys(m for pair in pairs for m in pair))
    drawn = Resampled({m: errors[m] for m in used}, n_resamples=n_resamples, seed=seed, confidence=confidence)
    return {(a, b): drawn.compare(a, b) for a, b in pairs}


class Resampled:
    """Many methods' errors on the same examples, resampled once, for comparing any two of them.

    :func:`compare_errors` draws, for each set, a stream that depends on the seed and the
    set's name only: the resampled examples and the flipped signs are the same whatever
    the two methods are. Here each method's bootstrap and sign-flip means are computed
    once on that stream (:func:`~odmd_bench.evaluation.resampling.paired_means`: products
    of the resample counts and the signs with every method's errors at once), and a pair's means of differences are the differences of
    its two methods' means. :meth:`compare` so gives what :func:`compare_errors` gives
    for the pair (the same draws, none fewer), up to the order of floating-point
    additions (about 1e-15, relative); it is what the leaderboard ranks with.

    Args:
        errors: ``{method: {set name: (N_set,) errors}}``, every method on the same sets
            and examples.
        n_resamples, seed, confidence: as for :func:`compare_errors`.
        draws: where the draws are kept for other comparisons with the same settings
            (e.g. the other boards of the leaderboard), and read back from (the same
            results; default: drawn here).

    Raises:
        UsageError: As :func:`compare_errors` does.

    Example:
        >>> import numpy as np
        >>> e = np.linspace(1.0, 2.0, 50)
        >>> r = Resampled({"a": {"normal": e}, "b": {"normal": e + 1.0}, "c": {"normal": e}})
        >>> r.compare("a", "b").all.verdict, r.compare("a", "c").all.verdict
        ('A better', 'not distinguishable')
    """

    def __init__(
        self,
        errors: Mapping[str, Mapping[str, Any]],
        *,
        n_resamples: int = 2000,
        seed: int = 0,
        confidence: float = 0.95,
        draws: SharedDraws | None = None,
    ) -> None:
        methods = list(errors)
        sets = list(errors[methods[0]]) if methods else []
        _check_settings(dict.fromkeys(sets), n_resamples, seed, confidence)
        for m in methods:
            if list(errors[m]) != sets:
                raise UsageError(
                    f"every method must cover the same sets; {methods[0]} has {sets}, {m} has {list(errors[m])}"
                )
        self.methods = {m: i for i, m in enumerate(methods)}
        self.n_resamples, self.seed, self.confidence = n_resamples, seed, confidence
        self._errors: dict[str, np.ndarray] = {}
        self._boot: dict[str, np.ndarray] = {}
        self._flip: dict[str, np.ndarray] = {}
        for s in sets:
            e = np.stack(_errors(s, *(errors[m][s] for m in methods)))  # (M, N)
            self._errors[s] = e
            self._boot[s], self._flip[s] = paired_means(e, n_resamples, seed, s, draws)

    def compare(self, a: str, b: str) -> Comparison:
        """Method ``a`` (A) against method ``b`` (B), as :func:`compare_errors` compares them."""
        unknown = [m for m in (a, b) if m not in self.methods]
        if unknown:
            raise UsageError(f"unknown method {unknown[0]!r}; expected one of {', '.join(self.methods)}")
        i, j = self.methods[a], self.methods[b]
        per_set: dict[str, PairedDifference] = {}
        boots, flips = [], []
        for s, e in self._errors.items():
            ea, eb = e[i], e[j]
            d = ea - eb
            boot = self._boot[s][i] - self._boot[s][j]
            flip = self._flip[s][i] - self._flip[s][j]
            per_set[s] = _summary(
                ea.size, float(ea.mean()), float(eb.mean()), float(d.mean()), boot, flip, self.confidence
            )
            boots.append(boot)
            flips.append(flip)
        return _combine(per_set, boots, flips, self.n_resamples, self.seed, self.confidence)


def compare_results(
    a: EvaluationResult,
    b: EvaluationResult,
    *,
    n_resamples: int = 2000,
    seed: int = 0,
    confidence: float = 0.95,
    metric: str = "percent_error",
) -> Comparison:
    """Compare two evaluations of the same benchmark, split and sets.

    ``metric``: ``"percent_error"`` (default) or ``"interval_score"`` (both files need an
    interval: :meth:`~odmd_bench.evaluation.result.EvaluationResult.errors`).
    """
    problems = []
    if (a.benchmark, a.split) != (b.benchmark, b.split):
        problems.append(f"A is {a.benchmark} {a.split}, B is {b.benchmark} {b.split}")
    if list(a.sets) != list(b.sets):
        problems.append(f"A covers the sets {', '.join(a.sets)}, B covers {', '.join(b.sets)}")
    ha, hb = a.provenance.get("sets_content_sha256", {}), b.provenance.get("sets_content_sha256", {})
    if not problems and ha != hb:
        problems.append("A and B were scored against different data (set content hashes differ)")
    if not problems and metric == "interval_score":
        levels = [r.sets[next(iter(r.sets))].get("coverage", {}).get("level") for r in (a, b)]
        if None not in levels and levels[0] != levels[1]:
            problems.append(
                f"A's intervals are at level {levels[0]:g}, B's at {levels[1]:g}: their interval scores differ in kind"
            )
    if problems:
        raise UsageError("A and B cannot be compared", problems)
    c = compare_errors(
        a.errors(metric, "A"),
        b.errors(metric, "B"),
        n_resamples=n_resamples,
        seed=seed,
        confidence=confidence,
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
        metric=f"{metric}_mean",
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
    metric: str = "percent_error",
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
    c = compare_results(a, b, n_resamples=n_resamples, seed=seed, confidence=confidence, metric=metric)
    return c, a, b
