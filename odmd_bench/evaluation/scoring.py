"""Reading and validating a predictions file (CONTRACT section 4) and scoring it.

Nothing here prints. :func:`read_predictions` checks a file strictly and names every
problem in one pass (:class:`~odmd_bench.errors.ValidationError`, one line per kind
of problem with its count and the first few offending lines); :func:`score` turns
valid predictions and the sets they refer to into an :class:`EvaluationResult`;
:func:`evaluate` does both, loading the sets through :func:`odmd_bench.load_split`,
which verifies their content hashes. Formatting is :mod:`odmd_bench.evaluation.report`'s job.

The file is read once, as bytes, and never modified; its SHA-256 goes into the
result's provenance. A UTF-8 byte-order mark (or UTF-16 with one), Windows or old Mac
line ends, surrounding spaces in a cell, blank lines, extra columns and any row order
are accepted. Numbers are parsed by Python's ``float`` and ``int`` after a strict
pattern check, so a depth written with ``repr`` precision is read back bit for bit.
"""

from __future__ import annotations

import csv
import difflib
import hashlib
import io
import os
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.data.registry import BENCHMARKS, DEFAULT_BENCHMARK, SPLITS, Benchmark, get_benchmark
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.evaluation.metrics import all_sets_mean, percent_error, set_metrics

#: Columns every predictions file must have.
REQUIRED_COLUMNS: tuple[str, ...] = ("split", "set", "index", "depth")
#: Columns that are read when present; any other column is ignored.
OPTIONAL_COLUMNS: tuple[str, ...] = ("benchmark",)
#: How many offending lines a problem shows.
SHOWN = 5

_INT = re.compile(r"[+-]?[0-9]+")
_FLOAT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)

#: ``(benchmark, split) -> {set: number of examples}`` for the sets being scored.
SetSizes = Callable[[str, str], Mapping[str, int]]


@dataclass(frozen=True)
class Predictions:
    """A validated predictions file.

    Attributes:
        path: the file as given.
        sha256: SHA-256 of the file's bytes.
        benchmark, split: what the file holds.
        depths: ``{set: (N,) float64}``, the estimate of example ``i`` at position ``i``,
            for the sets in scope (all of the benchmark's, or those asked for).
        n_rows: number of data rows in the file.
        ignored_columns: columns other than the required and optional ones.
        warnings: legal but suspicious things (zero or negative depths, rows of sets
            that were not asked for), one line each.
    """

    path: str
    sha256: str
    benchmark: str
    split: str
    depths: dict[str, np.ndarray]
    n_rows: int
    ignored_columns: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class EvaluationResult:
    """Scores of one predictions file, with what is needed to reproduce them.

    Attributes:
        benchmark, split: what was scored.
        sets: ``{set: {"n", "percent_error": {mean, median, min, max, std},
            "absolute_error": {...}}}`` in the benchmark's set order.
        all_percent_error_mean: ``All``, the mean of the sets' mean percent errors.
        provenance: package version, benchmark, split, each set's content SHA-256, the
            predictions file's SHA-256 and name.
        warnings: one line each (see :class:`Predictions`).
        predictions: ``{set: (N,)}`` the estimates scored.
        examples: ``{set: Examples}`` the sets scored (truth and what explains errors).
    """

    benchmark: str
    split: str
    sets: dict[str, dict[str, Any]]
    all_percent_error_mean: float
    provenance: dict[str, Any]
    warnings: tuple[str, ...] = ()
    predictions: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    examples: dict[str, Examples] = field(default_factory=dict, repr=False)

    def percent_errors(self) -> dict[str, np.ndarray]:
        """``{set: (N,)}`` per-example percent errors."""
        return {s: percent_error(self.examples[s].depth, self.predictions[s]) for s in self.sets}

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of CONTRACT section 5 (plus ``warnings``)."""
        return {
            "benchmark": self.benchmark,
            "split": self.split,
            "sets": {s: dict(m) for s, m in self.sets.items()},
            "all": {"percent_error_mean": self.all_percent_error_mean, "sets": list(self.sets)},
            "provenance": dict(self.provenance),
            "warnings": list(self.warnings),
        }


class _Problems:
    """Problems grouped by kind, each with a count and the first few occurrences."""

    def __init__(self) -> None:
        self._kinds: dict[str, list[str]] = {}
        self._counts: dict[str, int] = {}
        self._notes: dict[str, str] = {}

    def add(self, kind: str, where: str | None = None, note: str = "") -> None:
        self._counts[kind] = self._counts.get(kind, 0) + 1
        shown = self._kinds.setdefault(kind, [])
        if where is not None and len(shown) < SHOWN:
            shown.append(where)
        if note and kind not in self._notes:
            self._notes[kind] = note

    def __bool__(self) -> bool:
        return bool(self._counts)

    def lines(self) -> list[str]:
        out = []
        for kind, shown in self._kinds.items():
            n = self._counts[kind]
            line = kind
            if shown:
                more = f", ... ({n - len(shown)} more)" if n > len(shown) else ""
                line += f" ({n} {'row' if n == 1 else 'rows'}): " + ", ".join(shown) + more
            if kind in self._notes:
                line += f"; {self._notes[kind]}"
            out.append(line)
        return out


def _closest(value: str, choices: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the choice closest to ``value``, or ``""``."""
    choices = list(choices)
    folded = {c.lower(): c for c in choices}
    if value.strip().lower() in folded:
        return f"; did you mean {folded[value.strip().lower()]!r}?"
    match = difflib.get_close_matches(value.strip().lower(), list(folded), n=1, cutoff=0.6)
    return f"; did you mean {folded[match[0]]!r}?" if match else ""


