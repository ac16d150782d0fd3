"""The fresh-seed audit's test: committed against fresh per-example errors, Holm, the flags.

The test (docs: leaderboard/README.md, "Is a method tuned on the test set?"): for each
entry and set, the statistic is ``fresh mean - committed mean`` (positive: the committed
score is the better one). Under the null hypothesis, the method did not use the test set,
so its per-example errors on the committed set and on the fresh draws are exchangeable
(independent examples of one distribution, each estimated on its own); the one-sided
p-value is that of a permutation test, ``(1 + #{T* >= T}) / (B + 1)`` over ``B`` random
relabellings of the pooled errors, which is exact whatever the errors' distribution
(heavy tails included). ``generated_mean`` is the mean of the three sets' statistics,
permuted within each set (stratified): the mean over the *generated* sets only, not the
board's All (which includes Robot). The p-values of every entry and test (three sets and
``generated_mean``) are corrected together by Holm's method; an entry is **flagged** when
one of its adjusted p-values is at most :data:`LEVEL`. So an audit of honest entries flags
any of them with probability at most :data:`LEVEL` over the draws of the committed and the
fresh sets (audits of one board share its committed draw, so they are not independent
trials).

The draws, p-values, intervals and Holm's correction are the resampling engine's
(:mod:`odmd_bench.evaluation.resampling`); the errors come from
:func:`~odmd_bench.leaderboard.audit.collect_errors`. Everything is seeded by the audit's
seed: the same seed gives the same JSON.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from odmd_bench.evaluation.resampling import holm, keyed_stream, permutation_pvalues, stratified_intervals
from odmd_bench.leaderboard.specs import rounded as _r

#: Family-wise level: the chance that an audit flags any honest entry is at most this.
LEVEL = 0.01
#: Bootstrap resamples of the fresh means' intervals, and their confidence.
BOOTSTRAP = 2_000
CONFIDENCE = 0.95
#: Spawn keys of the audit's random streams (fresh sets: (repeat, set); statistics: these).
PERMUTATION_KEY = 1_000_001
BOOTSTRAP_KEY = 1_000_002


@dataclass(frozen=True)
class Collected:
    """An audit's data before its test: the rows, and the per-example errors of the re-run entries.

    Attributes:
        header: the audit's fields but ``test`` and ``entries``.
        rows: one per entry, ``sets``, ``generated_mean`` and ``flagged`` not filled in yet.
        audited: the indices in ``rows`` of the re-run entries, in column order.
        committed: ``{set: (n, E)}`` errors on the committed sets, a column per re-run entry.
        fresh: ``{set: (m, E)}`` errors on the fresh draws.
        shipped: the entries whose method is shipped in this repository
            (:func:`~odmd_bench.leaderboard.audit_files.shipped`).
    """

    header: dict[str, Any]
    rows: list[dict[str, Any]]
    audited: list[int]
    committed: dict[str, np.ndarray]
    fresh: dict[str, np.ndarray]
    shipped: frozenset[str] = frozenset()


def n_tests(found: Collected) -> int:
    """The size of the Holm family: every re-run entry's sets and ``generated_mean``."""
    return len(found.audited) * (len(found.header["sets"]) + 1)


def bootstrap_intervals(
    fresh: Mapping[str, np.ndarray], rng: np.random.Generator, n_resamples: int = BOOTSTRAP
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Percentile bootstrap intervals of the fresh means: ``({set: (E, 2)}, (E, 2) for the mean over sets)``.

    Each set is resampled on its own (stratified); the mean over sets is taken per resample.
    """
    return stratified_intervals(fresh, rng, n_resamples, CONFIDENCE)


def assess_with(
    found: Collected,
    n_permutations: int,
    *,
    progress: Callable[[str], None] | None = None,
    pvalues: tuple[Mapping[str, np.ndarray], np.ndarray] | None = None,
) -> dict[str, Any]:
    """The test of ``found`` with ``n_permutations`` per test: the intervals, Holm, the flags; the audit's data.

    ``pvalues``: the permutation p-values when they are already drawn, from this seed's stream
    with ``n_permutations`` (``leaderboard check --audits`` draws them with their ranges, in
    one pass of relabellings); drawn here otherwise.
    """
    seed, sets, audited, c, f = (
        found.header["seed"],
        list(found.header["sets"]),
        found.audited,
        found.committed,
        found.fresh,
    )
    rows = [{**row, "sets": {}} for row in found.rows]
    tests = n_tests(found)
    if audited:
        if progress is not None:
            progress(f"testing {len(audited)} entries: {n_permutations:,} permutations per test")
        if pvalues is None:
            pvalues = permutation_pvalues(c, f, keyed_stream(seed, PERMUTATION_KEY), n_permutations)
        p_sets, p_all = pvalues
        ci_sets, ci_all = bootstrap_intervals(f, keyed_stream(seed, BOOTSTRAP_KEY))
        # Holm over every entry and test at once, flattened entry-major
        flat = np.column_stack([*(p_sets[s] for s in sets), p_all]).ravel()
        adjusted = holm(flat).reshape(len(audited), len(sets) + 1)
        for k, i in enumerate(audited):
            row = rows[i]
            for j, s in enumerate(sets):
                row["sets"][s] = _test_dict(
                    c[s][:, k].mean(), f[s][:, k].mean(), ci_sets[s][k], p_sets[s][k], adjusted[k, j]
                )
            row["generated_mean"] = {
                "sets": sets,
                **_test_dict(
                    np.mean([c[s][:, k].mean() for s in sets]),
                    np.mean([f[s][:, k].mean() for s in sets]),
                    ci_all[k],
                    p_all[k],
                    adjusted[k, -1],
                ),
            }
            row["flagged"] = bool((adjusted[k] <= LEVEL).any())
    return {
        **found.header,
        "test": describe_test(tests, n_permutations),
        "entries": rows,
    }


def describe_test(tests: int, n_permutations: int) -> dict[str, Any]:
    """The audit's ``test`` field: the statistic, the test, its permutations and the Holm family's size."""
    return {
        "statistic": "difference = fresh mean - committed mean of per-example percent errors "
        "(positive: the committed score is the better one); generated_mean = the mean over the "
        "generated sets (normal, camera, object) of each figure, not the board's All (four sets)",
        "p": "one-sided permutation test, (1 + #{T* >= T}) / (B + 1), relabelling within each set",
        "permutations": n_permutations,
        "correction": "holm",
        "tests": tests,
        "level": LEVEL,
        "bootstrap_resamples": BOOTSTRAP,
        "confidence": CONFIDENCE,
    }


def _test_dict(
    committed: float, fresh: float, interval: np.ndarray, p: float, adjusted: float
) -> dict[str, Any]:
    return {
        "committed": _r(committed),
        "fresh": _r(fresh),
        "fresh_interval": [_r(interval[0]), _r(interval[1])],
        "difference": _r(fresh - committed),
        "p": _r(p),
        "p_adjusted": _r(adjusted),
    }


def flagged(result: Mapping[str, Any]) -> list[str]:
    """The method ids an audit flags."""
    return [e["method"] for e in result["entries"] if e.get("flagged")]


__all__ = [
    "BOOTSTRAP",
    "CONFIDENCE",
    "LEVEL",
    "Collected",
    "assess_with",
    "bootstrap_intervals",
    "describe_test",
    "flagged",
    "n_tests",
]
