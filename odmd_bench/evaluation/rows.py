"""The rows of a predictions CSV: the checks of each row.

The streaming pass of :func:`~odmd_bench.evaluation.parse.parse_predictions`: records
(:func:`odmd_bench.inputs.records.records`) are read one at a time and kept as flat
arrays (about 30 bytes a row), never as a list of rows. Most files are clean (every row
as ``odmd-bench`` writes it): :meth:`Rows.add_clean` reads those a block of lines at a
time, column by column, to the same arrays; any other file is left to the row-by-row
:meth:`Rows.add`, which alone says what a problem is.
"""

from __future__ import annotations

import csv
import math
import re
from array import array
from collections.abc import Sequence

import numpy as np

from odmd_bench.data.registry import BENCHMARKS, SPLITS
from odmd_bench.evaluation.kinds import MAX_ABS_DEPTH, NONFINITE, OUT_OF_RANGE, TOO_LARGE
from odmd_bench.evaluation.uncertainty import UNCERTAINTY_COLUMNS
from odmd_bench.inputs.problems import SHOWN, Problems, clip, closest, show
from odmd_bench.inputs.records import NONFINITE_CELL, NUMBER
from odmd_bench.inputs.table import PANDAS_BYTES, number_column

_INT = re.compile(r"[+-]?[0-9]+")
_is_int, _is_float = _INT.fullmatch, NUMBER.fullmatch
#: The text of a column of numbers (:func:`_number_columns`).
_NUMBER_CHARS = re.compile(r"[0-9.eE+-]*")
_NAN = float("nan")
_BENCHMARK_NAMES = tuple(sorted(BENCHMARKS))
#: Characters of text :meth:`Rows.add_clean` splits into cells at once (about 200,000
#: rows): its cells are strings for a moment, so a block bounds the memory they take.
_BLOCK_CHARS = 4 * 2**20


