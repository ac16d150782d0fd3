"""The resampling engine: seeded draws, p-values, percentile intervals and Holm's correction.

One engine serves every test odmd-bench makes (docs: leaderboard/README.md):

- **paired** (:mod:`odmd_bench.evaluation.compare`, and through it the leaderboard's rank
  groups): on per-example differences ``d`` of two methods, a percentile bootstrap of the
  mean (examples resampled with replacement, :func:`paired_draws`) and a two-sided
  sign-flip permutation test (:func:`sign_flip_p`). A set's stream (:func:`named_stream`)
  depends on the seed, the set's name and size only, never on the errors, so it is drawn
  once and applied to many methods by matrix products (:func:`paired_means`), and kept
  for boards of the same sets (:class:`SharedDraws`);
- **two-sample** (the fresh-seed audit, :mod:`odmd_bench.leaderboard.audit_stats`):
  a one-sided permutation test that committed errors are smaller than fresh ones
  (:func:`permutation_pvalues`), a stratified percentile bootstrap of the fresh means
  (:func:`stratified_intervals`), Holm's step-down correction (:func:`holm`).

Both tests' p-value is ``(1 + #{T* as extreme as T}) / (1 + B)`` (:func:`p_value`) and both
intervals are the percentiles of :func:`percentile_interval`.

Why by hand: ``scipy.stats.bootstrap`` and ``permutation_test`` are not dependencies of the
package (scipy is a dev-only cross-check: tests/test_resampling.py holds these functions to
them within Monte Carlo error), and they cannot do what the board needs: draw a set's
resamples once and apply them to every pair of 29 entries and to every board of the same
sets, stratify ``All`` over sets, and pin the streams, so that the recorded audits and the
leaderboard's groups are reproduced bit for bit by every later version.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import numpy as np

#: Resamples are drawn this many at a time, to bound memory (chunk x N indices).
_CHUNK = 250
#: :func:`paired_means` multiplies the draws of this many bytes at once (counts and signs).
_BLOCK_BYTES = 64 * 2**20
#: The most resamples a comparison draws (p-values to 1e-6; two float64 arrays of 8 MB).
MAX_RESAMPLES = 1_000_000
#: Relabellings of the two-sample test drawn at once: bounds the memory to about 50 MB.
CHUNK = 1_000

# ------------------------------------------------------------------ streams and statistics


def named_stream(seed: int, name: str) -> np.random.Generator:
    """The paired comparisons' stream of set ``name`` (the same on every machine)."""
    return np.random.default_rng([seed, zlib.crc32(name.encode())])


def keyed_stream(seed: int, key: int) -> np.random.Generator:
    """The stream spawned from ``seed`` with ``key`` (``SeedSequence``, SFC64): the audit's."""
    return np.random.Generator(np.random.SFC64(np.random.SeedSequence(seed, spawn_key=(key,))))


def p_value(count: Any, n: int) -> Any:
    """``(1 + count) / (1 + n)``: the p-value of ``count`` of ``n`` resamples as extreme as observed."""
    return (1 + count) / (1 + n)


def percentile_interval(samples: np.ndarray, confidence: float) -> np.ndarray:
    """The ``(1 - confidence) / 2`` and ``(1 + confidence) / 2`` quantiles along axis 0: ``(2, ...)``."""
    alpha = 1.0 - confidence
    return np.quantile(samples, [alpha / 2, 1 - alpha / 2], axis=0)


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


