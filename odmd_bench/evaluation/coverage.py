"""Checking parsed predictions against the sizes of the sets: the second stage of evaluation.

:func:`check_coverage` places each estimate at its index, and finds indices out of range
and examples without a row. It reads no data file: the sizes of the sets in scope come
from the caller (from the loaded sets in :func:`~odmd_bench.evaluation.scoring.evaluate`,
from the leaderboard's sets, or from a test); rows of the sets left out of scope are
range-checked against the sizes pinned in ``splits/``, so that a file is refused or not
whatever ``--sets`` says.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from odmd_bench.data.manifests import pinned_sizes
from odmd_bench.data.registry import Benchmark
from odmd_bench.errors import UsageError
from odmd_bench.evaluation.parse import ParsedPredictions
from odmd_bench.evaluation.result import Predictions
from odmd_bench.inputs.problems import SHOWN, Problems, clip, closest


def check_sets(sets: Sequence[str], bench: Benchmark) -> tuple[str, ...]:
    """The sets asked for, checked, in the benchmark's order, each once.

    Raises:
        UsageError: no set named, or a set the benchmark does not have.
    """
    names = [s.strip() for s in sets if s.strip()]
    if not names:
        raise UsageError(f"no sets named; expected some of {', '.join(bench.sets)}")
    unknown = [s for s in names if s not in bench.sets]
    if unknown:
        raise UsageError(
            f"unknown set {unknown[0]!r} for benchmark {bench.name!r}; expected some of "
            f"{', '.join(bench.sets)}{closest(unknown[0], bench.sets)}"
        )
    # Benchmark order, so that results do not depend on how --sets was typed.
    return tuple(s for s in bench.sets if s in names)


def nonpositive_warning(count: int, shown: Sequence[str]) -> str:
    """The warning about zero or negative depths (legal estimates, scored as given)."""
    more = f", ... ({count - len(shown)} more)" if count > len(shown) else ""
    return clip(
        f"{count} {'depth is' if count == 1 else 'depths are'} zero or negative "
        f"(scored as given): {', '.join(shown)}{more}",
        1000,
    )


def check_coverage(
    parsed: ParsedPredictions,
    sizes: Mapping[str, int],
    *,
    sets: Sequence[str] | None = None,
    board: bool = False,
) -> Predictions:
    """Place parsed estimates by index and check that they cover every example once.

    Args:
        parsed: from :func:`~odmd_bench.evaluation.parse.parse_predictions`; problems it
            kept (``strict=False``) are reported together with these.
        sizes: ``{set: number of examples}`` of ``parsed.split``, for every set in scope.
        sets: score only these sets (rows of others are checked like any row, their
            indices against the pinned sizes, and then ignored, with a warning);
            default: every set of the benchmark must be covered.
        board: the file is a leaderboard entry's (a set without rows is not told to
            use ``--sets``, which a board does not have).

    Returns:
        Validated predictions, ``depths[s][i]`` the estimate of example ``i`` of set ``s``.

    Raises:
        ValidationError: every problem found (the parser's and the coverage's).
        UsageError: unknown ``sets``, or ``sizes`` missing a set in scope.
    """
    problems = parsed.problems.copy()
    bench = parsed.bench
    if bench is None or parsed.split is None:
        if not problems:  # pragma: no cover - the parser records why
            problems.add("the file's benchmark or split could not be determined")
        raise problems.error(parsed.name)
    scope = check_sets(sets, bench) if sets is not None else bench.sets
    lacking = [s for s in scope if s not in sizes]
    if lacking:
        raise UsageError(f"no size given for the sets {', '.join(lacking)}")
    code = {n: i for i, n in enumerate(parsed.set_names)}
    size_of = np.full(len(parsed.set_names), -1, dtype=np.int64)
    scoped = np.zeros(len(parsed.set_names), dtype=bool)
    known = {**pinned_sizes(bench, parsed.split), **{s: int(sizes[s]) for s in scope}}
    for s, c in code.items():
        size_of[c] = known.get(s, -1)
        scoped[c] = s in scope
    n_row = size_of[parsed.codes]
    in_scope = scoped[parsed.codes]
    out = (n_row >= 0) & ((parsed.indices < 0) | (parsed.indices >= n_row))
    _out_of_range(parsed, np.flatnonzero(out), n_row, problems)
    if out.any():
        _one_based(parsed, size_of, problems)
    placed = in_scope & ~out
    depths = {
        s: _place(parsed, placed, code.get(s, -1), int(sizes[s]), s, scope, bench, sets, problems, board)
        for s in scope
    }
    if problems:
        raise problems.error(parsed.name)
    uncertainty = {
        s: {
            c: _place_values(parsed, placed, code.get(s, -1), int(sizes[s]), v)
            for c, v in parsed.uncertainty.items()
        }
        for s in scope
    }
    return Predictions(
        path=parsed.name,
        sha256=parsed.sha256,
        benchmark=bench.name,
        split=parsed.split,
        depths=depths,
        n_rows=parsed.n_rows,
        ignored_columns=parsed.ignored_columns,
        warnings=_warnings(parsed, placed, ~in_scope, scope),
        uncertainty=uncertainty if parsed.uncertainty else {},
        level=parsed.level,
    )


def _place_values(
    parsed: ParsedPredictions, placed: np.ndarray, code: int, n: int, values: np.ndarray
) -> np.ndarray:
    """``(n,)`` one uncertainty column of a set by index (every index has a row by now)."""
    out = np.full(n, np.nan)
    mine = placed & (parsed.codes == code)
    out[parsed.indices[mine]] = values[mine]
    return out


def _out_of_range(parsed: ParsedPredictions, rows: np.ndarray, n_row: np.ndarray, problems: Problems) -> None:
    for r in rows[:SHOWN]:
        s, i, n = parsed.set_names[parsed.codes[r]], parsed.indices[r], int(n_row[r])
        problems.add(
            "index out of range",
            f"line {parsed.lines[r]} ({s} {i}; {s} has {n} examples, indices 0..{n - 1})",
        )
    if rows.size > SHOWN:
        problems.add("index out of range", count=int(rows.size - SHOWN))


def _one_based(parsed: ParsedPredictions, size_of: np.ndarray, problems: Problems) -> None:
    """Name the sets whose indices run 1..n: counted from 1, where the format counts from 0."""
    for c, s in enumerate(parsed.set_names):
        n = int(size_of[c])
        idx = parsed.indices[parsed.codes == c]
        if n > 0 and idx.size and idx.min() == 1 and idx.max() == n:
            problems.add(
                f"set {s!r}: the indices run 1..{n}, counted from 1; the format counts from 0 "
                f"(0..{n - 1}, the examples' order in the set): subtract 1 from every index"
            )


def _place(
    parsed: ParsedPredictions,
    placed: np.ndarray,
    code: int,
    n: int,
    s: str,
    scope: tuple[str, ...],
    bench: Benchmark,
    sets: Sequence[str] | None,
    problems: Problems,
    board: bool = False,
) -> np.ndarray:
    """``(n,)`` the estimates of set ``s`` by index (NaN where missing); gaps are problems."""
    depth = np.full(n, np.nan)
    seen = np.zeros(n, dtype=bool)
    mine = placed & (parsed.codes == code)
    depth[parsed.indices[mine]] = parsed.depths[mine]
    seen[parsed.indices[mine]] = True
    gaps = np.flatnonzero(~seen)
    if gaps.size == n and code >= 0:
        # The set is named in the file, but every row of it was refused: --sets would not help.
        problems.add(
            f"set {s!r} of benchmark {bench.name!r} has no usable row (each of its rows has a problem)"
        )
    elif gaps.size == n:
        if board:
            hint = "a board needs predictions for every example of every set"
        elif sets is not None:
            hint = "it was asked for"
        elif parsed.problems:  # rows under a name refused above may well be this set's
            hint = "check the set names refused above"
        else:
            hint = f"to score only some sets, name them, e.g. --sets {','.join(x for x in scope if x != s)}"
        problems.add(f"set {s!r} of benchmark {bench.name!r} has no rows ({hint})")
    elif gaps.size:
        shown = ", ".join(str(i) for i in gaps[:SHOWN])
        more = ", ..." if gaps.size > SHOWN else ""
        problems.add(
            f"{gaps.size} of the {n} examples of set {s!r} have no row (missing indices {shown}{more})"
        )
    return depth


def _warnings(
    parsed: ParsedPredictions, placed: np.ndarray, ignored: np.ndarray, scope: tuple[str, ...]
) -> tuple[str, ...]:
    out = []
    count = int(np.count_nonzero(placed & (parsed.depths <= 0)))
    if count:
        first = sorted(x for s in scope for x in parsed.nonpositive.get(s, ()))
        out.append(nonpositive_warning(count, [text for _, text in first[:SHOWN]]))
    if ignored.any():
        codes, first_row, counts = np.unique(parsed.codes[ignored], return_index=True, return_counts=True)
        parts = ", ".join(
            f"{parsed.set_names[c]} ({k} rows)"
            for _, c, k in sorted(zip(first_row, codes, counts, strict=True))
        )
        out.append(f"ignored rows of sets not asked for: {parts}")
    return tuple(out)