class Rows:
    """Accumulates the rows of a file (the streaming pass of :func:`parse_predictions`)."""

    def __init__(self, cols: dict[str, int], width: int) -> None:
        self.cols, self.width = cols, width
        self.at = (cols["split"], cols["set"], cols["index"], cols["depth"], cols.get("benchmark", -1))
        self.fields, self.values = Problems(), Problems()
        self.split_tally: dict[str, list[int]] = {}
        self.bench_tally: dict[str, list[int]] = {}
        self.split_bad, self.bench_bad = Problems(), Problems()
        self.codes: dict[str, int] = {}
        self.code, self.line, self.index = array("i"), array("q"), array("q")
        self.depth, self.index_ok = array("d"), array("b")
        self.nonpositive: dict[int, list[tuple[int, str]]] = {}
        self.n = 0
        self.bulk = False  # a large file (add_clean): its number columns read by pandas
        #: The uncertainty columns present, and their cells as numbers (NaN: not a number).
        self.extra = tuple((c, cols[c]) for c in UNCERTAINTY_COLUMNS if c in cols)
        self.extra_values = {c: array("d") for c, _ in self.extra}

    def add(self, line: int, cells: list[str]) -> None:
        """Check one row and keep what it holds (the hot loop: kept lean on purpose)."""
        self.n += 1
        if len(cells) != self.width:
            self.fields.add(
                "wrong number of fields",
                f"line {line} ({len(cells)} {'field' if len(cells) == 1 else 'fields'})",
                note=f"every row must have {self.width} like the header",
            )
            return
        i_split, i_set, i_index, i_depth, i_bench = self.at
        seen = self.split_tally.get(cells[i_split])
        if seen is None:
            _tally(self.split_tally, cells[i_split], line, SPLITS, self.split_bad, "split")
        else:
            seen[0] += 1
        if i_bench >= 0:
            seen = self.bench_tally.get(cells[i_bench])
            if seen is None:
                _tally(self.bench_tally, cells[i_bench], line, _BENCHMARK_NAMES, self.bench_bad, "benchmark")
            else:
                seen[0] += 1
        name, index_s, depth_s = cells[i_set], cells[i_index], cells[i_depth]
        code = self.codes.setdefault(name, len(self.codes))
        ok = len(index_s) <= 18 and (index_s.isdigit() and index_s.isascii() or _is_int(index_s) is not None)
        if ok:
            index = int(index_s)
        else:
            index = 0
            kind = "index out of range" if _is_int(index_s) else "index is not an integer"
            self.values.add(kind, f"line {line} ({show(index_s)})", at=line)
        depth = float(depth_s) if _is_float(depth_s) else _NAN
        if not -MAX_ABS_DEPTH <= depth <= MAX_ABS_DEPTH:  # NaN too
            depth = self._bad_depth(line, depth_s, depth)
        elif depth <= 0 and ok:
            shown = self.nonpositive.setdefault(code, [])
            if len(shown) < SHOWN:
                shown.append((line, f"line {line} ({name} {index}: {clip(depth_s, 40)})"))
        self.code.append(code)
        self.line.append(line)
        self.index.append(index)
        self.depth.append(depth)
        self.index_ok.append(ok)
        for c, i in self.extra:
            text = cells[i]
            self.extra_values[c].append(float(text) if _is_float(text) else self._bad_cell(c, line, text))

    def add_clean(self, text: str, start: int, line: int) -> bool:
        r"""Add every row of ``text[start:]`` (its first line is file line ``line``) if all are clean.

        Clean: ASCII text, lines ended by ``\n`` or ``\r\n``, no quote, no blank line, no
        line over the csv module's field limit; on every line ``width`` cells, a valid
        split (and benchmark), a set name without surrounding spaces, an index of 1 to 18
        digits and a depth matching the number pattern within :data:`MAX_ABS_DEPTH`. Such
        rows are what :meth:`add` keeps without a problem, and here they become the very
        same arrays, tallies and non-positive depths, read a block of lines at a time
        with whole-column operations (several times faster).

        Returns:
            True when the rows were added; False, having added nothing, when a row is not
            clean: :meth:`add` then reads them all, and says what is wrong.
        """
        if self.n or start >= len(text) or not text.isascii() or text.find('"', start) >= 0:
            return False
        self.bulk = len(text) - start >= PANDAS_BYTES
        crlf = text.find("\r", start) >= 0
        if crlf and text.count("\r", start) != text.count("\r\n", start):
            return False  # a lone \r ends a line too: left to the csv module
        found = _Found()
        at = start
        while at < len(text):
            stop = text.find("\n", at + _BLOCK_CHARS)
            stop = len(text) if stop < 0 else stop + 1
            block = text[at:stop]
            block = block.replace("\r\n", "\n") if crlf else block
            if not self._add_block(block[:-1] if block.endswith("\n") else block, line + found.n, found):
                return False
            at = stop
        self.n = found.n
        self.codes, self.split_tally, self.bench_tally = found.names, found.split_tally, found.bench_tally
        self.nonpositive = found.nonpositive
        self.code = array("i", np.concatenate(found.code).astype(np.int32).tobytes())
        self.line = array("q", np.arange(line, line + found.n, dtype=np.int64).tobytes())
        self.index = array("q", np.concatenate(found.index).tobytes())
        self.depth = array("d", np.concatenate(found.depth).tobytes())
        self.index_ok = array("b", b"\x01" * found.n)
        for c, _ in self.extra:
            self.extra_values[c] = array("d", np.concatenate(found.extra[c]).tobytes())
        return True

    def _add_block(self, block: str, line: int, found: _Found) -> bool:
        """Add the lines of ``block`` (no final line end; the first is file line ``line``) to ``found``."""
        width = self.width
        n = block.count("\n") + 1
        cells = block.replace("\n", ",").split(",")
        if len(cells) != n * width:
            return False
        # Every line has ``width`` cells (not one more here and one fewer there), and no
        # line is longer than a cell may be.
        chars = np.frombuffer(block.encode("ascii"), dtype=np.uint8)
        ends = np.flatnonzero(chars == 10)
        if np.any(np.diff(np.searchsorted(np.flatnonzero(chars == 44), ends), prepend=0) != width - 1):
            return False
        if np.diff(ends, prepend=-1, append=chars.size).max() - 1 > csv.field_size_limit():
            return False
        i_split, i_set, i_index, i_depth, i_bench = self.at
        if not _tally_clean(cells[i_split::width], line, SPLITS, found.split_tally):
            return False
        if i_bench >= 0 and not _tally_clean(
            cells[i_bench::width], line, _BENCHMARK_NAMES, found.bench_tally
        ):
            return False
        names, indices, depths = cells[i_set::width], cells[i_index::width], cells[i_depth::width]
        for name in dict.fromkeys(names):
            if name != name.strip():
                return False
            found.names.setdefault(name, len(found.names))
        # An index of ASCII digits only (str.isdigit of ASCII text), 1 to 18 of them.
        if "" in indices or max(map(len, indices)) > 18 or not "".join(indices).isdigit():
            return False
        if not all(map(_is_float, depths)):
            return False
        depth = np.fromiter(map(float, depths), dtype=np.float64, count=n)
        if not np.all((depth >= -MAX_ABS_DEPTH) & (depth <= MAX_ABS_DEPTH)):
            return False
        extra: dict[str, np.ndarray] = {}
        if self.extra:
            # The level is one value on every row of a good file: read once.
            varied = []
            for c, i in self.extra:
                column = cells[i::width] if c == "level" else []
                if column and column.count(column[0]) == n:
                    if not _is_float(column[0]):
                        return False
                    extra[c] = np.full(n, float(column[0]))
                else:
                    varied.append((c, i))
            numbers = _number_columns(cells, width, [i for _, i in varied], self.bulk) if varied else None
            if varied and numbers is None:
                return False
            for k, (c, _) in enumerate(varied):
                extra[c] = numbers[k]  # type: ignore[index]
            extra = {c: extra[c] for c, _ in self.extra}
        code = np.fromiter(map(found.names.__getitem__, names), dtype=np.int32, count=n)
        index = np.fromiter(map(int, indices), dtype=np.int64, count=n)
        for r in np.flatnonzero(depth <= 0):
            shown = found.nonpositive.setdefault(int(code[r]), [])
            if len(shown) < SHOWN:
                at = line + int(r)
                shown.append((at, f"line {at} ({names[r]} {int(index[r])}: {clip(depths[r], 40)})"))
        found.code.append(code)
        found.index.append(index)
        found.depth.append(depth)
        for c, values in extra.items():
            found.extra.setdefault(c, []).append(values)
        found.n += n
        return True

    def _bad_cell(self, column: str, line: int, text: str) -> float:
        """Record why an uncertainty cell is refused; NaN stands for it from now on."""
        if not text.strip():
            kind = f"{column} is missing (an empty cell)"
        elif NONFINITE_CELL.fullmatch(text):
            kind = f"{column} is NaN or infinite"
        else:
            kind = f"{column} is not a number"
        self.values.add(kind, f"line {line} ({show(text)})", at=line)
        return _NAN

    def _bad_depth(self, line: int, text: str, depth: float) -> float:
        """Record why a depth is refused; NaN stands for it from now on."""
        if depth == depth:  # a number, too large
            kind = TOO_LARGE if math.isinf(depth) else OUT_OF_RANGE
        elif NONFINITE_CELL.fullmatch(text):
            kind = NONFINITE
        else:
            kind = "depth is not a number"
        self.values.add(kind, f"line {line} ({show(text)})", at=line)
        return float("nan")


