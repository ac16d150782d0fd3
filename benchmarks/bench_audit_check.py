"""``leaderboard check --audits``: the re-run's p-values and their ranges, two passes of relabellings or one.

Run: pytest benchmarks/bench_audit_check.py --benchmark-only -p no:randomly -s

A committed-size audit (12 entries; 3,000 committed and 5 x 3,000 fresh examples per
generated set; 9,999 permutations). Before (the reference, what the check did): the
p-values drawn by ``permutation_pvalues`` and their ranges by another pass of the same
relabellings; after: both counted on one pass (``audit_check._ranges_and_pvalues``). The
two are checked to give the same numbers, then timed alternately in one run, by CPU
time (the steadier measure on a shared machine); the medians and their ratio are printed
and kept in ``benchmark.extra_info``. The errors are seeded, exponential.
"""

from __future__ import annotations

import resource
import statistics
from typing import Any

import numpy as np
import pytest

from odmd_bench.evaluation.resampling import exceedances, keyed_stream, p_value, permutation_pvalues
from odmd_bench.leaderboard import audit_check as ac
from odmd_bench.leaderboard.audit_stats import PERMUTATION_KEY, Collected

SETS = ("normal", "camera", "object")
ENTRIES, COMMITTED, REPEATS, PERMUTATIONS, ROUNDS = 12, 3_000, 5, 9_999, 5


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _found() -> Collected:
    rng = np.random.default_rng(1)
    committed = {s: rng.exponential(5.0, (COMMITTED, ENTRIES)) for s in SETS}
    fresh = {s: rng.exponential(5.0, (REPEATS * COMMITTED, ENTRIES)) for s in SETS}
    rows = [{"method": f"m{k}", "runnable": True} for k in range(ENTRIES)]
    header = {"seed": 7, "sets": dict.fromkeys(SETS, COMMITTED)}
    return Collected(header, rows, list(range(ENTRIES)), committed, fresh)


def _two_passes(found: Collected) -> Any:
    """The reference: the p-values, then the ranges on a second pass of the same relabellings."""
    stream = keyed_stream(found.header["seed"], PERMUTATION_KEY)
    p = permutation_pvalues(found.committed, found.fresh, stream, PERMUTATIONS)
    margins = ac.statistic_margins(found.committed, found.fresh)
    down = ({s: -v for s, v in margins[0].items()}, -margins[1])
    stream = keyed_stream(found.header["seed"], PERMUTATION_KEY)
    counts, counts_all = exceedances(found.committed, found.fresh, stream, PERMUTATIONS, (margins, down))
    ranges = tuple(
        p_value(np.column_stack([*(counts[s][end] for s in SETS), counts_all[end]]), PERMUTATIONS)
        for end in (0, 1)
    )
    return ranges, p


def _one_pass(found: Collected) -> Any:
    return ac._ranges_and_pvalues(found, PERMUTATIONS, ac.DEPTH_RTOL)


@pytest.mark.benchmark(group="audit-check")
def test_p_values_and_their_ranges_on_one_pass(benchmark: Any) -> None:
    found = _found()
    (lo, hi), (p, p_all) = _one_pass(found)
    (lo2, hi2), (p2, p_all2) = _two_passes(found)
    assert (lo == lo2).all() and (hi == hi2).all() and (p_all == p_all2).all()
    assert all((p[s] == p2[s]).all() for s in SETS)
    times: dict[str, list[float]] = {"two passes": [], "one pass": []}
    for r in range(ROUNDS):
        order = [("two passes", _two_passes), ("one pass", _one_pass)]
        for name, run in order if r % 2 == 0 else order[::-1]:
            start = _cpu()
            run(found)
            times[name].append(_cpu() - start)
    medians = {k: statistics.median(v) for k, v in times.items()}
    ratio = medians["one pass"] / medians["two passes"]
    print(f"\nCPU s, median of {ROUNDS}: " + ", ".join(f"{k} {v:.2f}" for k, v in medians.items()))
    print(f"one pass / two passes: {ratio:.2f}")
    benchmark.extra_info.update({f"cpu_s_{k.replace(' ', '_')}": v for k, v in medians.items()})
    benchmark.extra_info["ratio"] = ratio
    benchmark.pedantic(_one_pass, args=(found,), rounds=1, iterations=1)
