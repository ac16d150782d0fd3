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
``cam_qx, cam_qy,``     (optional, all four or none) the camera's orientation in the
``cam_qz, cam_qw``      fixed frame, a unit quaternion (:mod:`odmd_bench.predict.orientation`)
======================  ================================================================

Rows may come in any order; other columns are ignored. Boxes and camera positions are
converted as :mod:`odmd_bench.data.pixels` says; a missed detection (all four corners
empty) becomes ``detected = False``.

Reading is strict in the way the predictions reader is: a file with a problem is refused
as a whole (:class:`~odmd_bench.errors.ValidationError`) naming every kind of problem
with its count and first lines. A clean file (no quote, no blank line, the header's
number of fields on every line, numbers as most tools write them) of at least
:data:`~odmd_bench.inputs.table.PANDAS_BYTES` is read by pandas' C parser
(:mod:`odmd_bench.inputs.table`); anything else goes to a row-by-row reader that
locates each problem, with Python's ``float``. Both give each number cell the float
``float`` gives it, so ``repr``-written numbers come back exactly. A UTF-8 byte-order mark, CRLF line ends, UTF-16 with a byte-order mark and
gzip-compressed files are accepted (:mod:`odmd_bench.predict.sequence_rows` reads the rows).
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.data.pixels import (
    boxes_to_corners,
    corners_to_boxes,
    image_size_of,
    intrinsics_of,
)
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.inputs.problems import SHOWN, Problems, show
from odmd_bench.inputs.records import decode
from odmd_bench.inputs.source import MAX_SEQUENCES_BYTES, cap_advice, input_limit, read_source, stdin_bytes
from odmd_bench.inputs.table import PANDAS_BYTES
from odmd_bench.predict.checks import depth_like, fraction_boxes_problem, outside_image, pose_like
from odmd_bench.predict.convention import (
    Order,
    Orientation,
    as_camera_to_world,
    check_choice,
    compare,
    convention_problem,
)
from odmd_bench.predict.orientation import (
    NO_TURN_DEGREES,
    Carry,
    carry_boxes,
    positions_in_last,
    relative_rotations,
    rotation_matrices,
    turn_degrees,
)
from odmd_bench.predict.sequence_rows import (
    OPTIONAL_COLUMNS,
    REQUIRED_COLUMNS,
    careful_rows,
    check_rows,
    fast_rows,
    group,
    header_columns,
)

_TITLE = "{name} cannot be read as sequences"


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
    text_names = [text_cell(str(s)) for s in names]
    values = [[number_cell(v) for v in col.ravel().tolist()] for col in cols]
    for i in range(n):
        for k in range(n_obs):
            r = i * n_obs + k
            buf.write(f"{text_names[i]},{k},{','.join(v[r] for v in values)}\n")
    return buf.getvalue()


def number_cell(v: float) -> str:
    """A number as a CSV cell: ``repr`` precision, empty for NaN."""
    return "" if v != v else repr(v)


def text_cell(s: str) -> str:
    """Text as a CSV cell, quoted where it holds a comma, quote, line end, or spaces at either end."""
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
    from odmd_bench.outputs import atomic_write

    text = format_sequences(examples, image_size, names, depth=depth)
    with atomic_write(path, "w") as fh:
        fh.write(text)


@dataclass(frozen=True, eq=False)
class Sequences:
    """The sequences of one file, grouped by their number of observations.

    Attributes:
        names: (N,) the sequence names, in order of first appearance in the file.
        n_obs: (N,) int, observations per sequence.
        groups: one ``(index, examples)`` per distinct ``n_obs`` (ascending):
            ``index`` (k,) the positions in ``names`` of the ``k`` sequences in
            ``examples``. Where the camera turns, the boxes are carried into the last
            observation's orientation, and ``examples.extras`` holds ``rotation``
            (k, n_obs, 3, 3), each observation's camera axes in the last one's, and
            ``turned_boxes``, the boxes as seen (for a method that models the turn), and
            ``other_carry_boxes``, the boxes carried the other way (``midpoints``, or
            ``plane`` where ``carry`` is ``midpoints``): how much a translation-only
            method's depth depends on the object's shape (``predict`` warns).
        source: where they were read from.
        ignored_columns: columns of the file that were not read.
        attrs: metadata shared by every group's examples (``source_file``).
        warnings: legal but suspicious things (boxes wholly outside the image), one line each.
        turn: (N,) the largest turn of the camera (degrees) between an observation and
            the last, zeros without the orientation columns.
        oriented: whether the file gives the camera's orientation.
    """

    names: tuple[str, ...]
    n_obs: np.ndarray
    groups: tuple[tuple[np.ndarray, Examples], ...]
    source: str = ""
    ignored_columns: tuple[str, ...] = ()
    attrs: dict[str, Any] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    turn: np.ndarray = field(default_factory=lambda: np.zeros(0))
    oriented: bool = False

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


