"""Rank groups: pure, over per-example percent errors (the rule is in the package docstring)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from odmd_bench.evaluation.compare import TIE, PairedDifference, Resampled
from odmd_bench.evaluation.resampling import SharedDraws

#: Settings of the paired comparison that forms rank groups.
RANK_RESAMPLES = 2000
RANK_SEED = 0
RANK_CONFIDENCE = 0.95


@dataclass(frozen=True)
class Ranked:
    """One row's place.

    Attributes:
        key: the method.
        all_mean: its All.
        group: its rank group (1 is best).
        leader: the method leading its group (itself for a leader).
        versus_leader: comparison with the group's leader on All, A = leader, B = this
            row (None for a leader).
        versus_previous: for the leader of group g > 1, the comparison with the leader
            of group g - 1 that started the new group (A = that leader), else None.
    """

    key: str
    all_mean: float
    group: int
    leader: str
    versus_leader: PairedDifference | None = None
    versus_previous: PairedDifference | None = None


def resamples(n_resamples: int | None) -> int:
    """``n_resamples``, or :data:`RANK_RESAMPLES` (read now, so that it can be patched) when None."""
    return RANK_RESAMPLES if n_resamples is None else n_resamples


def rule(n_resamples: int | None) -> str:
    """The rank-group rule in one paragraph, as the table and the JSON state it."""
    return (
        "Rows sorted by All (ties by method id). The first row leads group 1; each next row is "
        "compared with the current group's leader by odmd_bench.evaluation.compare.compare_errors on per-example "
        f"percent errors ({resamples(n_resamples)} paired bootstrap resamples and sign flips, seed {RANK_SEED}, "
        f"confidence {RANK_CONFIDENCE}, stratified by set for All); it joins the group if the verdict "
        "on All is 'not distinguishable', otherwise it leads the next group."
    )


def rank_groups(
    errors: Mapping[str, Mapping[str, ArrayLike]],
    *,
    n_resamples: int | None = None,
    seed: int = RANK_SEED,
    confidence: float = RANK_CONFIDENCE,
    draws: SharedDraws | None = None,
) -> list[Ranked]:
    """Sort methods by All and form rank groups.

    Args:
        errors: ``{method: {set: (N_set,) per-example percent errors}}``, the same sets
            and examples for every method.
        n_resamples: resamples of the paired comparison (default :data:`RANK_RESAMPLES`).
        seed: its seed.
        confidence: its confidence level.
        draws: the draws kept for, and from, the other boards
            (:class:`~odmd_bench.evaluation.resampling.SharedDraws`; the same groups).

    Returns:
        The rows, best first.

    Every method's errors are resampled once (:class:`~odmd_bench.evaluation.compare.Resampled`):
    each comparison of the walk is then the one :func:`~odmd_bench.evaluation.compare.compare_errors`
    makes, on the same draws, without drawing them again for every pair.

    Examples:
        >>> import numpy as np
        >>> e = np.linspace(1, 2, 100)
        >>> [(r.key, r.group) for r in rank_groups({"b": {"s": e}, "a": {"s": e}, "c": {"s": e + 5}})]
        [('a', 1), ('b', 1), ('c', 2)]
    """
    n = resamples(n_resamples)
    means = {
        k: float(np.mean([np.mean(np.asarray(v, dtype=np.float64)) for v in sets.values()]))
        for k, sets in errors.items()
    }
    order = sorted(errors, key=lambda k: (means[k], k))
    out: list[Ranked] = []
    shared: Resampled | None = None  # drawn at the first comparison: a lone row needs none
    for k in order:
        if not out:
            out.append(Ranked(k, means[k], 1, k))
            continue
        group, leader = out[-1].group, out[-1].leader
        if shared is None:
            shared = Resampled(errors, n_resamples=n, seed=seed, confidence=confidence, draws=draws)
        c = shared.compare(leader, k)
        if c.all.verdict == TIE:
            out.append(Ranked(k, means[k], group, leader, versus_leader=c.all))
        else:
            out.append(Ranked(k, means[k], group + 1, k, versus_previous=c.all))
    return out
