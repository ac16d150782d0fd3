"""A user's own detections and odometry, in pixels and metres, as :class:`Examples`.

The sequences format (``docs/own-data.md``) is a CSV file with one row per observation:

======================  ================================================================
column                  meaning
======================  ================================================================
``sequence``            name of the sequence the row belongs to (any text)
``observation``         its position in the sequence (a frame number or a time stamp:
                        any number); rows are ordered by it, the last is estimated
``x1, y1, x2, y2``      the detection's box corners in pixels, as detectors write them;
                        all four empty: the detector found nothing (missed detection)
``cam_x, cam_y, cam_z`` the camera position in metres, in any fixed frame whose axes are
                        the camera's (the camera translates without rotating)
``depth`` (optional)    the true depth along the optical axis, metres, where known; the
                        last observation's is the truth the estimate is scored against
======================  ================================================================

Rows may come in any order; other columns are ignored. The conversion to the package's
convention (CONTRACT section 1) is exact up to rounding::

    x = (x1 + x2) / 2 / W      w = (x2 - x1) / W      (W, H: image width, height)
    y = (y1 + y2) / 2 / H      h = (y2 - y1) / H
    camera_k = cam_k - cam_last

Missed detections become ``detected = False`` with a zero box (as the original
release stores them); each method then applies the shared missing-detection rule.

Reading is strict in the way the predictions reader is: a file with a problem is refused
as a whole (:class:`~odmd_bench.errors.ValidationError`) naming every kind of problem
with its count and first lines. A well-formed file is parsed by the pandas C parser
(vectorised) after byte-level checks (no quote, the header's number of commas on every
line); anything else (quoted cells, blank lines, a problem) goes to a row-by-row reader
that locates each problem, with Python's ``float``. The two gave the same float for each
of 4.4 million decimal strings of 1 to 20 digits tried, and ``repr``-written numbers come
back exactly. A UTF-8 byte-order mark, CRLF line ends, UTF-16 with a byte-order mark and
gzip-compressed files are accepted.
"""

from __future__ import annotations

import csv
import inspect
import io
import os
import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DataError, UsageError, ValidationError

#: Columns every sequences file must have, in the order files are written.
REQUIRED_COLUMNS: tuple[str, ...] = (
    "sequence",
    "observation",
    "x1",
    "y1",
    "x2",
    "y2",
    "cam_x",
    "cam_y",
    "cam_z",
)
#: Columns read when present; any other column is ignored.
OPTIONAL_COLUMNS: tuple[str, ...] = ("depth",)
#: Offending lines shown per kind of problem.
SHOWN = 5

_BOX = ("x1", "y1", "x2", "y2")
_CAM = ("cam_x", "cam_y", "cam_z")
_NUMERIC = ("observation", *_BOX, *_CAM)
_FLOAT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)

ImageSize = tuple[float, float]
Intrinsics = tuple[float, float, float, float]


# --- arrays ------------------------------------------------------------------------------------


def _image_size(image_size: Sequence[float]) -> tuple[float, float]:
    size = tuple(float(v) for v in image_size)
    if len(size) != 2 or not all(np.isfinite(v) and v > 0 for v in size):
        raise UsageError(
            f"image size must be two positive numbers (width, height) in pixels, got {image_size}"
        )
    return size[0], size[1]


def _intrinsics(intrinsics: Sequence[float] | None) -> tuple[float, float, float, float] | None:
    if intrinsics is None:
        return None
    k = tuple(float(v) for v in intrinsics)
    if len(k) != 4 or not all(np.isfinite(v) for v in k) or k[0] <= 0 or k[1] <= 0:
        raise UsageError(
            f"intrinsics must be four finite numbers fx fy cx cy in pixels, fx and fy > 0; got {intrinsics}"
        )
    return k[0], k[1], k[2], k[3]


