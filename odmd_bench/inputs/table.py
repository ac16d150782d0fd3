r"""The fast path of the strict CSV reading: a clean file's columns at once, by pandas.

Most files are clean: no quote, every line ended by ``\n`` (or ``\r\n``) with exactly the
header's number of commas, every number cell a number in the readers' pattern without
spaces around it, every name not empty. :func:`clean_columns` reads such a file with
``pandas.read_csv`` (its C engine; pandas, one of the package's dependencies, is
imported here, so only when a file is read this way: its import costs about half a
second, which a small file never repays, see :data:`PANDAS_BYTES`). Byte checks before
and after decide "clean"; a file that is not gives None, having reported nothing: the
row-by-row reader (:func:`~odmd_bench.inputs.records.csv_records`) then reads it, and it
alone says what a problem is. What the two give a clean file is the same: pandas
converts every number cell correctly rounded, as Python's ``float`` (pandas 3.1 always;
before it, asked for ``float_precision="round_trip"``, which calls Python's own parser).
"""

from __future__ import annotations

import io
import re
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Files of fewer bytes are read row by row (the caller decides): the row reader reads
#: them in about the time importing pandas takes. Measured (``read_sequences`` in a fresh
#: process, CPU seconds, AMD EPYC): 3.1 MB (20,000 rows) 0.77 row by row, 0.83 with
#: pandas' import; 7.8 MB 1.44 against 0.74; 0.8 MB 0.44 against 0.73.
PANDAS_BYTES = 4 << 20
_SPACES = (b" ", b"\t", b"\x0b", b"\x0c")  # what pandas' number parser skips around a number


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
        data: the file's bytes, UTF-8 (no byte-order mark); its first line is the header.
        width: the header's number of fields.
        numbers: the positions of the number columns, in groups: each group's columns
            come back as one array.
        text: the position of the text column whose values are factorized.

    Returns:
        :class:`Columns`, or None where the file holds a quote, a lone ``\r`` or a NUL, a
        line is blank or has another number of fields, a text value is empty, or a number
        cell is neither empty nor a finite number in the readers' pattern.
    """
    if b'"' in data or b"\x00" in data:
        return None
    if b"\r" in data and data.count(b"\r") != data.count(b"\r\n"):
        return None  # a lone \r ends a line too
    header_end = data.find(b"\n") + 1
    first_end = data.find(b"\n", header_end)
    if not header_end or header_end >= len(data):
        return None
    # Every line has the header's number of fields: pandas refuses a longer one, except
    # the first (read as more data, with a warning), which is counted here; with the total
    # of commas right no line then has fewer (a blank line has none).
    n_lines = data.count(b"\n", header_end) + (not data.endswith(b"\n"))
    if data.count(b",", header_end, first_end if first_end >= 0 else len(data)) != width - 1:
        return None
    if data.count(b",", header_end) != (width - 1) * n_lines:
        return None
    cols = sorted({c for group in numbers for c in group})
    frame = _read(data, width, cols, text)
    if frame is None or len(frame) != n_lines:
        return None
    out = tuple(np.ascontiguousarray(frame[group].to_numpy(dtype=np.float64)) for group in numbers)
    if any(np.isinf(group).any() for group in out):
        return None  # "inf", or too large: the row reader names it
    if not _numbers_plain(data, header_end, width, cols, out, numbers):
        return None
    found = _factorize(frame[text].to_numpy(dtype=object))
    if found is None:
        return None
    return Columns(n_lines, out, *found)


def _read(data: bytes, width: int, cols: list[int], text: int) -> Any:
    """The data rows' columns ``cols`` (float64) and ``text`` (str), or None where pandas refuses them."""
    import pandas as pd

    names = list(range(width))
    dtypes: dict[int, Any] = {c: np.float64 for c in cols}
    dtypes[text] = object
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", pd.errors.ParserWarning)
            return pd.read_csv(
                io.BytesIO(data),
                header=None,
                skiprows=1,
                names=names,
                usecols=sorted({*cols, text}),
                dtype=dtypes,
                keep_default_na=False,
                na_values=[""],
                index_col=False,
                encoding="utf-8",
                engine="c",
                low_memory=False,
                **_round_trip(pd.__version__),
            )
    except (ValueError, pd.errors.ParserError, pd.errors.ParserWarning):
        return None  # a cell that is no number, a line too long, text not UTF-8


