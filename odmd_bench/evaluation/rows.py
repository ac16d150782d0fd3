"""The rows of a predictions CSV: decoding, CSV records and the checks of each row.

The streaming pass of :func:`~odmd_bench.evaluation.parse.parse_predictions`: records
are read one at a time and kept as flat arrays (about 30 bytes a row), never as a list
of rows.
"""

from __future__ import annotations

import csv
import math
import re
from array import array
from collections.abc import Iterator, Sequence

from odmd_bench.data.registry import BENCHMARKS, SPLITS
from odmd_bench.errors import ValidationError
from odmd_bench.evaluation.problems import (
    MAX_ABS_DEPTH,
    NONFINITE,
    OUT_OF_RANGE,
    SHOWN,
    TOO_LARGE,
    Problems,
    clip,
    closest,
    show,
)

_INT = re.compile(r"[+-]?[0-9]+")
_FLOAT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_is_int, _is_float = _INT.fullmatch, _FLOAT.fullmatch
_NAN = float("nan")
_BENCHMARK_NAMES = tuple(sorted(BENCHMARKS))
# A physical line as ``io.StringIO(text, newline="")`` yields it, without copying the text.
_LINE = re.compile(r"[^\r\n]*(?:\r\n?|\n)|[^\r\n]+")
# A run of blank lines (nothing but spaces, tabs and commas) is passed over by one match of
# a character class, so that a file of millions of them is refused in a second, not a
# minute, in constant memory (a repeated group would keep state per line: gigabytes).
_BLANK_CHARS = " \t,\r\n"
_BLANK_RUN = re.compile(f"[{_BLANK_CHARS}]*")


def decode(data: bytes) -> tuple[str | None, str | None]:
    """The file's text, or a problem saying why it is not text."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return data.decode("utf-16"), None
        except UnicodeDecodeError:
            return None, "the file starts with a UTF-16 byte-order mark but is not UTF-16 text"
    nul = data.find(b"\x00")
    if nul >= 0:
        head = data[:200]
        if head.count(b"\x00") * 3 >= len(head) and b"\x00\x00" not in head:
            # Every other byte NUL: text in UTF-16 without its byte-order mark.
            return None, (
                f"the file looks like UTF-16 text without a byte-order mark (a NUL byte at offset {nul}); "
                "save it as UTF-8 CSV"
            )
        return None, f"the file is binary, not a CSV text file (a NUL byte at offset {nul})"
    try:
        return data.decode("utf-8-sig"), None
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        return None, (
            f"the file is not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start}, line {line}); "
            "save it as UTF-8 CSV"
        )


def _line_breaks(text: str, start: int, end: int) -> int:
    r"""How many physical lines ``text[start:end]`` ends (``\r\n``, ``\r`` or ``\n`` each)."""
    return text.count("\n", start, end) + text.count("\r", start, end) - text.count("\r\n", start, end)


class CsvSyntaxError(ValueError):
    """Text that is not valid CSV; the message is the problem, located by line."""


def csv_records(text: str) -> Iterator[tuple[int, list[str]]]:
    r"""Non-blank CSV records, cells stripped, with the (1-based) line each ends on.

    Blank lines and lines of separators only are skipped. A CSV syntax error raises
    :class:`CsvSyntaxError`.

    Examples:
        >>> list(csv_records("a,b\n\n , \r\n,,\nc,d"))
        [(1, ['a', 'b']), (5, ['c', 'd'])]
    """
    skipped = 0  # blank lines passed over here, which the reader's line_num misses

    def lines() -> Iterator[str]:
        nonlocal skipped
        at, end = 0, len(text)
        while at < end:
            if text[at] in _BLANK_CHARS:  # back to the start of the line a blank run ends in
                run = _BLANK_RUN.match(text, at).end()  # type: ignore[union-attr]  # always matches
                cut = max(text.rfind("\n", at, run), text.rfind("\r", at, run)) + 1
                if cut > at:
                    skipped += _line_breaks(text, at, cut)
                    at = cut
                    if at == end:
                        return
            line = _LINE.match(text, at)
            if line is None:
                return
            at = line.end()
            yield line.group()

    reader = csv.reader(lines(), strict=True)
    last = 0
    try:
        for record in reader:
            cells = [c.strip() for c in record]
            if any(cells):
                last = reader.line_num + skipped
                yield last, cells
    except csv.Error as e:
        if "unexpected end of data" in str(e) or "field larger than field limit" in str(e):
            # A quote never closed swallows the rest of the file (or the limit's worth).
            raise CsvSyntaxError(f"not valid CSV: a quote opened after line {last} is never closed") from None
        raise CsvSyntaxError(f"line {max(reader.line_num + skipped, 1)}: not valid CSV ({e})") from None


def records(text: str, title: str) -> Iterator[tuple[int, list[str]]]:
    """:func:`csv_records`, a CSV syntax error raised as a :class:`ValidationError` titled ``title``."""
    try:
        yield from csv_records(text)
    except CsvSyntaxError as e:
        raise ValidationError(title, [str(e)]) from None


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

    def _bad_depth(self, line: int, text: str, depth: float) -> float:
        """Record why a depth is refused; NaN stands for it from now on."""
        if depth == depth:  # a number, too large
            kind = TOO_LARGE if math.isinf(depth) else OUT_OF_RANGE
        elif _NONFINITE.fullmatch(text):
            kind = NONFINITE
        else:
            kind = "depth is not a number"
        self.values.add(kind, f"line {line} ({show(text)})", at=line)
        return float("nan")


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
