r"""The fast path of the strict CSV reading: a clean file's columns as arrays, without pandas.

Most files are clean: no quote, every line ended by ``\n`` with exactly the
header's number of commas, every number cell in the form ``odmd-bench`` and most tools
write. :func:`clean_columns` reads such a file a block of lines at a time with whole-array
numpy operations: the separators are found in the bytes, every cell located by its span,
the number cells converted by :func:`~odmd_bench.inputs.decimals.parse_decimals`
(correctly rounded; a cell in another form by Python's ``float``) and a text column's
values factorized. A file that is not clean gives None, having reported nothing: the
row-by-row reader (:func:`~odmd_bench.inputs.records.csv_records`) then reads it, and it
alone says what a problem is. What the two give a clean file is the same.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import as_strided

from odmd_bench.inputs.decimals import FRACTION_DIGITS, LITTLE_ENDIAN, parse_decimals
from odmd_bench.inputs.records import NUMBER_BYTES

#: Bytes of a file read at once (cut at a line end): the work arrays of a block stay in
#: the processor's cache, where whole-array operations are several times faster than on
#: arrays of the whole file.
BLOCK_BYTES = 1 << 19
_COMMA, _NEWLINE, _DOT = 44, 10, 46
_SHORT_TEXT = 16  # text cells up to this many bytes are compared as two 8-byte words
_KEEP_FIRST = np.array(
    [0] + [(1 << (8 * k)) - 1 for k in range(1, 8)] + [(1 << 64) - 1], dtype=np.uint64
)  # keep[k]: the first k bytes of a little-endian word


@dataclass(frozen=True)
class Columns:
    """A clean file's columns.

    Attributes:
        n: rows (the lines after the header).
        numbers: one (n, k) float64 array (C-contiguous) per group of number columns asked
            for, its columns in the order asked; NaN: an empty cell.
        codes: (n,) int64, the text column's value of each row, as an index into ``values``.
        values: the text column's distinct values (stripped of surrounding spaces), in
            order of first appearance.
    """

    n: int
    numbers: tuple[np.ndarray, ...]
    codes: np.ndarray
    values: tuple[str, ...]


def clean_columns(data: bytes, width: int, numbers: list[list[int]], text: int) -> Columns | None:
    r"""The columns of a clean file (module docstring), or None where it is not clean.

    Args:
        data: the file's bytes; its first line is the header (at least
            :data:`~odmd_bench.inputs.decimals.FRACTION_DIGITS` bytes long).
        width: the header's number of fields.
        numbers: the positions of the number columns, in groups: each group's columns
            come back as one array.
        text: the position of the text column whose values are factorized.

    Returns:
        :class:`Columns`, or None where a line is blank or has another number of fields,
        a text value is empty, or a number cell is no number in the reader's pattern, or
        the file holds a quote, a lone ``\r`` or a NUL. ``data`` must be UTF-8 (only a
        text column may hold bytes beyond ASCII).
    """
    if b'"' in data or b"\x00" in data:
        return None
    if b"\r" in data:
        if data.count(b"\r") != data.count(b"\r\n"):
            return None  # a lone \r ends a line too
        data = data.replace(b"\r\n", b"\n")
    if not data.endswith(b"\n"):
        data += b"\n"
    header_end = data.find(b"\n") + 1  # of the data as read here (CRLF made LF)
    if header_end < FRACTION_DIGITS or header_end >= len(data):
        return None
    buf = np.frombuffer(data, dtype=np.uint8)
    cols = np.asarray([c for group in numbers for c in group], dtype=np.int64)
    found: list[np.ndarray] = []  # (k, lines) per block
    codes: list[np.ndarray] = []
    names: dict[str, int] = {}
    at = header_end
    while at < len(data):
        stop = data.find(b"\n", at + BLOCK_BYTES) + 1 or len(data)
        block = _block(data, buf, at, stop, width, cols, text, names)
        if block is None:
            return None
        found.append(block[0])
        codes.append(block[1])
        at = stop
    code = np.concatenate(codes)
    # Each group row-major, filled a block at a time (a block's transpose stays in cache).
    out = [np.empty((code.size, len(group))) for group in numbers]
    done = 0
    for block_values in found:
        n, first = block_values.shape[1], 0
        for group in out:
            group[done : done + n] = block_values[first : first + group.shape[1]].T
            first += group.shape[1]
        done += n
    return Columns(code.size, tuple(out), code, tuple(names))


def _block(
    data: bytes,
    buf: np.ndarray,
    at: int,
    stop: int,
    width: int,
    cols: np.ndarray,
    text: int,
    names: dict[str, int],
) -> tuple[np.ndarray, np.ndarray] | None:
    """The numbers (one row per number column) and text codes of the lines ``data[at:stop]``, or None."""
    b = buf[at:stop]
    special = b == _COMMA
    special |= b == _NEWLINE
    special |= b == _DOT
    where = np.flatnonzero(special)
    where += at
    kind = buf[where]
    is_dot = kind == _DOT
    at_dot = np.flatnonzero(is_dot)
    seps = where[~is_dot] if at_dot.size else where
    if seps.size % width:
        return None
    n = seps.size // width
    grid = seps.reshape(n, width)
    # Every line has ``width`` fields: its last separator is its only line end.
    if np.count_nonzero(kind == _NEWLINE) != n or not (buf[grid[:, -1]] == _NEWLINE).all():
        return None
    # Each cell's decimal point (the last one where it has several: the others are then
    # bytes that are no digit), its end where it has none.
    dots = grid.copy()
    dots.flat[at_dot - np.arange(at_dot.size)] = where[at_dot]
    # Column-major: each number column's cells together.
    end, dot = grid.T[cols].ravel(), dots.T[cols].ravel()
    start = _starts(grid, cols, at).ravel()
    values, done = parse_decimals(buf, start, end, dot)  # an empty cell is not done
    empty = end == start
    values[empty] = np.nan
    done |= empty
    for i in np.flatnonzero(~done).tolist():
        cell = data[start[i] : end[i]]
        if NUMBER_BYTES.fullmatch(cell) is None:  # the row-by-row reader's pattern
            return None
        values[i] = float(cell)
    code = _factorize(data, buf, _starts(grid, np.array([text]), at)[0], grid[:, text], names)
    if code is None:
        return None
    return values.reshape(cols.size, n), code


def _starts(grid: np.ndarray, cols: np.ndarray, at: int) -> np.ndarray:
    """(len(cols), n): where the cells of columns ``cols`` start (the lines start at ``at``)."""
    out = np.empty((cols.size, grid.shape[0]), dtype=grid.dtype)
    for i, c in enumerate(cols.tolist()):
        if c:
            np.add(grid[:, c - 1], 1, out=out[i])
        else:
            out[i, 0] = at
            np.add(grid[:-1, -1], 1, out=out[i, 1:])
    return out


def _factorize(
    data: bytes,
    buf: np.ndarray,
    start: np.ndarray,
    end: np.ndarray,
    names: dict[str, int],
) -> np.ndarray | None:
    """Each row's text value as a code in ``names`` (extended in order of first appearance).

    Rows in a run of one value are compared as bytes, at once; each run's value is then
    looked up once. None where a value is empty once stripped.
    """
    n = start.size
    length = end - start
    if LITTLE_ENDIAN and length.max() <= _SHORT_TEXT and start.max() + _SHORT_TEXT <= buf.size:
        base = buf[: buf.size - buf.size % 8].view(np.uint64)
        words = as_strided(base, shape=(buf.size - 15, 2), strides=(1, 8), writeable=False)[start]
        words &= np.stack(
            (_KEEP_FIRST[np.minimum(length, 8)], _KEEP_FIRST[np.clip(length - 8, 0, 8)]), axis=1
        )
        new = np.empty(n, dtype=bool)
        new[0] = True
        new[1:] = length[1:] != length[:-1]
        new[1:] |= words[1:, 0] != words[:-1, 0]
        new[1:] |= words[1:, 1] != words[:-1, 1]
        runs = np.flatnonzero(new)
    else:
        cells = [data[a:b] for a, b in zip(start.tolist(), end.tolist(), strict=True)]
        runs = np.flatnonzero([True] + [x != y for x, y in zip(cells[1:], cells[:-1], strict=True)])
    # The runs' values joined by line ends into one text: one decode, one split.
    a, size = start[runs], length[runs]
    if not size.all():
        return None
    step = size + 1
    at = np.cumsum(step) - step  # where each value starts in the joined text
    joined = buf[np.arange(int(step.sum())) + np.repeat(a - at, step)]
    joined[at + size] = _NEWLINE
    texts = joined.tobytes().decode("utf-8").split("\n")[:-1]
    edges = np.concatenate((buf[a], buf[a + size - 1]))
    if (edges <= 32).any() or (edges >= 128).any():  # maybe spaces around (beyond ASCII too)
        texts = [t.strip() for t in texts]
        if not all(texts):
            return None
    fresh = list(itertools.filterfalse(names.__contains__, dict.fromkeys(texts)))
    names.update(zip(fresh, range(len(names), len(names) + len(fresh)), strict=True))
    run_codes = np.fromiter(map(names.__getitem__, texts), dtype=np.int64, count=len(texts))
    return np.repeat(run_codes, np.diff(runs, append=n))


def factorize(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(codes, uniques)`` of an object array of strings, uniques in order of first appearance.

    A run of one value is looked up once (the rows of a sequence usually come together).
    """
    n = len(values)
    index: dict[object, int] = {}
    if not n:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=object)
    new = np.ones(n, dtype=bool)
    new[1:] = values[1:] != values[:-1]
    runs = np.flatnonzero(new)
    run_codes = np.fromiter(
        (index.setdefault(v, len(index)) for v in values[runs].tolist()), dtype=np.int64, count=runs.size
    )
    uniques = np.empty(len(index), dtype=object)
    uniques[:] = list(index)
    return np.repeat(run_codes, np.diff(runs, append=n)), uniques


__all__ = ["BLOCK_BYTES", "Columns", "clean_columns", "factorize"]