def _round_trip(version: str) -> dict[str, Any]:
    """``read_csv`` options that convert every decimal to the nearest float64, as ``float`` does.

    pandas before 3.1 reads with a faster parser that can miss by one unit in the last
    place (17-digit decimals) unless asked for ``float_precision="round_trip"`` (Python's
    own parser); pandas 3.1 always rounds right and deprecates the option.
    """
    major, minor = (int(x) for x in re.findall(r"\d+", version)[:2])
    return {"float_precision": "round_trip"} if (major, minor) < (3, 1) else {}


def number_column(cells: list[str]) -> np.ndarray | None:
    """(n,) float64 of cells that hold only digits, ``.``, ``e``, ``E``, ``+`` and ``-``, by pandas.

    The predictions reader's uncertainty columns of a large file (the caller checks the
    characters: on them pandas, the readers' number pattern and ``float`` agree). None
    where a cell is no number (``""``, ``"1e"``, ``"1.2.3"``).
    """
    import pandas as pd

    try:
        frame = pd.read_csv(
            io.StringIO("\n".join(cells)),
            header=None,
            names=[0],
            dtype={0: np.float64},
            na_filter=False,
            skip_blank_lines=False,
            engine="c",
            low_memory=False,
            **_round_trip(pd.__version__),
        )
    except (ValueError, pd.errors.ParserError):
        return None
    values = frame[0].to_numpy(dtype=np.float64)
    return values if values.size == len(cells) else None


def _numbers_plain(
    data: bytes,
    header_end: int,
    width: int,
    cols: list[int],
    out: tuple[np.ndarray, ...],
    numbers: list[list[int]],
) -> bool:
    """Whether no number cell has spaces around it, and every NaN is an empty cell.

    pandas skips the spaces around a number (the row reader too, but it takes such a file
    as not clean); before 3.1 it also reads ``nan`` as NaN. Both are rare, so the cells
    are located (every separator found) only where the bytes say they may be.
    """
    spaces = any(s in data for s in _SPACES)
    maybe_nan = bool(_round_trip(_pandas_version())) and b"nan" in data.lower()
    if not spaces and not (maybe_nan and any(np.isnan(g).any() for g in out)):
        return True
    buf = np.frombuffer(data, dtype=np.uint8)
    seps = np.flatnonzero((buf[header_end:] == 44) | (buf[header_end:] == 10)) + header_end
    if not data.endswith(b"\n"):
        seps = np.append(seps, len(data))
    starts = np.concatenate(([header_end], seps[:-1] + 1))
    is_number = np.zeros(width, dtype=bool)
    is_number[cols] = True
    if spaces:
        at = np.flatnonzero(np.isin(buf[header_end:], np.frombuffer(b"".join(_SPACES), np.uint8)))
        if is_number[np.searchsorted(seps, at + header_end) % width].any():
            return False
    if maybe_nan:
        length = seps - starts
        length -= (length > 0) & (buf[np.maximum(seps - 1, 0)] == 13)  # the \r of a \r\n
        for group, columns in zip(out, numbers, strict=True):
            rows, k = np.nonzero(np.isnan(group))
            if (length[rows * width + np.asarray(columns)[k]] != 0).any():
                return False
    return True


def _pandas_version() -> str:
    import pandas as pd

    return str(pd.__version__)


def _factorize(names: np.ndarray) -> tuple[np.ndarray, tuple[str, ...]] | None:
    """``(codes, values)`` of the text column, stripped; None where a value is empty once stripped."""
    import pandas as pd

    codes, uniques = pd.factorize(names, sort=False, use_na_sentinel=True)
    if codes.size and codes.min() < 0:
        return None  # an empty cell
    index: dict[str, int] = {}
    remap = np.fromiter(
        (index.setdefault(str(u).strip(), len(index)) for u in uniques.tolist()),
        dtype=np.int64,
        count=len(uniques),
    )
    if "" in index:
        return None
    return remap[codes], tuple(index)


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


__all__ = ["PANDAS_BYTES", "Columns", "clean_columns", "factorize", "number_column"]
