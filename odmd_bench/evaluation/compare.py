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
The leaderboard forms its rank groups with :class:`Resampled`: the comparison of
:func:`compare_errors`, its draws made once for every pair of methods (and, kept in
:class:`SharedDraws`, once for every board of the same sets).
"""

from __future__ import annotations

import os
import zlib
from collections.abc import Iterator, Mapping, Sequence
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
#: :class:`Resampled` multiplies the draws of this many bytes at once (counts and signs).
_BLOCK_BYTES = 64 * 2**20
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


def _rng(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(name.encode())])


def _chunks(n: int, n_resamples: int, rng: np.random.Generator) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The stream of draws, chunk by chunk: resampled indices (k, n) int32 and sign bits (k, n) int8.

    The one definition of what a comparison draws (:func:`_draws` and :class:`Resampled`);
    a bit of 1 keeps an example's sign, 0 flips it (:func:`_signs`).
    """
    for start in range(0, n_resamples, _CHUNK):
        k = min(_CHUNK, n_resamples - start)
        idx = rng.integers(0, n, size=(k, n), dtype=np.int32)
        yield idx, rng.integers(0, 2, size=(k, n), dtype=np.int8)


def _signs(bits: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Sign bits (0 or 1) as signs of -1.0 or +1.0, written to ``out`` when given."""
    signs = np.multiply(bits, 2.0, out=out)
    signs -= 1.0
    return signs


def _draws(d: np.ndarray, n_resamples: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Bootstrap means and sign-flipped means of ``d``, each (n_resamples,)."""
    n = d.shape[0]
    boot = np.empty(n_resamples)
    flip = np.empty(n_resamples)
    start = 0
    for idx, bits in _chunks(n, n_resamples, rng):
        k = idx.shape[0]
        boot[start : start + k] = d[idx].mean(axis=1)
        flip[start : start + k] = _signs(bits) @ d / n
        start += k
    return boot, flip


def _counted(n: int, n_resamples: int, rng: np.random.Generator) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """:func:`_chunks` with each resample's indices counted: (k, n) draws of every example, and the sign bits."""
    offsets = np.arange(_CHUNK)[:, None] * n
    for idx, bits in _chunks(n, n_resamples, rng):
        k = idx.shape[0]
        yield np.bincount((idx + offsets[:k]).ravel(), minlength=k * n).reshape(k, n), bits


class SharedDraws:
    """The draws of :class:`Resampled` comparisons, made once for every set of one stream.

    A set's stream depends only on the seed, the set's name, its size and the number of
    resamples (:func:`_rng`), never on the errors: boards of the same sets (odmd-paper
    and odmd-v1 have the same names and sizes) draw the same one. The first
    :class:`Resampled` given this object draws a stream and keeps it, compact (the
    counts as the smallest unsigned integers that hold them, the sign bits packed: 6.75
    MB for 2,000 resamples of 3,000 examples); the next ones read it back, the same
    numbers, so that their results are bit for bit those of drawing again.
    """

    def __init__(self) -> None:
        self._kept: dict[tuple[int, str, int, int], list[tuple[np.ndarray, np.ndarray]]] = {}

    def counted(
        self, seed: int, name: str, n: int, n_resamples: int
    ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """What :func:`_counted` yields for this stream, drawn the first time only."""
        key = (seed, name, n, n_resamples)
        kept = self._kept.get(key)
        if kept is not None:
            for counts, packed in kept:
                yield counts, np.unpackbits(packed, axis=1, count=n)
            return
        chunks = []
        for counts, bits in _counted(n, n_resamples, _rng(seed, name)):
            compact = counts.astype(np.min_scalar_type(counts.max()))
            chunks.append((compact, np.packbits(bits, axis=1)))
            yield counts, bits
        self._kept[key] = chunks  # only a stream drawn to its end is kept


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
    _check_settings(errors_a, n_resamples, seed, confidence)
    per_set: dict[str, PairedDifference] = {}
    boots, flips = [], []
    for s in errors_a:
        ea, eb = _errors(s, errors_a[s], errors_b[s])
        d = ea - eb
        boot, flip = _draws(d, n_resamples, _rng(seed, s))
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
    once on that stream (products of the resample counts and the signs with every
    method's errors at once), and a pair's means of differences are the differences of
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
            n = e.shape[1]
            if draws is None:
                counted = _counted(n, n_resamples, _rng(seed, s))
            else:
                counted = draws.counted(seed, s, n, n_resamples)
            self._boot[s], self._flip[s] = self._means(e, counted)

    def _means(
        self, e: np.ndarray, counted: Iterator[tuple[np.ndarray, np.ndarray]]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Every method's bootstrap and sign-flip means of ``e`` (M, N): each (M, n_resamples)."""
        m, n = e.shape
        boot = np.empty((m, self.n_resamples))
        flip = np.empty((m, self.n_resamples))
        # The draws of several chunks go into one product: fewer, larger calls into BLAS
        # (whose idle threads spin between calls, which costs much on a busy machine).
        rows = min(self.n_resamples, max(1, _BLOCK_BYTES // (16 * n * _CHUNK)) * _CHUNK)
        counts = np.empty((rows, n))  # how often each example is drawn in each resample
        signs = np.empty((rows, n))
        start = drawn = 0
        for chunk, bits in counted:
            k = chunk.shape[0]
            counts[drawn : drawn + k] = chunk
            _signs(bits, out=signs[drawn : drawn + k])
            drawn += k
            if drawn == rows or start + drawn == self.n_resamples:
                block = slice(start, start + drawn)
                boot[:, block] = e @ counts[:drawn].T / n
                flip[:, block] = e @ signs[:drawn].T / n
                start, drawn = start + drawn, 0
        return boot, flip

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
