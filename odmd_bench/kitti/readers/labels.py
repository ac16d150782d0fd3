"""A KITTI tracking label file (``label_02/NNNN.txt``) read strictly: one object per line, 17 fields.

A clean file is read in whole arrays (:func:`_fast_labels`); any other goes line by line
(:func:`_careful_label_rows`), which names every problem, located.
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
from odmd_bench.inputs.records import NUMBER
from odmd_bench.kitti.readers.text import number, read_text, refuse

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

_INT = re.compile(r"[+-]?[0-9]+")


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
    text = read_text(p)
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
        values = [number(c, problems, where, name) for c, name in zip(cells[5:], names, strict=True)]
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
    refuse(p, problems, "KITTI tracking label file")
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
    refuse(p, problems, "KITTI tracking label file")
    if not rows:
        raise ImportRefused(f"{p}: not a KITTI tracking label file", ["no object lines"])
    return rows
