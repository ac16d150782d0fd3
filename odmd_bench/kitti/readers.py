"""Strict readers of the KITTI tracking files: labels, camera poses and intrinsics.

Three small text formats (docs/kitti.md#formats):

- a KITTI tracking label file (``label_02/NNNN.txt``): one object per line, 17
  space-separated fields ``frame track_id type truncated occluded alpha x1 y1 x2 y2 h w l
  X Y Z rotation_y``;
- a pose file in the KITTI odometry format (``poses/NNNN.txt``, what ORB-SLAM3 and most
  odometry tools write): one frame per line, the 3x4 camera-to-world matrix ``[R | t]``
  row by row;
- the intrinsics: ORB-SLAM3's camera file (``calib/NNNN.yaml``: ``Camera.fx``, ``fy``,
  ``cx``, ``cy``, ``width``, ``height``) or KITTI's own ``calib/NNNN.txt`` (the projection
  matrix ``P2`` of camera 2).

Every reader is strict: each line is checked (field count, decimal numbers only, no
``nan`` or ``inf``, whole numbers where the format has them, known object types, a
rotation that is a rotation) and every problem of a file is reported at once, located by
file and line, as one :class:`~odmd_bench.errors.ImportRefused` (exit status 2).

Written by hand: pandas' and numpy's text readers take ``nan``, ``inf`` and ``1_0`` as
numbers and stop at the first bad line without its reason; these formats are short lines
of a fixed number of fields, so a located check per line is a few lines of Python and
reads the 21 sequences (65,000 label lines) in well under a second.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from odmd_bench.errors import ImportRefused
from odmd_bench.inputs.problems import Problems, show
from odmd_bench.inputs.records import NONFINITE_CELL, NUMBER

#: The largest text file read (the largest label file of KITTI tracking is about 1 MB).
MAX_FILE_BYTES = 64 * 2**20

#: The object types of KITTI tracking labels. Tracking writes ``Person`` for the object
#: benchmark's ``Person_sitting``; both are read.
TYPES: tuple[str, ...] = (
    "Car",
    "Van",
    "Truck",
    "Pedestrian",
    "Person",
    "Person_sitting",
    "Cyclist",
    "Tram",
    "Misc",
    "DontCare",
)

#: How far ``R^T R`` may be from the identity, and ``det R`` from 1, for ``R`` to be a
#: rotation: a pose file writes 9 decimals, so a true rotation is within about 1e-8.
ROTATION_TOLERANCE = 1e-6

_INT = re.compile(r"[+-]?[0-9]+")


def _read_text(path: Path) -> str:
    """The text of ``path`` (ASCII or UTF-8), or :class:`ImportRefused` saying why not."""
    try:
        with path.open("rb") as fh:
            data = fh.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise ImportRefused(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ImportRefused(f"{path}: a folder, not a file") from None
    except OSError as e:
        raise ImportRefused(f"{path}: cannot read ({e.strerror})") from None
    if len(data) > MAX_FILE_BYTES:
        raise ImportRefused(f"{path}: larger than {MAX_FILE_BYTES // 2**20} MiB; not a KITTI file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ImportRefused(f"{path}: not text (byte {e.start} is not UTF-8)") from None


def _number(cell: str, problems: Problems, where: str, what: str) -> float:
    """``cell`` as a finite float; adds a located problem and returns NaN if it is not one."""
    if NUMBER.fullmatch(cell):
        v = float(cell)
        if math.isfinite(v):
            return v
        problems.add(f"{what}: a number too large for a float", f"{where} ({show(cell)})")
    elif NONFINITE_CELL.fullmatch(cell):
        problems.add(f"{what}: not a finite number", f"{where} ({show(cell)})")
    else:
        problems.add(f"{what}: not a number", f"{where} ({show(cell)})")
    return math.nan


def _refuse(path: Path, problems: Problems, what: str) -> None:
    if problems:
        raise ImportRefused(f"{path}: not a {what}", problems.lines())


@dataclass(frozen=True, eq=False)
class Labels:
    """The labelled objects of one sequence, one row per object per frame (``DontCare`` dropped).

    Attributes:
        frame: (M,) int64 frame number.
        track: (M,) int64 track id (>= 0).
        type: (M,) the object type (:data:`TYPES`).
        truncated: (M,) int64, 0 (not) to 2 (heavily).
        occluded: (M,) int64, 0 (fully visible) to 3 (unknown).
        corners: (M, 4) float64 ``x1, y1, x2, y2`` in pixels of ``image_02``.
        size: (M, 3) float64 ``h, w, l`` in metres.
        bottom: (M, 3) float64 ``X, Y, Z``, the bottom centre of the 3-D box in the camera
            frame, metres (the box centre is ``Y - h/2``).
        line: (M,) int64, the line of each row in its file (1-based).
    """

    frame: np.ndarray
    track: np.ndarray
    type: np.ndarray
    truncated: np.ndarray
    occluded: np.ndarray
    corners: np.ndarray
    size: np.ndarray
    bottom: np.ndarray
    line: np.ndarray


def read_labels(path: str | os.PathLike[str]) -> Labels:
    """Read a KITTI tracking label file strictly (module docstring).

    A line is refused when it has not 17 fields, a field is not a decimal number
    (``nan``, ``inf`` included), ``frame``, ``track_id``, ``truncated`` or ``occluded`` is
    not a whole number in its range, the type is unknown, a tracked object's box has
    ``x2 <= x1`` or ``y2 <= y1`` or its size is not positive, a track is labelled twice in
    one frame, or a track changes type.

    Raises:
        ImportRefused: every problem, each with its line.
    """
    p = Path(path)
    text = _read_text(p)
    fast = _fast_labels(text)
    if fast is not None:
        return fast
    rows = _careful_label_rows(p, text)
    numbers = np.array([r[5] for r in rows], dtype=np.float64).reshape(-1, 10)
    return Labels(
        frame=np.array([r[0] for r in rows], dtype=np.int64),
        track=np.array([r[1] for r in rows], dtype=np.int64),
        type=np.array([r[2] for r in rows], dtype=object),
        truncated=np.array([r[3] for r in rows], dtype=np.int64),
        occluded=np.array([r[4] for r in rows], dtype=np.int64),
        corners=numbers[:, 0:4].copy(),
        size=numbers[:, 4:7].copy(),
        bottom=numbers[:, 7:10].copy(),
        line=np.array([r[6] for r in rows], dtype=np.int64),
    )


_LABEL_LINE = re.compile(
    rf"[ \t]*([0-9]+)[ \t]+(-?[0-9]+)[ \t]+({'|'.join(TYPES)})[ \t]+(-?[0-9]+)[ \t]+(-?[0-9]+)"
    + rf"[ \t]+({NUMBER.pattern})" * 12
    + r"[ \t]*"
)


def _fast_labels(text: str) -> Labels | None:
    """The labels of a file with no problem at all, or None (then the careful reader names them)."""
    lines = text.splitlines()
    found = [(n, _LABEL_LINE.fullmatch(line)) for n, line in enumerate(lines, start=1) if line.strip()]
    if not found or any(m is None for _, m in found):
        return None
    groups = np.array([m.groups() for _, m in found if m is not None], dtype=object)
    keep = groups[:, 2] != "DontCare"
    groups = groups[keep]
    line = np.array([n for n, _ in found], dtype=np.int64)[keep]
    ints = groups[:, [0, 1, 3, 4]].astype(np.int64)
    numbers = groups[:, 5:].astype(np.float64)  # alpha, x1 y1 x2 y2, h w l, X Y Z, rotation_y
    frame, track, truncated, occluded = ints.T
    corners, size = numbers[:, 1:5], numbers[:, 5:8]
    pairs = frame * (int(track.max(initial=0)) + 1) + track
    ok = (
        np.isfinite(numbers).all()
        and (track >= 0).all()
        and ((truncated >= 0) & (truncated <= 2)).all()
        and ((occluded >= 0) & (occluded <= 3)).all()
        and (corners[:, 2] > corners[:, 0]).all()
        and (corners[:, 3] > corners[:, 1]).all()
        and (size > 0).all()
        and (frame <= 10**7).all()
        and (track <= 10**7).all()
        and len(np.unique(pairs)) == len(pairs)
    )
    if not ok:
        return None
    types = groups[:, 2]
    order = np.argsort(track, kind="stable")
    t_sorted, k_sorted = track[order], types[order]
    same_track = t_sorted[1:] == t_sorted[:-1]
    if (same_track & (k_sorted[1:] != k_sorted[:-1])).any():
        return None
    return Labels(
        frame=frame.copy(),
        track=track.copy(),
        type=types.astype(object),
        truncated=truncated.copy(),
        occluded=occluded.copy(),
        corners=corners.copy(),
        size=size.copy(),
        bottom=numbers[:, 8:11].copy(),
        line=line,
    )


def _careful_label_rows(p: Path, text: str) -> list[tuple[int, int, str, int, int, list[float], int]]:
    """The label rows, checked line by line; :class:`ImportRefused` naming every problem."""
    problems = Problems()
    rows: list[tuple[int, int, str, int, int, list[float], int]] = []
    for n, raw in enumerate(text.splitlines(), start=1):
        if not raw.strip():
            continue
        where = f"line {n}"
        cells = raw.split()
        if len(cells) != 17:
            problems.add("expected 17 fields, got another count", f"{where} ({len(cells)})", at=n)
            continue
        ints = []
        for i, (name, lo, hi) in enumerate(
            (("frame", 0, 10**7), ("track_id", -1, 10**7)),
        ):
            cell = cells[i]
            if not _INT.fullmatch(cell) or not lo <= int(cell) <= hi:
                problems.add(f"{name}: not a whole number from {lo}", f"{where} ({show(cell)})", at=n)
                ints.append(-2)
            else:
                ints.append(int(cell))
        kind = cells[2]
        if kind not in TYPES:
            problems.add(
                f"unknown type (expected one of {', '.join(TYPES)})", f"{where} ({show(kind)})", at=n
            )
            continue
        if kind == "DontCare":
            continue  # a region to ignore; its numbers are placeholders (-1, -10, -1000)
        if ints[1] == -1:
            problems.add("track_id -1 is only for DontCare", f"{where} ({show(kind)})", at=n)
            continue
        flags = []
        for cell, name, hi in ((cells[3], "truncated", 2), (cells[4], "occluded", 3)):
            if not _INT.fullmatch(cell) or not 0 <= int(cell) <= hi:
                problems.add(f"{name}: not a whole number from 0 to {hi}", f"{where} ({show(cell)})", at=n)
                flags.append(-1)
            else:
                flags.append(int(cell))
        names = ("alpha", "x1", "y1", "x2", "y2", "h", "w", "l", "X", "Y", "Z", "rotation_y")
        values = [_number(c, problems, where, name) for c, name in zip(cells[5:], names, strict=True)]
        if any(math.isnan(v) for v in values) or -2 in ints or -1 in flags:
            continue
        x1, y1, x2, y2, h, w, length = values[1:8]
        if not (x2 > x1 and y2 > y1):
            problems.add("box with x2 <= x1 or y2 <= y1", f"{where} ({x1:g} {y1:g} {x2:g} {y2:g})", at=n)
            continue
        if not (h > 0 and w > 0 and length > 0):
            problems.add("3-D size h, w, l not all > 0", f"{where} ({h:g} {w:g} {length:g})", at=n)
            continue
        rows.append((ints[0], ints[1], kind, flags[0], flags[1], values[1:11], n))
    _refuse(p, problems, "KITTI tracking label file")
    seen: dict[tuple[int, int], int] = {}
    types: dict[int, tuple[str, int]] = {}
    for frame, track, kind, *_, n in rows:
        first = seen.setdefault((frame, track), n)
        if first != n:
            problems.add(
                "a track labelled twice in one frame",
                f"line {n} (track {track}, frame {frame}, first on line {first})",
                at=n,
            )
        known = types.setdefault(track, (kind, n))
        if known[0] != kind:
            problems.add(
                "a track changes type",
                f"line {n} (track {track}: {kind}, {known[0]} on line {known[1]})",
                at=n,
            )
    _refuse(p, problems, "KITTI tracking label file")
    if not rows:
        raise ImportRefused(f"{p}: not a KITTI tracking label file", ["no object lines"])
    return rows


_POSE_LINE = re.compile(rf"[ \t]*{NUMBER.pattern}(?:[ \t]+{NUMBER.pattern}){{11}}[ \t]*")


def rotation_errors(r: np.ndarray) -> np.ndarray:
    """(...,) True where a matrix of ``r`` (..., 3, 3) is not a rotation (:func:`rotation_problem`)."""
    gram = np.einsum("...ki,...kj->...ij", r, r)
    off = np.abs(gram - np.eye(3)).max(axis=(-2, -1))
    det = np.linalg.det(r)
    return ~((off <= ROTATION_TOLERANCE) & (np.abs(det - 1) <= ROTATION_TOLERANCE))


def rotation_problem(r: np.ndarray) -> str | None:
    """Why the 3x3 matrix ``r`` is not a rotation (within :data:`ROTATION_TOLERANCE`), or None."""
    off = float(np.abs(r.T @ r - np.eye(3)).max())
    if off > ROTATION_TOLERANCE:
        return f"R^T R differs from the identity by {off:.3g}"
    det = float(np.linalg.det(r))
    if abs(det - 1) > ROTATION_TOLERANCE:
        return f"det R = {det:.6g}, not 1"
    return None


def read_poses(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a pose file in the KITTI odometry format strictly: (F, 3, 4) camera-to-world ``[R | t]``.

    Line ``i`` (1-based) is frame ``i - 1``. A line is refused when it has not 12 fields,
    a field is not a finite decimal number, or ``R`` is not a rotation (orthonormal
    within :data:`ROTATION_TOLERANCE`, determinant 1: a reflection is refused). Blank
    lines are refused too, as they would shift every later frame.

    Raises:
        ImportRefused: every problem, each with its line.
    """
    p = Path(path)
    text = _read_text(p)
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()  # a trailing newline or two
    if lines and all(_POSE_LINE.fullmatch(line) for line in lines):
        poses = np.array([line.split() for line in lines]).astype(np.float64).reshape(-1, 3, 4)
        if np.isfinite(poses).all() and not rotation_errors(poses[:, :, :3]).any():
            return poses
    problems = Problems()
    out = np.full((len(lines), 3, 4), np.nan)
    for n, raw in enumerate(lines, start=1):
        where = f"line {n}"
        cells = raw.split()
        if len(cells) != 12:
            problems.add("expected 12 numbers (a 3x4 matrix row by row)", f"{where} ({len(cells)})", at=n)
            continue
        values = [_number(c, problems, where, "pose") for c in cells]
        if any(math.isnan(v) for v in values):
            continue
        m = np.array(values).reshape(3, 4)
        why = rotation_problem(m[:, :3])
        if why:
            problems.add("not a rotation", f"{where} ({why})", at=n)
            continue
        out[n - 1] = m
    if not lines:
        problems.add("the file is empty; expected one 3x4 pose per frame")
    _refuse(p, problems, "pose file (KITTI odometry format)")
    return out


