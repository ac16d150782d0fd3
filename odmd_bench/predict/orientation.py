"""A camera that turns: quaternions, and boxes carried into the last observation's orientation.

The sequences format's optional columns ``cam_qx, cam_qy, cam_qz, cam_qw`` give the
camera's orientation in the fixed frame as a unit quaternion (Hamilton convention, the
order x, y, z, w of the TUM trajectory format) that rotates camera coordinates (x right,
y down, z forward) into the fixed frame: ``p_fixed = R p_camera + C``.

Every method of the package models a camera that translates without turning. A turning
camera is brought to that model exactly for the camera positions and, for the boxes,
through the rotation's homography ``H_k = K R_k K^-1``, ``R_k = R_last^T R(q_k)``, which
takes the pixel of a ray seen at observation ``k`` to the pixel of the same ray in a
camera at the same place with the last observation's orientation:

- positions: ``R_last^T (C_k - C_last)``, in the last camera's axes;
- boxes (``carry``, measured against the turn in ``docs/own-data.md``):

  ``"plane"`` (the default)
      the box ``B`` in the last orientation whose four corners, carried back by
      ``H_k^-1``, have the seen box as their bounding box: the box of a flat object
      facing the last observation (parallel to its image plane), found by Newton's
      method from the carried midpoints. Exact for such objects, as the methods are
      exact for them without a turn: they are the model of ODMD and of every method
      here, a box of the object's size times ``f`` over its depth. Where no such box
      exists (a thin box seen under a roll, thinner than any upright box turned so
      would be), the midpoints.
  ``"midpoints"``
      the midpoints of the four edges carried by ``H_k``; the box spans them. Close to
      exact for round objects (an ellipsoid's outline touches its box near the edge
      midpoints), off by about the turn's ``sec - 1`` on flat ones.
  ``"centre"``
      the box centre is carried by ``H_k``, and the width and height are divided by
      ``lambda = (R_k K^-1 u)_z`` (``u`` the centre), the ratio of the object's depth
      along the turned axis to its depth along the last one. Exact only for a
      "billboard" that turns with the camera (its box the object's size times ``f``
      over its depth along the turned optical axis), which no fixed object is: a turn
      on the spot warps any object's image by ``H_k``, whose local scale is not
      isotropic (``sec^2`` across the turn's axis, ``sec`` along it, where the
      billboard's box scales by ``sec`` both ways).
  ``"corners"``
      the bounding box of the four carried corners: inflated by the turn.

The depth estimated is then along the optical axis of the last observation.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from odmd_bench.errors import UsageError

Carry = Literal["plane", "centre", "midpoints", "corners"]
CARRIES: tuple[str, ...] = ("plane", "midpoints", "centre", "corners")

#: Turns smaller than this (degrees) leave the boxes as they are.
NO_TURN_DEGREES = 1e-6


def rotation_matrices(q: np.ndarray) -> np.ndarray:
    """Rotation matrices of quaternions ``x, y, z, w`` (normalised first).

    Args:
        q: (..., 4) quaternions, Hamilton convention, scalar last.

    Returns:
        (..., 3, 3) ``R`` with ``p_fixed = R p_camera``.

    Example:
        >>> r = rotation_matrices(np.array([0.0, np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)]))
        >>> np.round(r @ [0.0, 0.0, 1.0], 12).tolist()  # 90 degrees about y: forward becomes x
        [1.0, 0.0, 0.0]
    """
    q = np.asarray(q, dtype=np.float64)
    q = q / np.abs(q).max(axis=-1, keepdims=True)  # (first: no overflow in the squares)
    q = q / np.sqrt((q * q).sum(axis=-1, keepdims=True))
    x, y, z, w = np.moveaxis(q, -1, 0)
    r = np.empty(q.shape[:-1] + (3, 3))
    r[..., 0, 0] = 1 - 2 * (y * y + z * z)
    r[..., 0, 1] = 2 * (x * y - z * w)
    r[..., 0, 2] = 2 * (x * z + y * w)
    r[..., 1, 0] = 2 * (x * y + z * w)
    r[..., 1, 1] = 1 - 2 * (x * x + z * z)
    r[..., 1, 2] = 2 * (y * z - x * w)
    r[..., 2, 0] = 2 * (x * z - y * w)
    r[..., 2, 1] = 2 * (y * z + x * w)
    r[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def quaternions(r: np.ndarray) -> np.ndarray:
    """Unit quaternions ``x, y, z, w`` (``w >= 0``) of rotation matrices (..., 3, 3)."""
    r = np.asarray(r, dtype=np.float64)
    w = np.sqrt(np.maximum(0.0, 1 + r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2])) / 2
    x = np.sqrt(np.maximum(0.0, 1 + r[..., 0, 0] - r[..., 1, 1] - r[..., 2, 2])) / 2
    y = np.sqrt(np.maximum(0.0, 1 - r[..., 0, 0] + r[..., 1, 1] - r[..., 2, 2])) / 2
    z = np.sqrt(np.maximum(0.0, 1 - r[..., 0, 0] - r[..., 1, 1] + r[..., 2, 2])) / 2
    x = np.copysign(x, r[..., 2, 1] - r[..., 1, 2])
    y = np.copysign(y, r[..., 0, 2] - r[..., 2, 0])
    z = np.copysign(z, r[..., 1, 0] - r[..., 0, 1])
    return np.stack([x, y, z, w], axis=-1)


def relative_rotations(r: np.ndarray) -> np.ndarray:
    """``R_last^T R_k``: each observation's camera axes in the last observation's, (N, n_obs, 3, 3)."""
    return np.swapaxes(r[:, -1:], -1, -2) @ r


def turn_degrees(rel: np.ndarray) -> np.ndarray:
    """The angle of each relative rotation (..., 3, 3), degrees."""
    cos = (np.trace(rel, axis1=-2, axis2=-1) - 1) / 2
    skew = np.stack(
        [rel[..., 2, 1] - rel[..., 1, 2], rel[..., 0, 2] - rel[..., 2, 0], rel[..., 1, 0] - rel[..., 0, 1]],
        axis=-1,
    )
    sin = np.sqrt((skew * skew).sum(axis=-1)) / 2  # precise for small turns, unlike arccos
    return np.degrees(np.arctan2(sin, cos))


def positions_in_last(camera: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Camera positions (N, n_obs, 3) in a fixed frame as ``R_last^T (C_k - C_last)``."""
    rel = camera - camera[:, -1:]
    return np.einsum("nji,nkj->nki", r[:, -1], rel)


