"""Parsing a predictions CSV from its text alone: the first stage of evaluation.

:func:`parse_predictions` needs no data set: it checks everything the text can tell
(encoding, CSV syntax, the header, the field count of every row, one known benchmark and
one split, known set names, integer indices, finite numeric depths of a sane size, no
duplicate ``(set, index)``) and names every problem in one pass, with counts and the
first few lines (line 1 is the header). What needs the sets' sizes (indices in range,
every example present) is :func:`~odmd_bench.evaluation.coverage.check_coverage`'s job.

Accepted: a UTF-8 byte-order mark (or UTF-16 with one), Windows or old Mac line ends,
spaces around a cell, blank lines, extra columns (ignored), any row order, gzip. Numbers
are parsed by Python's ``int`` and ``float`` after a strict pattern check, so a depth
written with ``repr`` precision is read back bit for bit. The text is streamed row by
row into flat arrays, never held as a list of rows; a clean file (every row as
``odmd-bench`` writes it) a block of lines at a time, to the same arrays
(:meth:`~odmd_bench.evaluation.rows.Rows.add_clean`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from odmd_bench.data.registry import BENCHMARKS, DEFAULT_BENCHMARK, Benchmark, resolve_benchmark
from odmd_bench.errors import ValidationError
from odmd_bench.evaluation.columns import check_header, single_value
from odmd_bench.evaluation.rows import Rows
from odmd_bench.evaluation.uncertainty import UNCERTAINTY_COLUMNS, check_values
from odmd_bench.inputs.problems import SHOWN, Problems, closest, show
from odmd_bench.inputs.records import decode, records
from odmd_bench.inputs.source import Source, read_source


@dataclass(frozen=True)
class ParsedPredictions:
    """A predictions file checked as text; rows held as flat arrays in file order.

    Attributes:
        name: how the file is named in messages and provenance.
        sha256: SHA-256 of the CSV bytes (after gzip decompression).
        bench: the benchmark (argument, column or default); None if undetermined.
            ``benchmark`` is its name.
        split: the file's split; None if undetermined.
        n_rows: data rows in the file (blank lines not counted).
        ignored_columns: columns other than the required and optional ones.
        set_names: the set names met, in order of first appearance; ``codes`` index it.
        codes, indices, depths, lines: ``(R,)`` set code, index, depth (NaN where the
            depth is refused) and file line of each row with a valid, unique key.
        nonpositive: ``{set: ((line, "line L (set i: text)"), ...)}`` the first few
            zero or negative depths of each set.
        problems: every problem found; empty when parsed with ``strict=True``.
        benchmark_column: whether the file has a ``benchmark`` column (else its benchmark
            came from the argument or the default).
        benchmark_asked: whether the caller named the benchmark (``--benchmark``).
        uncertainty: ``{column: (R,) float64}`` of the uncertainty columns the file has
            (:mod:`~odmd_bench.evaluation.uncertainty`), aligned with ``depths``; empty
            without them.
        level: the interval's nominal coverage (the ``level`` column), or None.
    """

    name: str
    sha256: str
    bench: Benchmark | None
    split: str | None
    n_rows: int
    ignored_columns: tuple[str, ...]
    set_names: tuple[str, ...]
    codes: np.ndarray
    indices: np.ndarray
    depths: np.ndarray
    lines: np.ndarray
    nonpositive: dict[str, tuple[tuple[int, str], ...]] = field(default_factory=dict, repr=False)
    problems: Problems = field(default_factory=Problems, repr=False, compare=False)
    benchmark_column: bool = False
    benchmark_asked: bool = False
    uncertainty: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    level: float | None = None

    @property
    def benchmark(self) -> str | None:
        """The name of :attr:`bench`; None if undetermined."""
        return self.bench.name if self.bench is not None else None


def parse_predictions(
    source: Source,
    *,
    name: str | None = None,
    benchmark: str | Benchmark | None = None,
    strict: bool = True,
) -> ParsedPredictions:
    r"""Parse and check a predictions CSV from its text alone (no data set is read).

    Args:
        source: a path, the file's bytes, or a binary file object (gzip is recognised);
            at most :data:`~odmd_bench.inputs.source.MAX_PREDICTIONS_BYTES` are read.
        name: how messages and provenance name the file (default: the path).
        benchmark: the benchmark the file is for. Default: its ``benchmark`` column, else
            ``odmd-v1``; a column that says otherwise is a problem.
        strict: raise on any problem (default). With False the problems are kept in
            ``problems``, for :func:`~odmd_bench.evaluation.coverage.check_coverage` to
            report with its own in one error; an unreadable file or header still raises.

    Returns:
        The parsed rows.

    Raises:
        ValidationError: naming every problem found, with counts and lines.
        UsageError: an unknown ``benchmark``.

    Examples:
        >>> p = parse_predictions(b"split,set,index,depth\ntest,robot,0,1.5\n")
        >>> p.benchmark, p.split, p.set_names, p.depths.tolist()
        ('odmd-v1', 'test', ('robot',), [1.5])
    """
    bench = resolve_benchmark(benchmark) if benchmark is not None else None
    data, label = read_source(source, name=name)
    title = f"{label} cannot be scored"
    if not data or data.isspace():  # (strip() would copy the bytes)
        raise ValidationError(
            title, ["the file is empty; expected a header line split,set,index,depth and one row per example"]
        )
    sha256 = hashlib.sha256(data).hexdigest()
    text, problem = decode(data)
    del data  # the text is all that is needed now: keep one copy in memory
    if text is None:
        raise ValidationError(title, [problem or "the file is not text"])
    stream = records(text, title)
    first = next(stream, None)
    if first is None:
        raise ValidationError(title, ["the file holds no header and no rows"])
    header = first[1]
    header_problems = Problems()
    cols = check_header(header, header_problems)
    if cols is None:
        for _ in stream:  # a CSV syntax error later in the file is reported instead
            pass
        raise ValidationError(title, header_problems.lines())
    rows = Rows(cols, len(header))
    if first[0] != 1 or not rows.add_clean(text, _second_line(text), 2):
        for line, cells in stream:
            rows.add(line, cells)
    if not rows.n:
        raise ValidationError(title, ["the file has a header but no rows; expected one row per example"])
    parsed = _finish(rows, header, label, sha256, bench)
    if strict and parsed.problems:
        raise parsed.problems.error(label)
    return parsed


def _second_line(text: str) -> int:
    r"""Where the text's second line starts (after ``\n``, ``\r\n`` or ``\r``; the length if none)."""
    ends = [i for i in (text.find("\n"), text.find("\r")) if i >= 0]
    if not ends:
        return len(text)
    return min(ends) + (2 if text.startswith("\r\n", min(ends)) else 1)


