"""The rows of a sequences CSV (:mod:`odmd_bench.predict.sequences`): parsed, checked, grouped.

Two readers give the same :class:`Rows`: pandas' C parser for a clean file
(:mod:`odmd_bench.inputs.table`), and a row-by-row reader with :mod:`csv` that locates
each problem, for anything else. Then every rule on cell values is checked
vectorised, and the rows are grouped into sequences ordered by observation. Every
problem goes to one :class:`~odmd_bench.inputs.problems.Problems`, located by line.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass

import numpy as np

from odmd_bench.inputs.bounds import MAX_ABS_DEPTH, MAX_PIXELS, MIN_TRUE_DEPTH, outside
from odmd_bench.inputs.formats import OPTIONAL_SEQUENCE_COLUMNS as OPTIONAL_COLUMNS
from odmd_bench.inputs.formats import ORIENTATION_COLUMNS
from odmd_bench.inputs.formats import SEQUENCE_COLUMNS as REQUIRED_COLUMNS
from odmd_bench.inputs.problems import SHOWN, Problems, show
from odmd_bench.inputs.records import NONFINITE_CELL, NUMBER, CsvSyntaxError, csv_records
from odmd_bench.inputs.table import clean_columns, factorize

_BOX = ("x1", "y1", "x2", "y2")
_CAM = ("cam_x", "cam_y", "cam_z")


_NUMERIC = ("observation", *_BOX, *_CAM)


@dataclass
class Rows:
    """The cells of every row with the right number of fields, as arrays."""

    lines: np.ndarray  # (M,) int, 1-based line of each row
    sequence: np.ndarray  # (M,) object, stripped names
    numbers: np.ndarray  # (M, 8) observation, x1, y1, x2, y2, cam_x, cam_y, cam_z; NaN: empty
    depth: np.ndarray | None  # (M,) NaN: empty
    orientation: np.ndarray | None = None  # (M, 4) cam_qx, cam_qy, cam_qz, cam_qw; NaN: empty
    #: ``sequence`` factorized, where the reader did it already: (codes (M,), names).
    factorized: tuple[np.ndarray, np.ndarray] | None = None


#: A quaternion is refused when its length differs from 1 by more than this.
UNIT_TOLERANCE = 1e-3


def quaternion_norms(q: np.ndarray) -> np.ndarray:
    """The lengths of quaternions (M, 4), without overflow or underflow (scaled by the largest component).

    ``sqrt(sum q^2)`` overflows to infinity for components above about 1e154 (which the
    unit check then let through) and underflows to 0 below 1e-154; the scaled form is
    exact to rounding for any finite value. NaN where a component is NaN.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        top = np.abs(q).max(axis=1)
        safe = np.where(top > 0, top, 1.0)
        unit = q / safe[:, None]
        return top * np.sqrt((unit * unit).sum(axis=1))


def header_columns(data: bytes, problems: Problems) -> tuple[list[str], dict[str, int]] | None:
    """The header's cells and each column's position.

    Returns None where a required column is missing (the problems added to ``problems``).
    """
    end = data.find(b"\n")
    first = data[: end if end >= 0 else len(data)].decode("utf-8")
    try:
        header = [c.strip() for c in next(csv.reader([first.rstrip("\r")]))]
    except (csv.Error, StopIteration):
        header = []
    cols: dict[str, int] = {}
    for i, name in enumerate(header):
        if name in cols:
            problems.add(f"column {name!r} appears more than once in the header")
        cols.setdefault(name, i)
    given = [c for c in ORIENTATION_COLUMNS if c in cols]
    if given and len(given) < len(ORIENTATION_COLUMNS):
        absent = [c for c in ORIENTATION_COLUMNS if c not in cols]
        problems.add(
            f"the camera orientation is given in part: the header has {', '.join(given)} but not "
            f"{', '.join(absent)} (give all four of {', '.join(ORIENTATION_COLUMNS)}, a unit "
            "quaternion, or none)"
        )
    missing = [c for c in REQUIRED_COLUMNS if c not in cols]
    if missing:
        import difflib

        spare = [h for h in header if h not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS]
        for c in missing:
            near = difflib.get_close_matches(c, spare, n=1, cutoff=0.6)
            problems.add(
                f"missing column {c!r}" + (f" (the header has {near[0]!r}: misspelt?)" if near else "")
            )
        if len(header) == 1:
            for sep, name in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")):
                if sep in header[0]:
                    problems.add(f"the header {show(header[0])} seems to use {name} as separator; use commas")
                    break
        problems.add(
            f"expected the columns {', '.join(REQUIRED_COLUMNS)} (optional: depth, and cam_qx, cam_qy, cam_qz, cam_qw together; others are ignored); "
            f"the header is {show(','.join(header), 120)}"
        )
    return None if problems else (header, cols)