def carry_boxes(
    corners: np.ndarray,
    rel: np.ndarray,
    intrinsics: Sequence[float],
    carry: Carry = "plane",
) -> np.ndarray:
    """Boxes carried into the last observation's orientation (module docstring).

    Args:
        corners: (N, n_obs, 4) ``x1, y1, x2, y2`` in pixels; NaN: missed.
        rel: (N, n_obs, 3, 3) :func:`relative_rotations`.
        intrinsics: ``(fx, fy, cx, cy)`` in pixels.
        carry: ``"plane"``, ``"midpoints"``, ``"centre"`` or ``"corners"``.

    Returns:
        (N, n_obs, 4) carried corners, NaN where missed.

    Raises:
        UsageError: an unknown ``carry``.
    """
    if carry not in CARRIES:
        raise UsageError(f"unknown carry {carry!r}; expected one of {', '.join(CARRIES)}")
    fx, fy, cx, cy = (float(v) for v in intrinsics)
    c = np.asarray(corners, dtype=np.float64)
    x1, y1, x2, y2 = np.moveaxis(c, -1, 0)

    def warp(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ray = np.stack([(u - cx) / fx, (v - cy) / fy, np.ones_like(u)], axis=-1)
        p = np.einsum("...ij,...j->...i", rel, ray)
        lam = p[..., 2]
        return cx + fx * p[..., 0] / lam, cy + fy * p[..., 1] / lam, lam

    xc, yc = (x1 + x2) / 2, (y1 + y2) / 2
    if carry == "plane":
        return _plane_carry(c, rel, (fx, fy, cx, cy))
    if carry == "centre":
        u, v, lam = warp(xc, yc)
        hw, hh = (x2 - x1) / 2 / lam, (y2 - y1) / 2 / lam
        return np.stack([u - hw, v - hh, u + hw, v + hh], axis=-1)
    if carry == "midpoints":
        left, right = warp(x1, yc)[0], warp(x2, yc)[0]
        top, bottom = warp(xc, y1)[1], warp(xc, y2)[1]
        return np.stack([left, top, right, bottom], axis=-1)
    us, vs = [], []
    for u0, v0 in ((x1, y1), (x2, y1), (x1, y2), (x2, y2)):
        u, v, _ = warp(u0, v0)
        us.append(u)
        vs.append(v)
    su, sv = np.stack(us), np.stack(vs)
    return np.stack([su.min(axis=0), sv.min(axis=0), su.max(axis=0), sv.max(axis=0)], axis=-1)


#: At most this many Newton steps of the plane carry (on the scenes of ``docs/own-data.md``
#: 3 or 4 reach rounding; turns of 45 degrees need 5).
PLANE_ITERATIONS = 8


def _warp(
    rel: np.ndarray, u: np.ndarray, v: np.ndarray, k: tuple[float, float, float, float]
) -> tuple[np.ndarray, np.ndarray]:
    fx, fy, cx, cy = k
    x, y = (u - cx) / fx, (v - cy) / fy
    z = rel[..., 2, 0] * x + rel[..., 2, 1] * y + rel[..., 2, 2]
    px = rel[..., 0, 0] * x + rel[..., 0, 1] * y + rel[..., 0, 2]
    py = rel[..., 1, 0] * x + rel[..., 1, 1] * y + rel[..., 1, 2]
    return cx + fx * px / z, cy + fy * py / z


def _bounds(rel: np.ndarray, box: np.ndarray, k: tuple[float, float, float, float]) -> np.ndarray:
    """The bounding box (..., 4) of the four corners of ``box`` warped by ``rel``."""
    x1, y1, x2, y2 = np.moveaxis(box, -1, 0)
    u, v = _warp(rel, np.stack([x1, x2, x1, x2]), np.stack([y1, y1, y2, y2]), k)
    return np.stack([u.min(axis=0), v.min(axis=0), u.max(axis=0), v.max(axis=0)], axis=-1)


def _plane_carry(c: np.ndarray, rel: np.ndarray, k: tuple[float, float, float, float]) -> np.ndarray:
    """The box in the last orientation whose four corners, warped back, have ``c`` as bounding box.

    Newton's method on the four edges (the derivatives by central differences), from the
    edge midpoints carried. Where no such box exists (a thin box seen under a roll,
    thinner than any box of the last orientation turned so would be) or the steps do not
    settle, the edge midpoints carried are returned.
    """
    back = np.swapaxes(rel, -1, -2)
    start = carry_boxes(c, rel, k, "midpoints")
    box = start.copy()
    scale = np.abs(c[..., 2:] - c[..., :2]).sum(axis=-1, keepdims=True) + 1
    tol = 1e-10 * (np.abs(c) + scale)
    h = 1e-4 * scale
    eye = np.eye(4)
    with np.errstate(all="ignore"):
        residual = _bounds(back, box, k) - c
        for _ in range(PLANE_ITERATIONS):
            if not (np.abs(residual) > tol).any():  # NaN (missed) compares False
                break
            jac = np.stack(
                [(_bounds(back, box + h * e, k) - _bounds(back, box - h * e, k)) / (2 * h) for e in eye],
                axis=-1,
            )
            live = np.isfinite(jac).all(axis=(-2, -1)) & (
                np.abs(np.linalg.det(np.where(np.isfinite(jac), jac, 0))) > 1e-12
            )
            delta = np.zeros_like(box)
            delta[live] = np.linalg.solve(jac[live], residual[live][..., None])[..., 0]
            box = box - delta
            residual = _bounds(back, box, k) - c
        ok = (
            (np.abs(residual) <= tol).all(axis=-1) & (box[..., 2] > box[..., 0]) & (box[..., 3] > box[..., 1])
        )
    return np.where(ok[..., None], box, start)


__all__ = [
    "CARRIES",
    "NO_TURN_DEGREES",
    "carry_boxes",
    "positions_in_last",
    "quaternions",
    "relative_rotations",
    "rotation_matrices",
    "turn_degrees",
]