@dataclass(frozen=True)
class Camera:
    """A sequence's pinhole camera: ``fx, fy, cx, cy`` in pixels and the image size."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: float
    height: float

    @property
    def k(self) -> tuple[float, float, float, float]:
        """``(fx, fy, cx, cy)``."""
        return (self.fx, self.fy, self.cx, self.cy)


_YAML_KEYS = ("Camera.fx", "Camera.fy", "Camera.cx", "Camera.cy", "Camera.width", "Camera.height")


def read_camera(path: str | os.PathLike[str], image_size: tuple[float, float] | None = None) -> Camera:
    """Read a sequence's intrinsics: ORB-SLAM3's ``.yaml`` camera file or KITTI's ``calib/NNNN.txt``.

    From the ``.yaml`` file, the six keys ``Camera.fx, fy, cx, cy, width, height``
    (each once, positive, finite). From KITTI's ``.txt`` file, ``P2`` (12 numbers:
    ``fx = P2[0]``, ``cx = P2[2]``, ``fy = P2[5]``, ``cy = P2[6]``); it gives no image
    size, so ``image_size`` ``(width, height)`` must be given.

    Raises:
        ImportRefused: a key missing, repeated or not a positive finite number (located).
    """
    p = Path(path)
    text = _read_text(p)
    problems = Problems()
    values: dict[str, float]
    where: dict[str, str]
    if p.suffix == ".txt":
        found: dict[str, tuple[list[str], int]] = {}
        for n, raw in enumerate(text.splitlines(), start=1):
            cells = raw.replace(":", " ", 1).split()
            if cells and cells[0] == "P2":
                if "P2" in found:
                    problems.add("P2 given twice", f"line {n} (first on line {found['P2'][1]})", at=n)
                found["P2"] = (cells[1:], n)
        if "P2" not in found:
            raise ImportRefused(
                f"{p}: not a KITTI calibration file", ["no line P2: (camera 2's projection matrix)"]
            )
        cells, n = found["P2"]
        if len(cells) != 12:
            problems.add("P2: expected 12 numbers", f"line {n} ({len(cells)})", at=n)
            _refuse(p, problems, "KITTI calibration file")
        p2 = [_number(c, problems, f"line {n}", "P2") for c in cells]
        _refuse(p, problems, "KITTI calibration file")
        if image_size is None:
            raise ImportRefused(
                f"{p}: a KITTI calibration file gives no image size; give it (--image-size WIDTH HEIGHT)"
            )
        values = {
            "fx": p2[0],
            "fy": p2[5],
            "cx": p2[2],
            "cy": p2[6],
            "width": image_size[0],
            "height": image_size[1],
        }
        where = {k: f"line {n}" for k in values}
    else:
        values, where = {}, {}
        for n, raw in enumerate(text.splitlines(), start=1):
            line = raw.split("#", 1)[0]
            key, sep, rest = line.partition(":")
            key = key.strip()
            if not sep or key not in _YAML_KEYS:
                continue
            short = key.split(".", 1)[1]
            if short in values:
                problems.add(f"{key} given twice", f"line {n} (first on {where[short]})", at=n)
                continue
            values[short] = _number(rest.strip(), problems, f"line {n}", key)
            where[short] = f"line {n}"
        missing = [k for k in _YAML_KEYS if k.split(".", 1)[1] not in values]
        if missing:
            problems.add(f"missing {', '.join(missing)} (an ORB-SLAM3 camera file has them)")
    for k, v in values.items():
        if not math.isnan(v) and not v > 0 and k not in ("cx", "cy"):
            problems.add(f"{k} must be > 0", f"{where[k]} ({v:g})")
    _refuse(p, problems, "camera file (ORB-SLAM3 .yaml or KITTI calib .txt)")
    return Camera(values["fx"], values["fy"], values["cx"], values["cy"], values["width"], values["height"])


__all__ = [
    "MAX_FILE_BYTES",
    "ROTATION_TOLERANCE",
    "TYPES",
    "Camera",
    "Labels",
    "read_camera",
    "read_labels",
    "read_poses",
    "rotation_problem",
]