def fast_rows(data: bytes, header: list[str], cols: dict[str, int]) -> Rows | None:
    """The rows of a clean file (:func:`~odmd_bench.inputs.table.clean_columns`), or None.

    None sends the file to the careful reader: a quote, a blank line, a line with another
    number of fields, an empty sequence name, a cell of a number column that is neither
    empty nor a number in the reader's pattern. Every line has the header's number of
    fields, so a row's line is its index + 2.
    """
    groups = [[cols[c] for c in _NUMERIC]]
    if "depth" in cols:
        groups.append([cols["depth"]])
    if _orientation(cols):
        groups.append([cols[c] for c in _orientation(cols)])
    found = clean_columns(data, len(header), groups, cols["sequence"])
    if found is None:
        return None
    numbers, *rest = found.numbers
    depth = rest.pop(0)[:, 0] if "depth" in cols else None
    quat = rest.pop(0) if _orientation(cols) else None
    names = np.empty(len(found.values), dtype=object)
    names[:] = found.values
    return Rows(np.arange(found.n) + 2, names[found.codes], numbers, depth, quat, (found.codes, names))


def _orientation(cols: dict[str, int]) -> list[str]:
    """The orientation columns where the header has all four (a part is refused by the header's check)."""
    return list(ORIENTATION_COLUMNS) if all(c in cols for c in ORIENTATION_COLUMNS) else []


def careful_rows(text: str, header: list[str], cols: dict[str, int], problems: Problems) -> Rows:
    """Every row read with :mod:`csv` and every cell checked, each problem located."""
    lines: list[int] = []
    names: list[str] = []
    numbers: list[list[float]] = []
    depths: list[float] = []
    quats: list[list[float]] = []
    width = len(header)
    has_depth = "depth" in cols
    quat_cols = _orientation(cols)
    stream = csv_records(text)
    try:
        next(stream, None)  # the header: line 1, not blank (header_columns read it)
        for line, cells in stream:
            if len(cells) != width:
                problems.add(
                    f"wrong number of fields (every row must have {width}, like the header)",
                    f"line {line} ({len(cells)})",
                )
                continue
            row = []
            for c in _NUMERIC + (("depth",) if has_depth else ()):
                row.append(_cell(cells[cols[c]], c, line, problems))
            quats.append([_cell(cells[cols[c]], c, line, problems) for c in quat_cols])
            lines.append(line)
            names.append(cells[cols["sequence"]])
            numbers.append(row[: len(_NUMERIC)])
            if has_depth:
                depths.append(row[-1])
    except CsvSyntaxError as e:
        problems.add(str(e))
    arr = np.array(numbers, dtype=np.float64).reshape(-1, len(_NUMERIC))
    return Rows(
        np.array(lines, dtype=np.int64),
        np.array(names, dtype=object),
        arr,
        np.array(depths, dtype=np.float64) if has_depth else None,
        np.array(quats, dtype=np.float64).reshape(-1, 4) if quat_cols else None,
    )


def _cell(s: str, column: str, line: int, problems: Problems) -> float:
    """A cell's number, with text that is no number reported to ``problems``.

    NaN for an empty cell, inf for a non-finite one (reported later), 0 for text that is
    no number (reported here).
    """
    if not s:
        return np.nan
    if NUMBER.fullmatch(s):
        return float(s)
    if NONFINITE_CELL.fullmatch(s):
        return np.inf
    problems.add(f"{column} is not a number", f"line {line} ({show(s)})")
    return 0.0


