"""A pose file in the KITTI odometry format (``poses/NNNN.txt``) read strictly, and what makes a rotation."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from odmd_bench.inputs.problems import Problems
from odmd_bench.inputs.records import NUMBER
from odmd_bench.kitti.readers.text import number, read_text, refuse

#: How far ``R^T R`` may be from the identity, and ``det R`` from 1, for ``R`` to be a
#: rotation: a pose file writes 9 decimals, so a true rotation is within about 1e-8.
ROTATION_TOLERANCE = 1e-6

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
    text = read_text(p)
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
        values = [number(c, problems, where, "pose") for c in cells]
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
    refuse(p, problems, "pose file (KITTI odometry format)")
    return out