def _number_columns(cells: list[str], width: int, cols: list[int], bulk: bool) -> np.ndarray | None:
    """``(len(cols), n)`` the number cells of columns ``cols`` of a clean block, or None if one is no number.

    The uncertainty columns, whole columns at once: a column whose text holds only digits,
    ``.``, ``e``, ``E``, ``+`` and ``-`` (one pattern match of the column joined) is a
    column of numbers in the reader's pattern exactly where ``float`` takes every cell
    (on those characters the two grammars are one), and numpy converts it in one pass in
    C, each cell as ``float`` does; in a file of at least
    :data:`~odmd_bench.inputs.table.PANDAS_BYTES`, pandas' C parser does
    (:func:`~odmd_bench.inputs.table.number_column`, several times faster). (A pattern
    match per cell for three more columns would nearly double the time a file takes to
    read.) ``cells`` are the block's cells, row after row.
    """
    n = len(cells) // width
    out = np.empty((len(cols), n))
    for k, col in enumerate(cols):
        column = cells[col::width]
        if _NUMBER_CHARS.fullmatch("".join(column)) is None:
            return None
        if bulk:  # a large file: pandas' C parser
            values = number_column(column)
            if values is None:
                return None
            out[k] = values
            continue
        try:
            out[k] = np.array(column, dtype=np.float64)  # each cell by float
        except ValueError:  # "", "1e", "1.2.3": a cell no number
            return None
    return out


class _Found:
    """What :meth:`Rows.add_clean` has read so far, kept until every block proved clean."""

    def __init__(self) -> None:
        self.n = 0
        self.names: dict[str, int] = {}
        self.split_tally: dict[str, list[int]] = {}
        self.bench_tally: dict[str, list[int]] = {}
        self.nonpositive: dict[int, list[tuple[int, str]]] = {}
        self.code: list[np.ndarray] = []
        self.index: list[np.ndarray] = []
        self.depth: list[np.ndarray] = []
        self.extra: dict[str, list[np.ndarray]] = {}


def _tally_clean(column: list[str], line: int, valid: Sequence[str], tally: dict[str, list[int]]) -> bool:
    """Count a column's values as :func:`_tally` does, row by row; False if one is not valid."""
    for value in dict.fromkeys(column):
        if value not in valid:
            return False
        seen = tally.get(value)
        if seen is None:
            tally[value] = [column.count(value), line + column.index(value)]
        else:
            seen[0] += column.count(value)
    return True


def _tally(
    tally: dict[str, list[int]], value: str, line: int, valid: Sequence[str], bad: Problems, what: str
) -> None:
    seen = tally.get(value)
    if seen is not None:
        seen[0] += 1
    elif value in valid:
        tally[value] = [1, line]
    else:
        bad.add(
            f"unknown {what} in column {what!r}",
            f"line {line} ({show(value)}{closest(value, valid).replace('; ', ': ')})",
            note=f"expected one of {', '.join(valid)}",
        )