def holm(pvalues: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p-values (same order as given).

    Example:
        >>> holm(np.array([0.01, 0.04, 0.03])).tolist()
        [0.03, 0.06, 0.06]
    """
    p = np.asarray(pvalues, np.float64)
    order = np.argsort(p, kind="stable")
    scaled = (len(p) - np.arange(len(p))) * p[order]
    adjusted = np.minimum(1.0, np.maximum.accumulate(scaled))
    out = np.empty_like(p)
    out[order] = adjusted
    return out


def holm_permutations(tests: int, level: float) -> int:
    """Permutations whose smallest p-value, ``1 / (B + 1)``, is at most 40% of Holm's first threshold.

    Example:
        >>> holm_permutations(40, 0.01)
        9999
    """
    return math.ceil(2.5 * max(tests, 1) / level) - 1


# ------------------------------------------------------------------ paired: bootstrap and sign flips


def _chunks(n: int, n_resamples: int, rng: np.random.Generator) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The stream of draws, chunk by chunk: resampled indices (k, n) int32 and sign bits (k, n) int8.

    The one definition of what a paired comparison draws (:func:`paired_draws`,
    :func:`paired_means`); a bit of 1 keeps an example's sign, 0 flips it (:func:`_signs`).
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


def paired_draws(d: np.ndarray, n_resamples: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Bootstrap means and sign-flipped means of the differences ``d`` (N,): each (n_resamples,)."""
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
    """The draws of :func:`paired_means`, made once for every set of one stream.

    A set's stream depends only on the seed, the set's name, its size and the number of
    resamples (:func:`named_stream`), never on the errors: boards of the same sets
    (odmd-paper and odmd-v1 have the same names and sizes) draw the same one. The first
    call given this object draws a stream and keeps it, compact (the counts as the
    smallest unsigned integers that hold them, the sign bits packed: 6.75 MB for 2,000
    resamples of 3,000 examples); the next ones read it back, the same numbers, so that
    their results are bit for bit those of drawing again.
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
        for counts, bits in _counted(n, n_resamples, named_stream(seed, name)):
            compact = counts.astype(np.min_scalar_type(counts.max()))
            chunks.append((compact, np.packbits(bits, axis=1)))
            yield counts, bits
        self._kept[key] = chunks  # only a stream drawn to its end is kept


def paired_means(
    e: np.ndarray, n_resamples: int, seed: int, name: str, draws: SharedDraws | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Every method's bootstrap and sign-flip means of ``e`` (M, N) on set ``name``'s stream: each (M, n_resamples).

    The draws are :func:`paired_draws`'s (read from ``draws`` where it holds them); a
    pair's means of differences are the differences of its two methods' means, what
    :func:`paired_draws` gives for the pair up to the order of floating-point additions.
    """
    m, n = e.shape
    if draws is None:
        counted = _counted(n, n_resamples, named_stream(seed, name))
    else:
        counted = draws.counted(seed, name, n, n_resamples)
    boot = np.empty((m, n_resamples))
    flip = np.empty((m, n_resamples))
    # The draws of several chunks go into one product: fewer, larger calls into BLAS
    # (whose idle threads spin between calls, which costs much on a busy machine).
    rows = min(n_resamples, max(1, _BLOCK_BYTES // (16 * n * _CHUNK)) * _CHUNK)
    counts = np.empty((rows, n))  # how often each example is drawn in each resample
    signs = np.empty((rows, n))
    start = drawn = 0
    for chunk, bits in counted:
        k = chunk.shape[0]
        counts[drawn : drawn + k] = chunk
        _signs(bits, out=signs[drawn : drawn + k])
        drawn += k
        if drawn == rows or start + drawn == n_resamples:
            block = slice(start, start + drawn)
            boot[:, block] = e @ counts[:drawn].T / n
            flip[:, block] = e @ signs[:drawn].T / n
            start, drawn = start + drawn, 0
    return boot, flip


def sign_flip_p(flip: np.ndarray, observed: float) -> float:
    """The two-sided sign-flip p-value of ``observed`` among the flipped means ``flip`` (B,)."""
    # Ties with the observed statistic count as "as extreme" (up to rounding).
    tol = 1e-12 * max(1.0, abs(observed))
    return p_value(int(np.count_nonzero(np.abs(flip) >= abs(observed) - tol)), flip.shape[0])


# ------------------------------------------------------------------ two-sample: relabellings, bootstrap


def permutation_pvalues(
    committed: Mapping[str, np.ndarray],
    fresh: Mapping[str, np.ndarray],
    rng: np.random.Generator,
    n_permutations: int,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """One-sided permutation p-values that the committed errors are smaller than the fresh ones.

    Args:
        committed: ``{set: (n, E)}`` per-example errors of E entries on the committed set.
        fresh: ``{set: (m, E)}`` the same entries' errors on the fresh draws.
        rng: the random stream (its draws do not depend on E).
        n_permutations: B.

    Returns:
        ``({set: (E,)}, (E,) for the mean over sets)``: ``(1 + #{T* >= T}) / (B + 1)``
        with ``T = mean(fresh) - mean(committed)``, the relabellings drawn within each set.

    When the fresh errors are ``K`` whole repeats of the committed set's size (``m = K n``,
    the audit's default), the relabellings are drawn within blocks: committed example
    ``i`` and example ``i`` of each repeat form a block, and a random one of its ``K + 1``
    members is labelled committed (for ``K = 1``, a sign flip of each pair's
    difference). Under the null hypothesis the pooled errors are exchangeable, so a
    relabelling from any fixed group of permutations keeps their distribution: the test
    is exact either way, and this one is several times faster to draw. Other sizes
    (``--size``) draw a uniformly random subset of the pooled errors.

    Example:
        >>> rng = np.random.default_rng(0)
        >>> c, f = {"a": np.zeros((50, 1))}, {"a": np.ones((50, 1))}
        >>> p, p_all = permutation_pvalues(c, f, rng, 999)
        >>> float(p["a"][0]), float(p_all[0])
        (0.001, 0.001)
    """
    counts, counts_all = exceedances(committed, fresh, rng, n_permutations, (0.0,))
    return {s: p_value(c[0], n_permutations) for s, c in counts.items()}, p_value(
        counts_all[0], n_permutations
    )


def exceedances(
    committed: Mapping[str, np.ndarray],
    fresh: Mapping[str, np.ndarray],
    rng: np.random.Generator,
    n_permutations: int,
    shifts: Sequence[float | tuple[Mapping[str, np.ndarray], np.ndarray]],
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """``#{T* >= T + shift}`` for each shift: ``({set: (len(shifts), E)}, (len(shifts), E))``.

    A shift is ``0.0`` (the p-value's count) or ``({set: (E,)}, (E,) for the mean over
    sets)``; the relabellings are those :func:`permutation_pvalues` draws, whatever the shifts.
    """
    sets = list(committed)
    observed, pooled, totals, sizes = {}, {}, {}, {}
    for s in sets:
        c, f = np.asarray(committed[s], np.float64), np.asarray(fresh[s], np.float64)
        pooled[s] = np.concatenate([c, f])
        totals[s] = pooled[s].sum(axis=0)
        sizes[s] = (len(c), len(f))
        observed[s] = _statistic(c.sum(axis=0), totals[s], len(c), len(f))
    observed_all = np.mean([observed[s] for s in sets], axis=0)

    def threshold(s: str | None, shift: float | tuple[Mapping[str, np.ndarray], np.ndarray]) -> np.ndarray:
        t = observed_all if s is None else observed[s]
        by = shift if isinstance(shift, float) else (shift[1] if s is None else shift[0][s])
        return t + by - _tie(t)

    limits = {s: np.array([threshold(s, x) for x in shifts]) for s in sets}
    limits_all = np.array([threshold(None, x) for x in shifts])
    exceed = {s: np.zeros((len(shifts), len(observed[s])), np.int64) for s in sets}
    exceed_all = np.zeros((len(shifts), len(observed_all)), np.int64)
    done = 0
    while done < n_permutations:
        rows = min(CHUNK, n_permutations - done)
        stats = []
        for s in sets:
            n, m = sizes[s]
            if m % n == 0:
                committed_sum = _block_sums(pooled[s], n, m // n, rows, rng)
            else:
                # a uniformly random subset: the smaller group's positions drawn
                labels = np.zeros((rows, n + m))
                for row in labels:
                    row[rng.choice(n + m, min(n, m), replace=False)] = 1.0
                drawn = labels @ pooled[s]
                committed_sum = drawn if n <= m else totals[s] - drawn
            t = _statistic(np.asarray(committed_sum), totals[s], n, m)
            exceed[s] += (t[None] >= limits[s][:, None]).sum(axis=1)
            stats.append(t)
        t_all = np.mean(stats, axis=0)
        exceed_all += (t_all[None] >= limits_all[:, None]).sum(axis=1)
        done += rows
    return exceed, exceed_all


def _block_sums(pooled: np.ndarray, n: int, k: int, rows: int, rng: np.random.Generator) -> np.ndarray:
    """``(rows, E)`` committed-group sums, one random member of each block of ``k + 1`` labelled committed.

    Block ``i`` is ``pooled[i + j * n]`` for ``j = 0..k``. The sum is that of the last
    members plus, for each block whose pick ``j`` is not the last, ``x_j - x_k``.
    """
    blocks = pooled.reshape(k + 1, n, -1)
    out = np.broadcast_to(blocks[k].sum(axis=0), (rows, blocks.shape[2])).copy()
    if k == 1:  # a fair bit per block: whether the committed label stays on the committed example
        bits = rng.integers(0, 256, (rows, (n + 7) // 8), dtype=np.uint8)
        stays = np.unpackbits(bits, axis=1, count=n).astype(np.float64)
        return out + stays @ (blocks[0] - blocks[1])
    picks = rng.integers(0, k + 1, (rows, n), dtype=np.int16)
    for j in range(k):
        out += (picks == j).astype(np.float64) @ (blocks[j] - blocks[k])
    return out


def _statistic(committed_sum: np.ndarray, total: np.ndarray, n: int, m: int) -> np.ndarray:
    """``mean(fresh) - mean(committed)`` from the committed group's sum and the pooled total."""
    return (total - committed_sum) / m - committed_sum / n


def _tie(observed: np.ndarray) -> np.ndarray:
    """A relabelling within rounding of the observed statistic counts as reaching it (conservative)."""
    return 1e-9 * (np.abs(observed) + 1.0)


def stratified_intervals(
    samples: Mapping[str, np.ndarray], rng: np.random.Generator, n_resamples: int, confidence: float
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Percentile bootstrap intervals of the means of ``{set: (n, E)}``: ``({set: (E, 2)}, (E, 2) for the mean over sets)``.

    Each set is resampled on its own (stratified); the mean over sets is taken per resample.
    """
    means = {}
    for s, f in samples.items():
        f = np.asarray(f, np.float64)
        counts = rng.multinomial(len(f), np.full(len(f), 1.0 / len(f)), size=n_resamples)
        means[s] = counts @ f / len(f)
    over_sets = np.mean(list(means.values()), axis=0)
    return {s: percentile_interval(m, confidence).T for s, m in means.items()}, percentile_interval(
        over_sets, confidence
    ).T


__all__ = [
    "MAX_RESAMPLES",
    "SharedDraws",
    "exceedances",
    "holm",
    "holm_permutations",
    "keyed_stream",
    "minimum_resamples",
    "named_stream",
    "p_value",
    "paired_draws",
    "paired_means",
    "percentile_interval",
    "permutation_pvalues",
    "resolution_problem",
    "sign_flip_p",
    "smallest_p",
    "stratified_intervals",
]