def check_rows(rows: Rows, problems: Problems) -> None:
    """The rules on cell values, vectorised; every breach located by line."""
    lines, num = rows.lines, rows.numbers
    problems.add_lines("sequence is empty", rows.sequence == "", lines)
    for j, c in enumerate(_NUMERIC):
        if c in _BOX:
            continue
        problems.add_lines(f"{c} is empty", np.isnan(num[:, j]), lines)
    for j, c in enumerate(_NUMERIC):
        problems.add_lines(f"{c} is not finite", np.isinf(num[:, j]), lines)
    _bounds(rows, problems)
    box = num[:, 1:5]
    empty = np.isnan(box)
    problems.add_lines(
        "box partly empty (a missed detection leaves all four of x1, y1, x2, y2 empty)",
        empty.any(axis=1) & ~empty.all(axis=1),
        lines,
    )
    detected = ~empty.any(axis=1) & np.isfinite(box).all(axis=1)
    with np.errstate(invalid="ignore"):
        flipped_x = detected & ~(box[:, 2] > box[:, 0])
        flipped_y = detected & ~(box[:, 3] > box[:, 1])
        problems.add_lines("box with x2 <= x1", flipped_x, lines)
        problems.add_lines("box with y2 <= y1", flipped_y, lines)
        # Most boxes "flipped", all with positive x2 and y2: widths and heights, very likely.
        wrong = flipped_x | flipped_y
        if wrong.sum() * 2 > detected.sum() and (box[wrong, 2:] > 0).all():
            problems.add(
                "most boxes end before they start, and their x2 and y2 are all positive: they look "
                "like x, y, width, height; the columns x1, y1, x2, y2 are corners (x2 = x + width, "
                "y2 = y + height)"
            )
        if rows.orientation is not None:
            q = rows.orientation
            for j, c in enumerate(ORIENTATION_COLUMNS):
                problems.add_lines(
                    f"{c} is empty (a camera that does not turn, its positions in its own axes: "
                    "cam_qx, cam_qy, cam_qz, cam_qw = 0, 0, 0, 1)",
                    np.isnan(q[:, j]),
                    lines,
                )
                problems.add_lines(f"{c} is not finite", np.isinf(q[:, j]), lines)
            norm = quaternion_norms(q)
            off = np.isfinite(norm) & ~(np.abs(norm - 1) <= UNIT_TOLERANCE)
            shown = np.empty(len(norm), dtype=object)  # the length, 6 significant digits
            shown[off] = [f"{v:.6g}" for v in norm[off][: SHOWN + 1].tolist()] + [""] * max(
                0, int(off.sum()) - SHOWN - 1
            )
            problems.add_lines(
                f"orientation not a unit quaternion (its length differs from 1 by more than {UNIT_TOLERANCE:g})",
                off,
                lines,
                shown,
            )
        if rows.depth is not None:
            d = rows.depth
            problems.add_lines("depth is not finite", np.isinf(d), lines)
            problems.add_lines(
                "depth must be > 0 (a true depth, metres)", np.isfinite(d) & (d <= 0), lines, d
            )


def _bounds(rows: Rows, problems: Problems) -> None:
    """The shared numeric bounds (:mod:`odmd_bench.inputs.bounds`) on corners, camera and depth."""
    lines, num = rows.lines, rows.numbers
    for j, c in enumerate(_NUMERIC):
        if c in _BOX:
            limit, unit = MAX_PIXELS, "pixels"
        elif c in _CAM:
            limit, unit = MAX_ABS_DEPTH, "m"
        else:
            continue
        out = outside(num[:, j], -limit, limit)
        problems.add_lines(f"{c} is out of range (|{c}| > {limit:g} {unit})", out, lines, num[:, j])
    if rows.depth is not None:
        d = rows.depth
        with np.errstate(invalid="ignore"):
            out = outside(d, MIN_TRUE_DEPTH, MAX_ABS_DEPTH) & (d > 0)  # <= 0 is named apart
        problems.add_lines(
            f"depth is out of range ({MIN_TRUE_DEPTH:g} to {MAX_ABS_DEPTH:g} m)", out, lines, d
        )


def group(rows: Rows, problems: Problems) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Group the rows by sequence.

    Returns:
        ``(names, order, starts, counts)``: the sequences in order of first appearance
        and the rows sorted by sequence then observation.
    """
    codes, names = rows.factorized or factorize(rows.sequence)
    obs = rows.numbers[:, 0]
    order = np.lexsort((obs, codes))
    counts = np.bincount(codes, minlength=len(names))
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    sc, so = codes[order], obs[order]
    dup = np.flatnonzero((sc[1:] == sc[:-1]) & (so[1:] == so[:-1]))
    kind = "observation repeated within a sequence"
    for i in dup[:SHOWN]:
        a, b = order[i], order[i + 1]
        problems.add(
            kind,
            f"lines {rows.lines[a]} and {rows.lines[b]} (sequence {show(str(names[codes[a]]))}, "
            f"observation {obs[a]:g})",
        )
    if dup.size > SHOWN:
        problems.add(kind, count=int(dup.size - SHOWN))
    single = np.flatnonzero((counts == 1) & (names != ""))  # an empty name is reported already
    problems.add_lines(
        "sequence with one observation (at least 2 are needed)",
        np.ones(single.size, dtype=bool),
        rows.lines[order[starts[single]]],
        names[single],
    )
    return names, order, starts, counts
