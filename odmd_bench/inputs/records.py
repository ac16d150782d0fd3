"""Text and CSV records of an input file, each record located by its line.

The strict reading shared by every CSV the package reads (predictions, sequences):
:func:`decode` turns bytes into text or says why they are not text; :func:`csv_records`
yields the non-blank records with the line each ends on, a CSV syntax error located;
:func:`records` raises it as a :class:`~odmd_bench.errors.ValidationError`.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Iterator

from odmd_bench.errors import ValidationError

#: A number cell as every reader takes it: decimal, optional sign and exponent (no spaces,
#: no ``nan`` or ``inf``, no ``_``); :data:`NUMBER_BYTES` the same on bytes.
NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
NUMBER_BYTES = re.compile(NUMBER.pattern.encode("ascii"))
#: A cell that names a non-finite number (refused as such, not as "no number").
NONFINITE_CELL = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)

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