def _finish(
    rows: Rows, header: list[str], label: str, sha256: str, bench: Benchmark | None
) -> ParsedPredictions:
    """Resolve the benchmark and split, check set names and duplicates, build the result."""
    problems = rows.fields
    chosen: Benchmark | None
    if "benchmark" in rows.cols:
        problems.extend(rows.bench_bad)
        from_file = single_value(rows.bench_tally, problems, "benchmark")
        if bench is not None and from_file is not None and from_file != bench.name:
            problems.add(f"the file's benchmark column says {from_file!r} but --benchmark is {bench.name!r}")
            chosen = None
        else:  # the rows keep only registered names in the tally
            chosen = bench or (BENCHMARKS[from_file] if from_file is not None else None)
    else:
        chosen = bench or BENCHMARKS[DEFAULT_BENCHMARK]
    problems.extend(rows.split_bad)
    split = single_value(rows.split_tally, problems, "split")

    names = tuple(rows.codes)
    codes = np.frombuffer(rows.code, dtype=np.int32)
    lines = np.frombuffer(rows.line, dtype=np.int64)
    indices = np.frombuffer(rows.index, dtype=np.int64)
    keep = np.frombuffer(rows.index_ok, dtype=np.int8).astype(bool)
    set_problems = Problems()
    if chosen is not None:
        keep &= _check_set_names(names, codes, lines, chosen.sets, chosen.name, set_problems)
    extra = {c: np.frombuffer(v, dtype=np.float64) for c, v in rows.extra_values.items()}
    extra_problems = Problems()
    level = check_values(extra, lines, extra_problems) if extra else None
    problems.extend(Problems.by_line(set_problems, rows.values, extra_problems))
    keep &= ~_duplicates(names, codes, indices, lines, keep, problems)
    return ParsedPredictions(
        name=label,
        sha256=sha256,
        bench=chosen,
        split=split,
        n_rows=rows.n,
        ignored_columns=tuple(
            h
            for h in header
            if h not in ("split", "set", "index", "depth", "benchmark", *UNCERTAINTY_COLUMNS)
        ),
        set_names=names,
        codes=codes[keep],
        indices=indices[keep],
        depths=np.frombuffer(rows.depth, dtype=np.float64)[keep],
        lines=lines[keep],
        nonpositive={names[c]: tuple(v) for c, v in rows.nonpositive.items()},
        problems=problems,
        benchmark_column="benchmark" in rows.cols,
        benchmark_asked=bench is not None,
        uncertainty={c: v[keep] for c, v in extra.items()},
        level=level,
    )