def read_sequences(
    source: str | os.PathLike[str] | bytes,
    image_size: Sequence[float],
    intrinsics: Sequence[float] | None = None,
    *,
    normalized_boxes: bool = False,
    carry: Carry = "plane",
    orientation: Orientation = "camera-to-world",
    quaternion_order: Order = "xyzw",
) -> Sequences:
    """Read a sequences CSV (module docstring) strictly, naming every problem at once.

    Args:
        source: a path, ``"-"`` for standard input, or the file's bytes; gzip-compressed
            content (``.csv.gz``) is decompressed. At most
            :data:`~odmd_bench.inputs.source.MAX_SEQUENCES_BYTES` (256 MiB) are read, before
            and after decompression; ``ODMD_BENCH_MAX_INPUT_MIB`` sets another cap.
        image_size: ``(width, height)`` of the images the boxes are in, pixels.
        intrinsics: ``(fx, fy, cx, cy)`` in pixels, for the methods that need them, and
            to carry the boxes of a turning camera.
        normalized_boxes: the boxes are fractions of the image (0 to 1), multiplied by
            the image width and height here; boxes that look like fractions are refused
            without it (:mod:`odmd_bench.predict.checks`).
        carry: how the boxes of a turning camera are carried into the last
            observation's orientation (:mod:`odmd_bench.predict.orientation`).
        orientation: the quaternions' convention, ``"camera-to-world"`` (the format's)
            or ``"world-to-camera"`` (their inverse).
        quaternion_order: ``"xyzw"`` (the format's) or ``"wxyz"`` (the scalar first).
            A file whose boxes another convention explains clearly better is refused
            (:mod:`odmd_bench.predict.convention`).

    Returns:
        :class:`Sequences`, each sequence's observations ordered by ``observation``;
        with the orientation columns, the boxes are carried into the last observation's
        orientation and the camera positions are in its axes.

    Raises:
        ValidationError: the file cannot be read as sequences (or is over the cap); one
            line per kind of problem with its count and first lines (line 1 is the header);
            or its orientations disagree with its boxes where another convention agrees.
        UsageError: a bad ``image_size``, ``intrinsics``, ``orientation`` or ``quaternion_order``.
    """
    size = image_size_of(image_size)
    k = intrinsics_of(intrinsics)
    check_choice(orientation, quaternion_order)
    limit, advice = input_limit(MAX_SEQUENCES_BYTES), cap_advice("a sequences file")
    if isinstance(source, bytes):
        data, where = read_source(source, limit=limit, title=_TITLE, kind="sequences", advice=advice)
    elif str(source) == "-":
        stream = stdin_bytes()
        data, where = read_source(
            stream, name="<stdin>", limit=limit, title=_TITLE, kind="sequences", advice=advice
        )
    else:
        data, where = read_source(
            source, name=str(source), limit=limit, title=_TITLE, kind="sequences", advice=advice
        )
    title = f"{where} cannot be read as sequences"
    if not data or data.isspace():
        raise ValidationError(
            title, [f"the file is empty; expected a header {','.join(REQUIRED_COLUMNS)}[,depth]"]
        )
    text: str | None = None
    if not data.isascii() or b"\x00" in data:  # plain ASCII is UTF-8 already (no byte-order mark)
        text, problem = decode(data)
        if text is None:
            raise ValidationError(title, [problem or "the file is not text"])
        data = text.encode("utf-8")  # without a byte-order mark, UTF-16 made UTF-8
    problems = Problems()
    parsed = header_columns(data, problems)
    if parsed is None:
        raise ValidationError(title, problems.lines())
    header, cols = parsed
    rows = fast_rows(data, header, cols) if len(data) >= PANDAS_BYTES else None
    if rows is None:
        rows = careful_rows(data.decode("utf-8") if text is None else text, header, cols, problems)
    if not len(rows.lines) and not problems:
        raise ValidationError(title, ["the file has a header but no rows; expected one row per observation"])
    check_rows(rows, problems)
    names, order, starts, counts = group(rows, problems)
    if not problems:
        fraction = fraction_boxes_problem(rows.numbers[:, 1:5], size, normalized_boxes)
        if fraction is not None:
            problems.add(fraction)
    if problems:
        raise ValidationError(title, problems.lines())
    if normalized_boxes:
        rows.numbers[:, [1, 3]] *= size[0]
        rows.numbers[:, [2, 4]] *= size[1]
    takes = [
        order[starts[np.flatnonzero(counts == n)][:, None] + np.arange(n)] for n in np.unique(counts).tolist()
    ]
    unchecked: tuple[str, ...] = ()
    if rows.orientation is not None and k is not None:
        # The convention: the one given, unless the boxes refuse it (before any method runs).
        given, others, sizes = compare(
            [(rows.numbers[t][:, :, 1:5], rows.numbers[t][:, :, 5:8], rows.orientation[t]) for t in takes],
            k,
            orientation,
            quaternion_order,
        )
        wrong = convention_problem(given, others, sizes, orientation, quaternion_order)
        if wrong is not None:
            raise ValidationError(title, [wrong])
    elif rows.orientation is not None and not (np.abs(rows.orientation[:, :3]) < 1e-12).all():
        unchecked = (
            f"the quaternions' convention ({orientation}, {', '.join(quaternion_order)}) is not checked "
            "without --intrinsics (the box sizes alone cannot tell): a world-to-camera or w-first "
            "quaternion would put the camera's travel in the wrong axes and every depth would be wrong "
            "(docs/own-data.md, checks before any method runs)",
        )
    if rows.orientation is not None:
        rows.orientation = as_camera_to_world(rows.orientation, orientation, quaternion_order)

    attrs: dict[str, Any] = {"source_file": where}
    groups = []
    turn = np.zeros(len(names))
    unturned: list[str] = []
    for n_obs, take in zip(np.unique(counts).tolist(), takes, strict=True):
        index = np.flatnonzero(counts == n_obs)
        num = rows.numbers[take]
        corners, camera = num[:, :, 1:5], num[:, :, 5:8]
        extras: dict[str, np.ndarray] = {}
        if rows.orientation is not None:
            r = rotation_matrices(rows.orientation[take])
            rel = relative_rotations(r)
            turn[index] = turn_degrees(rel).max(axis=1)
            camera = positions_in_last(camera, r)
            if (turn[index] > NO_TURN_DEGREES).any():
                if k is None:
                    unturned += [str(names[i]) for i in index[turn[index] > NO_TURN_DEGREES]]
                else:
                    other = carry_boxes(corners, rel, k, "midpoints" if carry != "midpoints" else "plane")
                    extras = {
                        "rotation": rel,
                        "turned_boxes": corners_to_boxes(corners, size)[0],
                        "other_carry_boxes": corners_to_boxes(other, size)[0],
                    }
                    corners = carry_boxes(corners, rel, k, carry)
        truth = None
        obs_depth = None
        if rows.depth is not None:
            obs_depth = rows.depth[take]
            truth = obs_depth[:, -1]
        ex = Examples.from_pixels(
            corners,
            camera,
            size,
            truth,
            intrinsics=k,
            observation_depth=obs_depth,
            attrs=attrs,
        )
        ex.extras.update(extras)
        groups.append((index, ex))
    if unturned:
        raise UsageError(
            f"the camera turns (cam_qx, cam_qy, cam_qz, cam_qw) in {len(unturned)} sequences, by up to "
            f"{turn.max():.3g} degrees (first: {', '.join(show(s) for s in unturned[:SHOWN])}); carrying "
            "their boxes into the last observation's orientation needs the camera's intrinsics: give "
            "--intrinsics FX FY CX CY (intrinsics= from Python)"
        )
    ignored = tuple(h for h in header if h not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS)
    return Sequences(
        names=tuple(str(s) for s in names.tolist()),
        n_obs=counts.astype(np.int64),
        groups=tuple(groups),
        source=where,
        ignored_columns=ignored,
        attrs=attrs,
        warnings=outside_image(rows.numbers[:, 1:5], rows.lines, size)
        + pose_like(ignored)
        + depth_like(ignored, "depth" in header)
        + unchecked,
        turn=turn,
        oriented=rows.orientation is not None,
    )


__all__ = [
    "OPTIONAL_COLUMNS",
    "REQUIRED_COLUMNS",
    "Sequences",
    "format_sequences",
    "number_cell",
    "read_sequences",
    "text_cell",
    "write_sequences",
]