def corners_to_boxes(corners: np.ndarray, image_size: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Pixel corners to normalised centre-size boxes.

    Args:
        corners: (..., 4) ``x1, y1, x2, y2`` in pixels; NaN in all four: missed detection.
        image_size: ``(width, height)`` in pixels.

    Returns:
        ``(boxes, detected)``: (..., 4) ``x, y, w, h`` divided by the image width (x, w)
        or height (y, h), zero where missed; (...) bool.

    Example:
        >>> boxes, det = corners_to_boxes(np.array([[300.0, 200.0, 340.0, 260.0]]), (640, 480))
        >>> boxes.tolist(), det.tolist()
        ([[0.5, 0.4791666666666667, 0.0625, 0.125]], [True])
    """
    width, height = _image_size(image_size)
    c = np.asarray(corners, dtype=np.float64)
    detected = np.asarray(~np.isnan(c).any(axis=-1), dtype=bool)
    boxes = np.empty(c.shape)
    boxes[..., 0] = (c[..., 0] + c[..., 2]) / 2 / width
    boxes[..., 1] = (c[..., 1] + c[..., 3]) / 2 / height
    boxes[..., 2] = (c[..., 2] - c[..., 0]) / width
    boxes[..., 3] = (c[..., 3] - c[..., 1]) / height
    boxes[~detected] = 0.0
    return boxes, detected


def boxes_to_corners(boxes: np.ndarray, detected: np.ndarray, image_size: Sequence[float]) -> np.ndarray:
    """Normalised centre-size boxes to pixel corners, NaN where ``detected`` is False.

    The inverse of :func:`corners_to_boxes` up to rounding.

    Args:
        boxes: (..., 4) ``x, y, w, h`` normalised.
        detected: (...) bool.
        image_size: ``(width, height)`` in pixels.

    Returns:
        (..., 4) ``x1, y1, x2, y2`` in pixels.
    """
    width, height = _image_size(image_size)
    b = np.asarray(boxes, dtype=np.float64)
    c = np.empty(b.shape)
    c[..., 0] = (b[..., 0] - b[..., 2] / 2) * width
    c[..., 1] = (b[..., 1] - b[..., 3] / 2) * height
    c[..., 2] = (b[..., 0] + b[..., 2] / 2) * width
    c[..., 3] = (b[..., 1] + b[..., 3] / 2) * height
    c[~np.asarray(detected, dtype=bool)] = np.nan
    return c


def _where(mask: Any, label: str = "example") -> str:
    """``example 3, 7, ... (12 in all)`` for the first few True entries of ``mask``."""
    hits = np.argwhere(mask)
    shown = ", ".join(" ".join(str(int(i)) for i in h) for h in hits[:SHOWN])
    more = f", ... ({len(hits)} in all)" if len(hits) > SHOWN else ""
    return f"{label} {shown}{more}"


def from_pixels(
    corners: Any,
    camera: Any,
    image_size: Sequence[float],
    depth: Any = None,
    *,
    intrinsics: Sequence[float] | None = None,
    observation_depth: Any = None,
    attrs: dict[str, Any] | None = None,
) -> Examples:
    """Examples from pixel boxes and camera positions in a fixed frame.

    Args:
        corners: (N, n_obs, 4) box corners ``x1, y1, x2, y2`` in pixels, NaN in all four
            where the detector found nothing.
        camera: (N, n_obs, 3) camera positions in metres in any fixed frame whose axes
            are the camera's; made relative to the last observation.
        image_size: ``(width, height)`` in pixels.
        depth: (N,) true depth at the last observation in metres, NaN where unknown;
            None: unknown for all.
        intrinsics: ``(fx, fy, cx, cy)`` in pixels, for the methods that need them.
        observation_depth: (N, n_obs) true depth at each observation, NaN where unknown.
        attrs: further metadata.

    Returns:
        :class:`Examples` with ``attrs`` holding ``image_width``, ``image_height`` and,
        when given, ``fx, fy, cx, cy``.

    Raises:
        DataError: wrong shapes, a box partly NaN, with ``x2 <= x1`` or ``y2 <= y1``,
            non-finite numbers, or a known depth that is not > 0 (every problem named).

    Example:
        >>> import numpy as np
        >>> corners = np.array([[[280.0, 200.0, 360.0, 280.0], [270.0, 190.0, 370.0, 290.0]]])
        >>> camera = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.2]]])
        >>> ex = from_pixels(corners, camera, (640, 480))
        >>> ex.boxes[0, 1].tolist(), ex.camera[0, 0].tolist(), bool(np.isnan(ex.depth[0]))
        ([0.5, 0.5, 0.15625, 0.20833333333333334], [0.0, 0.0, -0.2], True)
    """
    width, height = _image_size(image_size)
    k = _intrinsics(intrinsics)
    c = np.asarray(corners, dtype=np.float64)
    cam = np.asarray(camera, dtype=np.float64)
    problems: list[str] = []
    if c.ndim != 3 or c.shape[2] != 4:
        raise DataError("cannot convert pixel boxes", [f"corners must be (N, n_obs, 4), got {c.shape}"])
    n, n_obs = c.shape[:2]
    if cam.shape != (n, n_obs, 3):
        problems.append(f"camera must be {(n, n_obs, 3)}, got {cam.shape}")
    d = np.full(n, np.nan) if depth is None else np.asarray(depth, dtype=np.float64)
    if d.shape != (n,):
        problems.append(f"depth must be {(n,)}, got {d.shape}")
    od = None if observation_depth is None else np.asarray(observation_depth, dtype=np.float64)
    if od is not None and od.shape != (n, n_obs):
        problems.append(f"observation_depth must be {(n, n_obs)}, got {od.shape}")
    if problems:
        raise DataError("cannot convert pixel boxes", problems)
    if n_obs < 2:
        problems.append(f"every example needs at least 2 observations, got {n_obs}")
    nan = np.isnan(c)
    partly = nan.any(axis=2) & ~nan.all(axis=2)
    if partly.any():
        problems.append(
            f"box partly NaN (a missed detection is NaN in all four): {_where(partly, 'observation')}"
        )
    detected = ~nan.any(axis=2)
    with np.errstate(invalid="ignore"):
        if np.isinf(c).any():
            problems.append(f"box corner not finite: {_where(np.isinf(c).any(axis=2), 'observation')}")
        for lo, hi, axis in ((0, 2, "x"), (1, 3, "y")):
            bad = detected & ~(c[:, :, hi] > c[:, :, lo])
            if bad.any():
                problems.append(f"box with {axis}2 <= {axis}1: {_where(bad, 'observation')}")
        if not np.isfinite(cam).all():
            problems.append(
                f"camera position not finite: {_where(~np.isfinite(cam).all(axis=2), 'observation')}"
            )
        if np.isinf(d).any() or (d <= 0).any():
            problems.append(f"known depth not finite and > 0: {_where(np.isinf(d) | (d <= 0))}")
    if problems:
        raise DataError("cannot convert pixel boxes", problems)
    boxes, detected = corners_to_boxes(c, (width, height))
    meta: dict[str, Any] = {"source": "pixels", "image_width": width, "image_height": height}
    if k is not None:
        meta.update(fx=k[0], fy=k[1], cx=k[2], cy=k[3])
    meta.update(attrs or {})
    return Examples(
        boxes=boxes,
        detected=detected,
        camera=cam - cam[:, -1:, :],
        depth=d.copy(),
        observation_depth=None if od is None else od.copy(),
        attrs=meta,
    )


def select_observations(examples: Examples, count: int) -> Examples:
    """``count`` observations chosen evenly, the first and the last kept.

    Observation ``round((n_obs - 1) * i / (count - 1))`` for ``i = 0 .. count - 1``
    (halves rounded up): distinct because the spacing is at least 1. The last is the
    one whose depth is estimated and the camera stays relative to it.

    Args:
        examples: examples of ``n_obs >= count`` observations.
        count: observations to keep, >= 2.

    Returns:
        The same examples with ``count`` observations (``examples`` itself when
        ``n_obs == count``); per-observation ``extras`` are dropped.

    Raises:
        DataError: fewer than ``count`` observations.

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(2, rng=0)
        >>> select_observations(ex, 4).n_obs
        4
        >>> observation_indices(10, 4).tolist()
        [0, 3, 6, 9]
    """
    if count < 2:
        raise UsageError(f"count must be >= 2, got {count}")
    n_obs = examples.n_obs
    if n_obs < count:
        raise DataError(f"{count} observations are needed, the examples have {n_obs}")
    if n_obs == count:
        return examples
    idx = observation_indices(n_obs, count)
    return Examples(
        boxes=examples.boxes[:, idx],
        detected=examples.detected[:, idx],
        camera=examples.camera[:, idx],
        depth=examples.depth.copy(),
        observation_depth=None if examples.observation_depth is None else examples.observation_depth[:, idx],
        attrs=dict(examples.attrs),
    )


def observation_indices(n_obs: int, count: int) -> np.ndarray:
    """The ``count`` observation indices :func:`select_observations` keeps out of ``n_obs``."""
    return np.floor(np.linspace(0.0, n_obs - 1, count) + 0.5).astype(np.intp)


# --- writing -----------------------------------------------------------------------------------


def format_sequences(
    examples: Examples,
    image_size: Sequence[float] | None = None,
    names: Sequence[str] | None = None,
    *,
    depth: bool = True,
) -> str:
    """The sequences CSV of ``examples`` (the inverse of :func:`read_sequences`).

    Camera positions are written relative to the last observation (a fixed frame);
    numbers with ``repr`` precision. Observations are numbered 0 .. n_obs - 1.

    Args:
        examples: the examples.
        image_size: ``(width, height)``; default: the examples' own attributes.
        names: one name per example; default ``0, 1, ...``.
        depth: write the ``depth`` column (each observation's true depth where known,
            else the last observation's truth on the last row).

    Returns:
        The CSV text.
    """
    if image_size is None:
        if examples.attrs.get("image_width") is None or examples.attrs.get("image_height") is None:
            raise UsageError("the examples carry no image size; give image_size=(width, height)")
        image_size = (examples.attrs["image_width"], examples.attrs["image_height"])
    n, n_obs = len(examples), examples.n_obs
    if names is None:
        names = [str(i) for i in range(n)]
    if len(names) != n:
        raise UsageError(f"{len(names)} names for {n} examples")
    corners = boxes_to_corners(examples.boxes, examples.detected, image_size)
    cols: list[np.ndarray] = [corners[:, :, i] for i in range(4)] + [
        examples.camera[:, :, i] for i in range(3)
    ]
    if depth:
        if examples.observation_depth is not None:
            d = examples.observation_depth.copy()
        else:
            d = np.full((n, n_obs), np.nan)
        d[:, -1] = examples.depth
        cols.append(d)
    header = list(REQUIRED_COLUMNS) + (["depth"] if depth else [])
    buf = io.StringIO()
    buf.write(",".join(header) + "\n")
    text_names = [_csv_cell(str(s)) for s in names]
    values = [[_number(v) for v in col.ravel().tolist()] for col in cols]
    for i in range(n):
        for k in range(n_obs):
            r = i * n_obs + k
            buf.write(f"{text_names[i]},{k},{','.join(v[r] for v in values)}\n")
    return buf.getvalue()


def _number(v: float) -> str:
    return "" if v != v else repr(v)


def _csv_cell(s: str) -> str:
    if any(ch in s for ch in ',"\r\n') or s != s.strip():
        return '"' + s.replace('"', '""') + '"'
    return s


def write_sequences(
    path: str | os.PathLike[str],
    examples: Examples,
    image_size: Sequence[float] | None = None,
    names: Sequence[str] | None = None,
    *,
    depth: bool = True,
) -> None:
    """Write :func:`format_sequences` to ``path`` atomically."""
    from odmd_bench.data.io import atomic_write

    text = format_sequences(examples, image_size, names, depth=depth)
    with atomic_write(path, "w") as fh:
        fh.write(text)


# --- reading -----------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Sequences:
    """The sequences of one file, grouped by their number of observations.

    Attributes:
        names: (N,) the sequence names, in order of first appearance in the file.
        n_obs: (N,) int, observations per sequence.
        groups: one ``(index, examples)`` per distinct ``n_obs`` (ascending):
            ``index`` (k,) the positions in ``names`` of the ``k`` sequences in
            ``examples``.
        source: where they were read from.
        ignored_columns: columns of the file that were not read.
        attrs: metadata shared by every group's examples (``source_file``).
    """

    names: tuple[str, ...]
    n_obs: np.ndarray
    groups: tuple[tuple[np.ndarray, Examples], ...]
    source: str = ""
    ignored_columns: tuple[str, ...] = ()
    attrs: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.names)

    @property
    def depth(self) -> np.ndarray:
        """(N,) the true depth at each sequence's last observation, NaN where unknown."""
        out = np.full(len(self), np.nan)
        for index, ex in self.groups:
            out[index] = ex.depth
        return out

    def examples(self) -> Examples:
        """All sequences as one :class:`Examples` (they must have one length)."""
        if len(self.groups) != 1:
            counts = ", ".join(f"{len(ex)} of {ex.n_obs} observations" for _, ex in self.groups)
            raise UsageError(f"the sequences have different lengths ({counts}); use .groups")
        return self.groups[0][1]


class _Problems:
    """Problems by kind, each with a count and the first few places."""

    def __init__(self) -> None:
        self.shown: dict[str, list[str]] = {}
        self.counts: dict[str, int] = {}

    def add(self, kind: str, where: str | None = None, count: int = 1) -> None:
        self.counts[kind] = self.counts.get(kind, 0) + count
        shown = self.shown.setdefault(kind, [])
        if where is not None and len(shown) < SHOWN:
            shown.append(where)

    def add_lines(self, kind: str, mask: np.ndarray, lines: np.ndarray, cells: Any = None) -> None:
        hit = np.flatnonzero(mask)
        if not hit.size:
            return
        for i in hit[:SHOWN]:
            what = f"line {int(lines[i])}"
            if cells is not None:
                what += f" ({_show(str(cells[i]))})"
            self.add(kind, what, 0)
        self.counts[kind] += int(hit.size)

    def __bool__(self) -> bool:
        return bool(self.counts)

    def lines(self) -> list[str]:
        out = []
        for kind, shown in self.shown.items():
            n = self.counts[kind]
            line = kind
            if shown:
                more = f", ... ({n - len(shown)} more)" if n > len(shown) else ""
                line += f" ({n} {'row' if n == 1 else 'rows'}): " + ", ".join(shown) + more
            out.append(line)
        return out


def _show(value: str, limit: int = 40) -> str:
    return repr(value if len(value) <= limit else value[:limit] + "...")


def _utf8(data: bytes) -> bytes:
    """The file as UTF-8 bytes without a byte-order mark, checked to be text.

    Raises:
        ValueError: the file is binary, or not UTF-8 (or BOM-marked UTF-16) text.
    """
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return data.decode("utf-16").encode("utf-8")
        except UnicodeDecodeError:
            raise ValueError("the file starts with a UTF-16 byte-order mark but is not UTF-16 text") from None
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    nul = data.find(b"\x00")
    if nul >= 0:
        raise ValueError(f"the file is binary, not a CSV text file (a NUL byte at offset {nul})")
    if not data.isascii():
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as e:
            line = data[: e.start].count(b"\n") + 1
            raise ValueError(
                f"the file is not UTF-8 text (byte 0x{data[e.start]:02x} on line {line}); save it as UTF-8 CSV"
            ) from None
    return data


@dataclass
class _Rows:
    """The cells of every row with the right number of fields, as arrays."""

    lines: np.ndarray  # (M,) int, 1-based line of each row
    sequence: np.ndarray  # (M,) object, stripped names
    numbers: np.ndarray  # (M, 8) observation, x1, y1, x2, y2, cam_x, cam_y, cam_z; NaN: empty
    depth: np.ndarray | None  # (M,) NaN: empty


def _header(data: bytes, problems: _Problems) -> tuple[list[str], dict[str, int]] | None:
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
                    problems.add(
                        f"the header {_show(header[0])} seems to use {name} as separator; use commas"
                    )
                    break
        problems.add(
            f"expected the columns {', '.join(REQUIRED_COLUMNS)} (optional: depth; others are ignored); "
            f"the header is {_show(','.join(header), 120)}"
        )
    return None if problems else (header, cols)


def _fast_rows(data: bytes, header: list[str], cols: dict[str, int]) -> _Rows | None:
    """The rows by the pandas C parser, or None when the file needs the careful reader.

    Taken only when the file has no quote and no line end but LF or CRLF, holds exactly
    the header's number of commas on every line, and pandas reads every cell of the
    columns used as a number or an empty cell. Every line has the header's number of
    fields: pandas refuses a line with more, and with the total of commas right no line
    can then have fewer (a blank line has none). So a row's line is its index + 2.
    """
    returns = data.count(b"\r")
    if b'"' in data or (returns and returns != data.count(b"\r\n")):
        return None
    n_lines = data.count(b"\n") + (not data.endswith(b"\n"))
    if n_lines < 2 or data.count(b",") != (len(header) - 1) * n_lines:
        return None
    import pandas as pd

    used = ["sequence", *_NUMERIC] + (["depth"] if "depth" in cols else [])
    dtypes: dict[int, Any] = {i: object for i in range(len(header))}  # ignored columns: any text
    dtypes.update({cols[c]: np.float64 for c in used if c != "sequence"})
    try:
        df = pd.read_csv(
            io.BytesIO(data),
            header=None,
            skiprows=1,
            names=list(range(len(header))),
            dtype=dtypes,
            keep_default_na=False,
            na_values=[""],
            index_col=False,
            encoding="utf-8",
            engine="c",
            low_memory=False,
        )
    except (ValueError, pd.errors.ParserError):  # a cell that is no number, a long line
        return None
    m = len(df)
    if m != n_lines - 1:
        return None
    seq = df[cols["sequence"]].to_numpy(dtype=object)
    codes, uniques = pd.factorize(seq, sort=False, use_na_sentinel=False)
    stripped = np.array(["" if u is None or u != u else str(u).strip() for u in uniques], dtype=object)
    numbers = np.empty((m, len(_NUMERIC)))
    for j, c in enumerate(_NUMERIC):
        numbers[:, j] = df[cols[c]].to_numpy(dtype=np.float64)
    depth = df[cols["depth"]].to_numpy(dtype=np.float64) if "depth" in cols else None
    return _Rows(np.arange(m) + 2, stripped[codes], numbers, depth)


def _careful_rows(text: str, header: list[str], cols: dict[str, int], problems: _Problems) -> _Rows:
    """Every row read with :mod:`csv` and every cell checked, each problem located."""
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    lines: list[int] = []
    names: list[str] = []
    numbers: list[list[float]] = []
    depths: list[float] = []
    width = len(header)
    has_depth = "depth" in cols
    try:
        next(reader)
        for record in reader:
            cells = [c.strip() for c in record]
            if not any(cells):
                continue
            line = reader.line_num
            if len(cells) != width:
                problems.add(
                    f"wrong number of fields (every row must have {width}, like the header)",
                    f"line {line} ({len(cells)})",
                )
                continue
            row = []
            for c in _NUMERIC + (("depth",) if has_depth else ()):
                row.append(_cell(cells[cols[c]], c, line, problems))
            lines.append(line)
            names.append(cells[cols["sequence"]])
            numbers.append(row[: len(_NUMERIC)])
            if has_depth:
                depths.append(row[-1])
    except csv.Error as e:
        problems.add(f"line {max(reader.line_num, 1)}: not valid CSV ({e})")
    arr = np.array(numbers, dtype=np.float64).reshape(-1, len(_NUMERIC))
    return _Rows(
        np.array(lines, dtype=np.int64),
        np.array(names, dtype=object),
        arr,
        np.array(depths, dtype=np.float64) if has_depth else None,
    )


def _cell(s: str, column: str, line: int, problems: _Problems) -> float:
    """A cell's number: NaN for an empty cell, inf for a non-finite one (reported later),
    0 for text that is no number (reported here)."""
    if not s:
        return np.nan
    if _FLOAT.fullmatch(s):
        return float(s)
    if _NONFINITE.fullmatch(s):
        return np.inf
    problems.add(f"{column} is not a number", f"line {line} ({_show(s)})")
    return 0.0


def _check_rows(rows: _Rows, problems: _Problems) -> None:
    """The rules on cell values, vectorised; every breach located by line."""
    lines, num = rows.lines, rows.numbers
    problems.add_lines("sequence is empty", rows.sequence == "", lines)
    for j, c in enumerate(_NUMERIC):
        if c in _BOX:
            continue
        problems.add_lines(f"{c} is empty", np.isnan(num[:, j]), lines)
    for j, c in enumerate(_NUMERIC):
        problems.add_lines(f"{c} is not finite", np.isinf(num[:, j]), lines)
    box = num[:, 1:5]
    empty = np.isnan(box)
    problems.add_lines(
        "box partly empty (a missed detection leaves all four of x1, y1, x2, y2 empty)",
        empty.any(axis=1) & ~empty.all(axis=1),
        lines,
    )
    detected = ~empty.any(axis=1) & np.isfinite(box).all(axis=1)
    with np.errstate(invalid="ignore"):
        problems.add_lines("box with x2 <= x1", detected & ~(box[:, 2] > box[:, 0]), lines)
        problems.add_lines("box with y2 <= y1", detected & ~(box[:, 3] > box[:, 1]), lines)
        if rows.depth is not None:
            d = rows.depth
            problems.add_lines("depth is not finite", np.isinf(d), lines)
            problems.add_lines(
                "depth must be > 0 (a true depth, metres)", np.isfinite(d) & (d <= 0), lines, d
            )


def _group(rows: _Rows, problems: _Problems) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(names, order, starts, counts)``: the sequences in order of first appearance and
    the rows sorted by sequence then observation."""
    import pandas as pd

    codes, uniques = pd.factorize(rows.sequence, sort=False)
    names = np.asarray(uniques, dtype=object)
    obs = rows.numbers[:, 0]
    order = np.lexsort((obs, codes))
    counts = np.bincount(codes, minlength=len(names))
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    sc, so = codes[order], obs[order]
    dup = np.flatnonzero((sc[1:] == sc[:-1]) & (so[1:] == so[:-1]))
    if dup.size:
        for i in dup[:SHOWN]:
            a, b = order[i], order[i + 1]
            problems.add(
                "observation repeated within a sequence",
                f"lines {rows.lines[a]} and {rows.lines[b]} (sequence {_show(str(names[codes[a]]))}, "
                f"observation {obs[a]:g})",
                0,
            )
        problems.counts["observation repeated within a sequence"] += int(dup.size)
    single = np.flatnonzero((counts == 1) & (names != ""))  # an empty name is reported already
    if single.size:
        kind = "sequence with one observation (at least 2 are needed)"
        for s in single[:SHOWN]:
            line = rows.lines[order[starts[s]]]
            problems.add(kind, f"line {line} ({_show(str(names[s]))})", 0)
        problems.counts[kind] += int(single.size)
    return names, order, starts, counts


def read_sequences(
    source: str | os.PathLike[str] | bytes,
    image_size: Sequence[float],
    intrinsics: Sequence[float] | None = None,
) -> Sequences:
    """Read a sequences CSV (module docstring) strictly, naming every problem at once.

    Args:
        source: a path, ``"-"`` for standard input, or the file's bytes; gzip-compressed
            content (``.csv.gz``) is decompressed.
        image_size: ``(width, height)`` of the images the boxes are in, pixels.
        intrinsics: ``(fx, fy, cx, cy)`` in pixels, for the methods that need them.

    Returns:
        :class:`Sequences`, each sequence's observations ordered by ``observation``.

    Raises:
        ValidationError: the file cannot be read as sequences; one line per kind of
            problem with its count and first lines (line 1 is the header).
        UsageError: a bad ``image_size`` or ``intrinsics``.
    """
    size = _image_size(image_size)
    k = _intrinsics(intrinsics)
    if isinstance(source, bytes):
        data, where = source, "<bytes>"
    elif str(source) == "-":
        data, where = sys.stdin.buffer.read(), "<stdin>"
    else:
        where = str(source)
        try:
            data = Path(source).read_bytes()
        except FileNotFoundError:
            raise ValidationError(f"{where} cannot be read", [f"no such file: {where}"]) from None
        except IsADirectoryError:
            raise ValidationError(
                f"{where} cannot be read", [f"{where} is a folder, not a CSV file"]
            ) from None
        except OSError as e:
            raise ValidationError(f"{where} cannot be read", [f"{e.strerror or e}"]) from None
    title = f"{where} cannot be read as sequences"
    if data[:2] == b"\x1f\x8b":  # gzip, as `.csv.gz`
        import gzip
        import zlib

        try:
            data = gzip.decompress(data)
        except (OSError, EOFError, zlib.error) as e:
            raise ValidationError(
                title, [f"the file looks gzip-compressed but cannot be decompressed ({e})"]
            ) from None
    if not data or data.isspace():
        raise ValidationError(
            title, [f"the file is empty; expected a header {','.join(REQUIRED_COLUMNS)}[,depth]"]
        )
    try:
        data = _utf8(data)
    except ValueError as e:
        raise ValidationError(title, [str(e)]) from None
    problems = _Problems()
    parsed = _header(data, problems)
    if parsed is None:
        raise ValidationError(title, problems.lines())
    header, cols = parsed
    rows = _fast_rows(data, header, cols)
    if rows is None:
        rows = _careful_rows(data.decode("utf-8"), header, cols, problems)
    if not len(rows.lines) and not problems:
        raise ValidationError(title, ["the file has a header but no rows; expected one row per observation"])
    _check_rows(rows, problems)
    names, order, starts, counts = _group(rows, problems)
    if problems:
        raise ValidationError(title, problems.lines())

    attrs: dict[str, Any] = {"source_file": where}
    groups = []
    for n_obs in np.unique(counts).tolist():
        index = np.flatnonzero(counts == n_obs)
        take = order[starts[index][:, None] + np.arange(n_obs)]
        num = rows.numbers[take]
        truth = None
        obs_depth = None
        if rows.depth is not None:
            obs_depth = rows.depth[take]
            truth = obs_depth[:, -1]
        ex = from_pixels(
            num[:, :, 1:5],
            num[:, :, 5:8],
            size,
            truth,
            intrinsics=k,
            observation_depth=obs_depth,
            attrs=attrs,
        )
        groups.append((index, ex))
    ignored = tuple(h for h in header if h not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS)
    return Sequences(
        names=tuple(str(s) for s in names.tolist()),
        n_obs=counts.astype(np.int64),
        groups=tuple(groups),
        source=where,
        ignored_columns=ignored,
        attrs=attrs,
    )


# --- methods -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class SequenceDepths:
    """What :func:`predict_sequences` gives.

    Attributes:
        names: (N,) sequence names.
        depth: (N,) the estimated depth at each sequence's last observation, metres.
        truth: (N,) the true depth where the file gives it, else NaN.
        observations: (N,) int, observations the method used.
        detections: (N,) int, how many of those had a detection.
        counts: the method's counted fallbacks, summed over the sequences, and what it
            says of its run (strings).
        method: the method's name.
    """

    names: tuple[str, ...]
    depth: np.ndarray
    truth: np.ndarray
    observations: np.ndarray
    detections: np.ndarray
    counts: dict[str, int | str]
    method: str


def method_observations(method: Any) -> int | None:
    """The number of observations a method is built for (``OBSERVATIONS`` in the module
    that defines its ``predict``), or None where it takes any number."""
    value = getattr(method, "observations", None)
    if value is None:
        module = inspect.getmodule(getattr(method, "predict", method))
        value = getattr(module, "OBSERVATIONS", None)
    return None if value is None else int(value)


def predict_sequences(sequences: Sequences, method: str | Any, **options: Any) -> SequenceDepths:
    """The depth at the last observation of every sequence, by a registered method.

    A method whose module declares ``OBSERVATIONS = k`` (DBox: 10) gets ``k``
    observations chosen evenly with the first and the last kept
    (:func:`select_observations`) from a longer sequence; a shorter one is refused.
    Every other method takes all the observations.

    Args:
        sequences: from :func:`read_sequences`.
        method: a registered name (:func:`odmd_bench.methods.load`) or a loaded method.
        **options: the method's options (``config=``, ``weights=``, ``mode=``).

    Returns:
        :class:`SequenceDepths`.

    Raises:
        UsageError: an unknown method or option; a method that needs the camera
            intrinsics and none were given; sequences too short for the method.
    """
    from odmd_bench import methods

    m = methods.load(method) if isinstance(method, str) else method
    name = str(getattr(m, "name", method))
    wanted = method_observations(m)
    n = len(sequences)
    depth = np.empty(n)
    used = np.empty(n, dtype=np.int64)
    detections = np.empty(n, dtype=np.int64)
    counts: dict[str, int | str] = {}
    if wanted is not None:
        short = sequences.n_obs < wanted
        if short.any():
            first = [sequences.names[i] for i in np.flatnonzero(short)[:SHOWN]]
            raise UsageError(
                f"method {name!r} takes {wanted} observations per sequence; "
                f"{int(short.sum())} of {n} sequences have fewer: "
                + ", ".join(_show(s) for s in first)
                + (", ..." if short.sum() > SHOWN else "")
                + f" (longer sequences give {wanted} chosen evenly, the first and the last kept)"
            )
    for index, ex in sequences.groups:
        if wanted is not None:
            ex = select_observations(ex, wanted)
        try:
            d, c = m.run(ex, **options) if hasattr(m, "run") else m.predict_report(ex, **options)
        except DataError as e:
            if "intrinsics" in e.message and ex.attrs.get("fx") is None:
                raise UsageError(
                    f"method {name!r} needs the camera intrinsics: give them with --intrinsics FX FY CX CY "
                    "(pixels, in the same pixel frame as the boxes), or intrinsics= from Python"
                ) from None
            raise
        depth[index] = d
        used[index] = ex.n_obs
        detections[index] = ex.detected.sum(axis=1)
        for key, value in c.items():
            if isinstance(value, str):  # what the method says of its run (e.g. the weights)
                counts[key] = value
            elif key != "n":
                before = counts.get(key, 0)
                counts[key] = (before if isinstance(before, int) else 0) + int(value)
    return SequenceDepths(
        names=sequences.names,
        depth=depth,
        truth=sequences.depth,
        observations=used,
        detections=detections,
        counts=counts,
        method=name,
    )


def format_depths(result: SequenceDepths) -> str:
    """The output CSV: ``sequence,depth,observations,detections`` and, where any truth
    is given, ``true_depth,percent_error`` (empty where unknown)."""
    has_truth = bool(np.isfinite(result.truth).any())
    header = ["sequence", "depth", "observations", "detections"]
    if has_truth:
        header += ["true_depth", "percent_error"]
    buf = io.StringIO()
    buf.write(",".join(header) + "\n")
    with np.errstate(invalid="ignore", divide="ignore"):
        pct = np.abs(result.truth - result.depth) / result.truth * 100.0
    depth = result.depth.tolist()
    obs, det = result.observations.tolist(), result.detections.tolist()
    truth, err = result.truth.tolist(), pct.tolist()
    for i, name in enumerate(result.names):
        row = f"{_csv_cell(name)},{depth[i]!r},{obs[i]},{det[i]}"
        if has_truth:
            row += f",{_number(truth[i])},{_number(err[i])}"
        buf.write(row + "\n")
    return buf.getvalue()


__all__ = [
    "OPTIONAL_COLUMNS",
    "REQUIRED_COLUMNS",
    "SequenceDepths",
    "Sequences",
    "boxes_to_corners",
    "corners_to_boxes",
    "format_depths",
    "format_sequences",
    "from_pixels",
    "method_observations",
    "observation_indices",
    "predict_sequences",
    "read_sequences",
    "select_observations",
    "write_sequences",
]