def _show(value: str, limit: int = 40) -> str:
    return repr(value if len(value) <= limit else value[:limit] + "...")


def _decode(data: bytes) -> tuple[str | None, str | None]:
    """The file's text, or a problem saying why it is not text."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return data.decode("utf-16"), None
        except UnicodeDecodeError:
            return None, "the file starts with a UTF-16 byte-order mark but is not UTF-16 text"
    nul = data.find(b"\x00")
    if nul >= 0:
        return None, f"the file is binary, not a CSV text file (a NUL byte at offset {nul})"
    try:
        return data.decode("utf-8-sig"), None
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        return None, (
            f"the file is not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start}, line {line}); "
            "save it as UTF-8 CSV"
        )


def _rows(text: str) -> tuple[list[tuple[int, list[str]]], str | None]:
    """Non-blank CSV records with the (1-based) line each ends on, or a CSV error."""
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    rows: list[tuple[int, list[str]]] = []
    try:
        for record in reader:
            cells = [c.strip() for c in record]
            if any(cells):  # skip blank lines and lines of separators only
                rows.append((reader.line_num, cells))
    except csv.Error as e:
        if "unexpected end of data" in str(e):
            after = rows[-1][0] if rows else 0
            return rows, f"not valid CSV: a quote opened after line {after} is never closed"
        return rows, f"line {max(reader.line_num, 1)}: not valid CSV ({e})"
    return rows, None


def _check_header(header: list[str], problems: _Problems) -> dict[str, int] | None:
    """Column positions by name, or None when a required column is missing."""
    cols: dict[str, int] = {}
    for i, name in enumerate(header):
        if name in cols:
            problems.add(f"column {name!r} appears more than once in the header")
        else:
            cols[name] = i
    missing = [c for c in REQUIRED_COLUMNS if c not in cols]
    if not missing:
        return None if problems else cols
    spare = [h for h in header if h not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS]
    for c in missing:
        near = _closest(c, spare)
        found = near[len("; did you mean ") : -1] if near else ""
        problems.add(f"missing column {c!r}" + (f" (the header has {found}: misspelt?)" if found else ""))
    if len(header) == 1:
        for sep, name in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")):
            if sep in header[0]:
                problems.add(f"the header {_show(header[0])} seems to use {name} as separator; use commas")
                break
    problems.add(
        f"the header is {', '.join(repr(h) for h in header)}; expected the columns "
        f"{', '.join(REQUIRED_COLUMNS)} (optional: {', '.join(OPTIONAL_COLUMNS)}; others are ignored)"
    )
    return None


def _single_value(
    column: str,
    values: list[tuple[int, str]],
    valid: Sequence[str],
    problems: _Problems,
    what: str,
) -> str | None:
    """The one valid value a column holds, or None (with problems added)."""
    by_value: dict[str, list[int]] = {}
    for line, v in values:
        if v in valid:
            by_value.setdefault(v, []).append(line)
        else:
            problems.add(
                f"unknown {what} in column {column!r}",
                f"line {line} ({_show(v)}{_closest(v, valid).replace('; ', ': ')})",
                note=f"expected one of {', '.join(valid)}",
            )
    if len(by_value) > 1:
        parts = [
            f"{v} ({len(lines)} {'row' if len(lines) == 1 else 'rows'}, first on line {lines[0]})"
            for v, lines in by_value.items()
        ]
        problems.add(f"a file holds one {what}, this one has {len(by_value)}: {', '.join(parts)}")
        return None
    return next(iter(by_value), None)


def read_predictions(
    path: str | os.PathLike[str],
    *,
    set_sizes: SetSizes,
    benchmark: str | None = None,
    sets: Sequence[str] | None = None,
) -> Predictions:
    """Read and validate a predictions CSV, naming every problem at once.

    Parameters
    ----------
    path : path of the CSV file (read once; never modified)
    set_sizes : callable ``(benchmark, split) -> {set: N}``
        Sizes of the sets in scope, called once the file's benchmark and split are
        known (:func:`evaluate` loads the sets here).
    benchmark : str, optional
        The benchmark the file is for. Default: the file's ``benchmark`` column, else
        ``odmd-v1``. A file whose ``benchmark`` column says otherwise is refused.
    sets : sequence of str, optional
        Score only these sets; rows of other sets are ignored (with a warning). By
        default every set of the benchmark must be covered.

    Returns
    -------
    Predictions

    Raises
    ------
    ValidationError
        When the file cannot be scored; ``problems`` has one line per kind of
        problem with its count and the first few offending lines (line 1 is the header).
    UsageError
        For an unknown ``benchmark`` or ``sets`` argument.
    """
    if benchmark is not None and sets is not None:
        _check_sets(sets, get_benchmark(benchmark))
    elif benchmark is not None:
        get_benchmark(benchmark)
    p = Path(path)
    title = f"{p} cannot be scored"
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise ValidationError(title, [f"no such file: {p}"]) from None
    except IsADirectoryError:
        raise ValidationError(title, [f"{p} is a folder, not a predictions CSV file"]) from None
    except OSError as e:
        raise ValidationError(title, [f"the file cannot be read ({e.strerror or e})"]) from None
    sha256 = hashlib.sha256(data).hexdigest()
    if not data.strip():
        raise ValidationError(
            title,
            [
                f"the file is empty; expected a header line {','.join(REQUIRED_COLUMNS)} and one row per example"
            ],
        )
    text, problem = _decode(data)
    if text is None:
        raise ValidationError(title, [problem or "the file is not text"])
    rows, csv_problem = _rows(text)
    if csv_problem:
        raise ValidationError(title, [csv_problem])
    if not rows:
        raise ValidationError(title, ["the file holds no header and no rows"])

    problems = _Problems()
    (_, header), body = rows[0], rows[1:]
    cols = _check_header(header, problems)
    if cols is None:
        raise ValidationError(title, problems.lines())
    if not body:
        raise ValidationError(title, ["the file has a header but no rows; expected one row per example"])
    ignored = tuple(h for h in header if h not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS)

    width = len(header)
    good: list[tuple[int, list[str]]] = []
    for line, cells in body:
        if len(cells) != width:
            problems.add(
                "wrong number of fields",
                f"line {line} ({len(cells)} {'field' if len(cells) == 1 else 'fields'})",
                note=f"every row must have {width} like the header",
            )
        else:
            good.append((line, cells))

    # Benchmark: the argument, the column, or the default; they must agree.
    bench: Benchmark | None
    if "benchmark" in cols:
        from_file = _single_value(
            "benchmark",
            [(ln, c[cols["benchmark"]]) for ln, c in good],
            sorted(BENCHMARKS),
            problems,
            "benchmark",
        )
        if benchmark is not None and from_file is not None and from_file != benchmark:
            problems.add(f"the file's benchmark column says {from_file!r} but --benchmark is {benchmark!r}")
            bench = None
        else:
            name = benchmark or from_file
            bench = BENCHMARKS[name] if name else None
    else:
        bench = get_benchmark(benchmark or DEFAULT_BENCHMARK)
    scope: tuple[str, ...] | None = None
    if bench is not None:
        scope = _check_sets(sets, bench) if sets is not None else bench.sets

    split = _single_value("split", [(ln, c[cols["split"]]) for ln, c in good], SPLITS, problems, "split")

    # Per-row values: set, index, depth. A row whose set and index are valid counts as
    # present (for duplicates and gaps) even when its depth is bad, so that one bad
    # depth is reported once, not also as a missing example.
    parsed: list[tuple[int, str, int, float]] = []
    ignored_rows: dict[str, int] = {}
    nonpositive: list[str] = []
    n_nonpositive = 0
    for line, cells in good:
        set_name, index_s, depth_s = cells[cols["set"]], cells[cols["index"]], cells[cols["depth"]]
        key_ok = True
        if bench is not None and set_name not in bench.sets:
            problems.add(
                f"unknown set for benchmark {bench.name!r}",
                f"line {line} ({_show(set_name)}{_closest(set_name, bench.sets).replace('; ', ': ')})",
                note=f"expected one of {', '.join(bench.sets)}",
            )
            key_ok = False
        index = 0
        if _INT.fullmatch(index_s) and len(index_s) <= 18:
            index = int(index_s)
        elif _INT.fullmatch(index_s):
            problems.add("index out of range", f"line {line} ({_show(index_s)})")
            key_ok = False
        else:
            problems.add("index is not an integer", f"line {line} ({_show(index_s)})")
            key_ok = False
        depth = np.nan
        if _FLOAT.fullmatch(depth_s):
            depth = float(depth_s)
            if not np.isfinite(depth):
                problems.add("depth is too large to be a finite float64", f"line {line} ({_show(depth_s)})")
                depth = np.nan
        elif _NONFINITE.fullmatch(depth_s):
            problems.add("depth is NaN or infinite", f"line {line} ({_show(depth_s)})")
        else:
            problems.add("depth is not a number", f"line {line} ({_show(depth_s)})")
        if not key_ok:
            continue
        if scope is not None and set_name not in scope:
            ignored_rows[set_name] = ignored_rows.get(set_name, 0) + 1
            continue
        if depth <= 0:
            n_nonpositive += 1
            if len(nonpositive) < SHOWN:
                nonpositive.append(f"line {line} ({set_name} {index}: {depth_s})")
        parsed.append((line, set_name, index, depth))

    depths: dict[str, np.ndarray] = {}
    if bench is not None and scope is not None:
        # Sizes need the split; without one, duplicates are still found.
        sizes = dict(set_sizes(bench.name, split)) if split is not None else None
        depths = _place(parsed, scope, sizes, problems, explicit_sets=sets is not None, bench=bench)
    if problems:
        lines = problems.lines()
        raise ValidationError(
            f"{title}: {len(lines)} {'problem' if len(lines) == 1 else 'problems'} found", lines
        )
    if bench is None or split is None:  # pragma: no cover - each such case adds a problem above
        raise ValidationError(title, ["the file's benchmark or split could not be determined"])

    warnings = []
    if n_nonpositive:
        more = f", ... ({n_nonpositive - len(nonpositive)} more)" if n_nonpositive > len(nonpositive) else ""
        warnings.append(
            f"{n_nonpositive} {'depth is' if n_nonpositive == 1 else 'depths are'} zero or negative "
            f"(scored as given): {', '.join(nonpositive)}{more}"
        )
    if ignored_rows:
        parts = ", ".join(f"{s} ({n} rows)" for s, n in ignored_rows.items())
        warnings.append(f"ignored rows of sets not asked for: {parts}")
    return Predictions(
        path=str(p),
        sha256=sha256,
        benchmark=bench.name,
        split=split,
        depths=depths,
        n_rows=len(body),
        ignored_columns=ignored,
        warnings=tuple(warnings),
    )


def _check_sets(sets: Sequence[str], bench: Benchmark) -> tuple[str, ...]:
    names = [s.strip() for s in sets if s.strip()]
    if not names:
        raise UsageError(f"no sets named; expected some of {', '.join(bench.sets)}")
    unknown = [s for s in names if s not in bench.sets]
    if unknown:
        raise UsageError(
            f"unknown set {unknown[0]!r} for benchmark {bench.name!r}; expected some of "
            f"{', '.join(bench.sets)}{_closest(unknown[0], bench.sets)}"
        )
    # Benchmark order, each once, so that results do not depend on how --sets was typed.
    return tuple(s for s in bench.sets if s in names)


def _place(
    parsed: list[tuple[int, str, int, float]],
    scope: tuple[str, ...],
    sizes: Mapping[str, int] | None,
    problems: _Problems,
    *,
    explicit_sets: bool,
    bench: Benchmark,
) -> dict[str, np.ndarray]:
    """Put each estimate at its index; find duplicates and, given the sizes, indices
    out of range and examples without a row. (A bad depth arrives as NaN; its
    problem is already recorded.)"""
    depths = {s: np.full(int(sizes[s]), np.nan) for s in scope} if sizes is not None else {}
    seen = {s: np.zeros(int(sizes[s]), dtype=bool) for s in scope} if sizes is not None else {}
    first_line: dict[tuple[str, int], int] = {}
    for line, set_name, index, depth in parsed:
        if sizes is not None:
            n = int(sizes[set_name])
            if not 0 <= index < n:
                problems.add(
                    "index out of range",
                    f"line {line} ({set_name} {index}; {set_name} has {n} examples, indices 0..{n - 1})",
                )
                continue
        key = (set_name, index)
        if key in first_line:
            problems.add(
                "duplicate (set, index)",
                f"line {line} repeats line {first_line[key]} ({set_name} {index})",
            )
            continue
        first_line[key] = line
        if sizes is not None:
            depths[set_name][index] = depth
            seen[set_name][index] = True
    for s in scope if sizes is not None else ():
        gaps = np.flatnonzero(~seen[s])
        if gaps.size == len(depths[s]):
            hint = (
                "it was named by --sets"
                if explicit_sets
                else f"to score only some sets, name them, e.g. --sets {','.join(x for x in scope if x != s)}"
            )
            problems.add(f"set {s!r} of benchmark {bench.name!r} has no rows ({hint})")
        elif gaps.size:
            shown = ", ".join(str(i) for i in gaps[:SHOWN])
            more = ", ..." if gaps.size > SHOWN else ""
            problems.add(
                f"{gaps.size} of the {len(depths[s])} examples of set {s!r} have no row "
                f"(missing indices {shown}{more})"
            )
    return depths


def score(predictions: Predictions, examples: Mapping[str, Examples]) -> EvaluationResult:
    """Score validated predictions against the sets they refer to.

    Parameters
    ----------
    predictions : Predictions
    examples : ``{set: Examples}`` holding at least the sets of ``predictions.depths``.

    Returns
    -------
    EvaluationResult
    """
    from odmd_bench import __version__

    per_set: dict[str, dict[str, Any]] = {}
    preds: dict[str, np.ndarray] = {}
    used: dict[str, Examples] = {}
    for s, depth in predictions.depths.items():
        ex = examples[s]
        if len(ex) != len(depth):
            raise ValidationError(
                f"{predictions.path} cannot be scored",
                [f"set {s!r} has {len(ex)} examples but {len(depth)} estimates"],
            )
        per_set[s] = set_metrics(ex.depth, depth)
        preds[s] = depth.copy()
        used[s] = ex
    all_mean = all_sets_mean({s: m["percent_error"]["mean"] for s, m in per_set.items()})
    provenance = {
        "package": "odmd-bench",
        "version": __version__,
        "benchmark": predictions.benchmark,
        "split": predictions.split,
        "sets_content_sha256": {s: str(used[s].attrs.get("content_sha256", "")) for s in per_set},
        "predictions_file": Path(predictions.path).name,
        "predictions_sha256": predictions.sha256,
        "predictions_rows": predictions.n_rows,
        "ignored_columns": list(predictions.ignored_columns),
    }
    return EvaluationResult(
        benchmark=predictions.benchmark,
        split=predictions.split,
        sets=per_set,
        all_percent_error_mean=all_mean,
        provenance=provenance,
        warnings=predictions.warnings,
        predictions=preds,
        examples=used,
    )


def evaluate(
    path: str | os.PathLike[str],
    *,
    benchmark: str | None = None,
    data_dir: str | os.PathLike[str] | None = None,
    sets: Sequence[str] | None = None,
) -> EvaluationResult:
    """Validate a predictions file and score it against the benchmark's sets.

    Parameters
    ----------
    path : the predictions CSV (CONTRACT section 4)
    benchmark : default the file's ``benchmark`` column, else ``odmd-v1``
    data_dir : the data folder (default ``$ODMD_BENCH_DATA`` or the documented default)
    sets : score only these sets (default: all of the benchmark's)

    Returns
    -------
    EvaluationResult

    Raises
    ------
    ValidationError
        When the file cannot be scored (every problem named at once).
    DataError, UsageError
        When the sets cannot be loaded, or for unknown arguments.

    Examples
    --------
    >>> result = evaluate("preds.csv", benchmark="odmd-paper")  # doctest: +SKIP
    >>> round(result.all_percent_error_mean, 2)  # doctest: +SKIP
    11.83
    """
    from odmd_bench.data.store import load_split

    loaded: dict[str, Examples] = {}

    def sizes(bench: str, split: str) -> dict[str, int]:
        names = list(sets) if sets is not None else None
        if names is not None:
            names = list(_check_sets(names, get_benchmark(bench)))
        loaded.update(load_split(split, bench, data_dir, names))
        return {s: len(ex) for s, ex in loaded.items()}

    preds = read_predictions(path, set_sizes=sizes, benchmark=benchmark, sets=sets)
    return score(preds, loaded)