#: The original release's names of the ODMD sets (its file names), and other spellings.
_ALIASES = {
    "perturb_motion": "camera",
    "perturb_camera": "camera",
    "perturb_camera_motion": "camera",
    "perturb_detection": "object",
    "perturb_object": "object",
    "perturb_object_detection": "object",
}


def _check_set_names(
    names: tuple[str, ...],
    codes: np.ndarray,
    lines: np.ndarray,
    valid: tuple[str, ...],
    bench: str,
    problems: Problems,
) -> np.ndarray:
    """``(R,)`` True where the row's set is one of ``valid``; the others are problems."""
    known = np.array([n in valid for n in names], dtype=bool)
    ok = known[codes] if codes.size else np.ones(0, dtype=bool)
    bad = np.flatnonzero(~ok)
    kind = f"unknown set for benchmark {bench!r}"
    note = f"expected one of {', '.join(valid)}"
    for r in bad[:SHOWN]:
        name = names[codes[r]]
        alias = _ALIASES.get(name.strip().lower())
        hint = f": did you mean {alias!r}?" if alias in valid else closest(name, valid).replace("; ", ": ")
        where = f"line {lines[r]} ({show(name)}{hint})"
        problems.add(kind, where, note, at=int(lines[r]))
    if bad.size > SHOWN:
        problems.add(kind, count=int(bad.size - SHOWN))
    return ok


def _duplicates(
    names: tuple[str, ...],
    codes: np.ndarray,
    indices: np.ndarray,
    lines: np.ndarray,
    keep: np.ndarray,
    problems: Problems,
) -> np.ndarray:
    """``(R,)`` True for a row whose ``(set, index)`` an earlier kept row already has.

    Negative indices are left to the coverage check, which reports them out of range.
    """
    rows = np.flatnonzero(keep & (indices >= 0))
    order = rows[np.lexsort((indices[rows], codes[rows]))]  # stable: equal keys stay in line order
    same = np.zeros(order.size, dtype=bool)
    same[1:] = (codes[order][1:] == codes[order][:-1]) & (indices[order][1:] == indices[order][:-1])
    dup = np.zeros(codes.size, dtype=bool)
    if not same.any():
        return dup
    start = np.maximum.accumulate(np.where(same, 0, np.arange(order.size)))
    rows_dup = order[same]  # rows are in line order, so sorting rows sorts lines
    first_line = lines[order][start][same]
    by_line = np.argsort(rows_dup, kind="stable")
    for k in by_line[:SHOWN]:
        r = rows_dup[k]
        problems.add(
            "duplicate (set, index)",
            f"line {lines[r]} repeats line {first_line[k]} ({names[codes[r]]} {indices[r]})",
        )
    if rows_dup.size > SHOWN:
        problems.add("duplicate (set, index)", count=int(rows_dup.size - SHOWN))
    dup[order[same]] = True
    return dup
