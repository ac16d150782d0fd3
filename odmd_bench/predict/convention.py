"""Which orientation convention the boxes agree with, checked before any method runs.

Orientation data come in several conventions, and a file in the wrong one is read
without any rule breaking: a world-to-camera quaternion (the inverse of the
camera-to-world one the format wants, ``p_fixed = R p_camera + C``), or the components
written ``w, x, y, z`` (Eigen's and many tools' order) where the format wants
``x, y, z, w``. Either turns the camera positions into the wrong axes and carries the
boxes by the wrong rotation, and every method then answers wrongly (robust 19 m for
3.8 m, expansion -51 m).

The boxes tell. A static object seen by a camera of known pose obeys, at every
observation ``k`` (``P`` the object's centre in the last observation's axes, ``a``,
``b`` its width and height times the focal lengths, ``R_k`` the observation's axes in
the last one's, ``c_k`` its position there)::

    P_k = R_k^T (P - c_k)
    u_k = cx + fx P_k,x / P_k,z      v_k = cy + fy P_k,y / P_k,z
    w_k = a / P_k,z                  h_k = b / P_k,z

which is linear in ``(P, a, b)`` once multiplied by ``P_k,z``. :func:`residuals` solves
it by least squares for every sequence and reports the root mean square reprojection
residual of the box centres and sizes in pixels (sizes only without the intrinsics; the
check is made only with them: on noisy scenes the sizes alone refused 2 of 60 right files).
Under the right convention it is the detector's noise (and the few pixels by which a
box's centre is not its object's under a turn); under a wrong one the motion and the
boxes disagree, by tens to hundreds of pixels on the scenes of ``docs/own-data.md``.

:func:`convention_problem` compares the convention given with the three others
(inverse, ``w`` first, both) and refuses where another explains the boxes clearly
better (:data:`RATIO`, :data:`FLOOR_PIXELS`), and well (:data:`GOOD_SHARE`: wrong
intrinsics, under which no convention fits, do not blame the quaternions), in at least
half of the sequences that can tell (:data:`MIN_SHARE`). The thresholds were chosen on the scenes of
:mod:`odmd_bench.predict.scenes`, noise included; ``tests/test_own_data.py``
measures them (no refusal of a right file over many seeds, every wrong one refused).

Hand-written: the fit is a small linear system per sequence, solved batched with numpy;
no library fits a point and a size to bounding boxes under known poses.
"""

from __future__ import annotations

import warnings
from typing import Literal

import numpy as np

from odmd_bench.errors import UsageError
from odmd_bench.predict.orientation import positions_in_last, relative_rotations, rotation_matrices

Orientation = Literal["camera-to-world", "world-to-camera"]
Order = Literal["xyzw", "wxyz"]
ORIENTATIONS: tuple[str, ...] = ("camera-to-world", "world-to-camera")
ORDERS: tuple[str, ...] = ("xyzw", "wxyz")

#: Another convention is "clearly better" for a sequence where the residual under the
#: convention given exceeds this many times the other's (and :data:`FLOOR_PIXELS`).
RATIO = 4.0
#: ... and the other's residual taken as at least this many pixels, so that two
#: noise-free fits (residuals of 1e-10 pixels) are never compared by their ratio.
FLOOR_PIXELS = 1.0
#: Refused where another convention is clearly better in at least this share of the
#: sequences that can tell the conventions apart.
MIN_SHARE = 0.5
#: ... and, to speak for it, explains a sequence's boxes to this share of their size (its
#: residual at most this times the median box width and height): under wrong intrinsics
#: no convention does, and the quaternions are not blamed.
GOOD_SHARE = 0.1


def check_choice(orientation: str, order: str) -> None:
    """Refuse an unknown ``orientation`` or ``order``, naming the choices."""
    if orientation not in ORIENTATIONS:
        raise UsageError(f"unknown orientation {orientation!r}; expected one of {', '.join(ORIENTATIONS)}")
    if order not in ORDERS:
        raise UsageError(f"unknown quaternion order {order!r}; expected one of {', '.join(ORDERS)}")


def as_camera_to_world(q: np.ndarray, orientation: str, order: str) -> np.ndarray:
    """Quaternions (..., 4) of the convention named, as camera-to-world ``x, y, z, w``.

    Args:
        q: (..., 4) as the file gives them.
        orientation: ``"camera-to-world"`` (the format's) or ``"world-to-camera"``
            (its inverse: the conjugate is taken).
        order: ``"xyzw"`` (the format's) or ``"wxyz"`` (the scalar first).
    """
    check_choice(orientation, order)
    out = np.asarray(q, dtype=np.float64)
    if order == "wxyz":
        out = out[..., [1, 2, 3, 0]]
    if orientation == "world-to-camera":
        out = out * np.array([-1.0, -1.0, -1.0, 1.0])
    return out


def residuals(
    corners: np.ndarray,
    positions: np.ndarray,
    q: np.ndarray,
    intrinsics: tuple[float, float, float, float] | None,
) -> np.ndarray:
    """The RMS reprojection residual (pixels) of a static object's fit, per sequence (module docstring).

    Args:
        corners: (N, n_obs, 4) ``x1, y1, x2, y2`` in pixels, NaN where missed.
        positions: (N, n_obs, 3) camera centres in the fixed frame, metres.
        q: (N, n_obs, 4) camera-to-world quaternions ``x, y, z, w`` (unit length).
        intrinsics: ``(fx, fy, cx, cy)``; without them only the sizes are fitted.

    Returns:
        (N,) pixels; NaN where too few detections leave the fit without residual
        (the fit has 5 unknowns: 4 equations per detection with the intrinsics, 2 without).
    """
    r = rotation_matrices(q)
    rel = relative_rotations(r)
    c = positions_in_last(positions, r)
    rt = np.swapaxes(rel, -1, -2)  # R_k^T: last axes -> observation k's
    rc = (rt @ c[..., None])[..., 0]  # R_k^T c_k (matmul: several times einsum's speed here)
    x1, y1, x2, y2 = np.moveaxis(np.asarray(corners, dtype=np.float64), -1, 0)
    seen = np.isfinite(x1) & np.isfinite(y1) & np.isfinite(x2) & np.isfinite(y2)
    w, h = np.where(seen, x2 - x1, 0.0), np.where(seen, y2 - y1, 0.0)
    n, n_obs = seen.shape
    # Rows of the linear system in (P_x, P_y, P_z, a, b): coefficients (N, n_obs, 5) and the
    # right-hand side, each equation's residual in pixels times P_k,z.
    rows: list[tuple[np.ndarray, np.ndarray]] = []
    zero = np.zeros((n, n_obs))
    for size, col in ((w, 3), (h, 4)):  # size P_k,z - a = 0
        coef = np.concatenate([size[..., None] * rt[..., 2, :], zero[..., None].repeat(2, -1)], axis=-1)
        coef[..., col] = -1.0
        rows.append((coef, size * rc[..., 2]))
    if intrinsics is not None:
        fx, fy, cx, cy = intrinsics
        u, v = np.where(seen, (x1 + x2) / 2, 0.0), np.where(seen, (y1 + y2) / 2, 0.0)
        for centre, f, p0, axis in ((u, fx, cx, 0), (v, fy, cy, 1)):  # (u - cx) P_k,z - f P_k,x = 0
            d = (centre - p0)[..., None] * rt[..., 2, :] - f * rt[..., axis, :]
            coef = np.concatenate([d, zero[..., None].repeat(2, -1)], axis=-1)
            rows.append((coef, (centre - p0) * rc[..., 2] - f * rc[..., axis]))
    a = np.concatenate([coef for coef, _ in rows], axis=1) * np.tile(seen, len(rows))[..., None]
    rhs = np.concatenate([b for _, b in rows], axis=1) * np.tile(seen, len(rows))
    with np.errstate(all="ignore"):
        # Columns scaled to unit length, a ridge of 1e-12 for the unobservable directions
        # (the object's sideways position where only sizes are fitted).
        scale = np.sqrt((a * a).sum(axis=1))
        scale = np.where(scale > 0, scale, 1.0)
        an = a / scale[:, None, :]
        ant = np.swapaxes(an, 1, 2)
        gram = ant @ an + 1e-12 * np.eye(5)
        rhs_n = (ant @ rhs[..., None])[..., 0]
        ok = np.isfinite(gram).all(axis=(1, 2)) & np.isfinite(rhs_n).all(axis=1)
        sol = np.zeros((n, 5))
        if ok.any():
            sol[ok] = np.linalg.solve(gram[ok], rhs_n[ok][..., None])[..., 0]
        sol = sol / scale
        p = sol[:, None, :3]
        pk = (rt @ (p - c)[..., None])[..., 0]
        z = pk[..., 2]
        diff = [w - sol[:, None, 3] / z, h - sol[:, None, 4] / z]
        if intrinsics is not None:
            diff += [u - (cx + fx * pk[..., 0] / z), v - (cy + fy * pk[..., 1] / z)]
        sq = sum(np.where(seen, d * d, 0.0) for d in diff)
        equations = len(diff) * seen.sum(axis=1)
        rms = np.sqrt(np.where(seen, sq, 0.0).sum(axis=1) / np.maximum(equations, 1))
    rms = np.where(np.isnan(rms), np.inf, rms)
    return np.where(ok & (equations > 5), rms, np.nan)


#: The alternatives to the convention given, with the words that name them.
_ALTERNATIVES: tuple[tuple[bool, bool], ...] = ((True, False), (False, True), (True, True))


def _other(orientation: str, order: str, invert: bool, swap: bool) -> tuple[str, str]:
    o = ORIENTATIONS[1 - ORIENTATIONS.index(orientation)] if invert else orientation
    k = ORDERS[1 - ORDERS.index(order)] if swap else order
    return o, k


def compare(
    groups: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
    intrinsics: tuple[float, float, float, float] | None,
    orientation: str,
    order: str,
) -> tuple[np.ndarray, dict[tuple[str, str], np.ndarray], np.ndarray]:
    """The residuals under the convention given and under each other, per sequence.

    Args:
        groups: ``(corners, positions, q)`` per group of sequences, ``q`` as the file
            gives it.
        intrinsics: or None.
        orientation: the convention the file is said to use, ``"camera-to-world"`` or
            ``"world-to-camera"``.
        order: its component order, ``"xyzw"`` or ``"wxyz"``.

    Returns:
        ``(given, others, sizes)``: (N,) residuals in the order of the groups
        concatenated, the same per other convention ``(orientation, order)``, and (N,)
        each sequence's median box width and height (pixels; NaN without a detection).
    """

    def run(o: str, k: str) -> np.ndarray:
        return np.concatenate(
            [residuals(cor, pos, as_camera_to_world(q, o, k), intrinsics) for cor, pos, q in groups]
        )

    given = run(orientation, order)
    others = {}
    for invert, swap in _ALTERNATIVES:
        o, k = _other(orientation, order, invert, swap)
        others[(o, k)] = run(o, k)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # (all-NaN: a sequence without a detection)
        sizes = np.concatenate(
            [
                np.nanmedian(np.concatenate([c[..., 2] - c[..., 0], c[..., 3] - c[..., 1]], axis=1), axis=1)
                for c, _, _ in groups
            ]
        )
    return given, others, sizes


def convention_problem(
    given: np.ndarray,
    others: dict[tuple[str, str], np.ndarray],
    sizes: np.ndarray,
    orientation: str,
    order: str,
) -> str | None:
    """The refusal where another convention explains the boxes clearly better, or None.

    A sequence tells the conventions apart where one fits :data:`RATIO` times better than
    another; it speaks for another convention where that one fits :data:`RATIO` times
    better than the one given and explains the boxes, to :data:`GOOD_SHARE` of their size
    (so that intrinsics that are wrong, under which no convention fits, do not blame the
    quaternions). Refused where one other convention is spoken for by at least
    :data:`MIN_SHARE` of the sequences that tell.

    Args:
        given: (N,) residuals under the convention given (:func:`compare`).
        others: the same per other convention.
        sizes: (N,) the sequences' box sizes, pixels.
        orientation: the convention given.
        order: the component order given.
    """
    names = list(others)
    res = np.stack([np.where(np.isnan(others[k]), np.inf, others[k]) for k in names])
    pick = np.argmin(res, axis=0)
    best = res.min(axis=0)
    worst = res.max(axis=0)
    known = np.isfinite(given)
    with np.errstate(invalid="ignore"):
        better = known & (given > RATIO * np.maximum(best, FLOOR_PIXELS))
        tell = better | (known & np.isfinite(worst) & (worst > RATIO * np.maximum(given, FLOOR_PIXELS)))
        speaks = better & (best <= GOOD_SHARE * sizes)
    if not speaks.any():
        return None
    votes = np.bincount(pick[speaks], minlength=len(names))
    top = int(np.argmax(votes))
    if votes[top] < MIN_SHARE * int(tell.sum()):
        return None
    chosen = speaks & (pick == top)
    med_given = float(np.median(given[chosen]))
    med_other = float(np.median(best[chosen]))
    o, k = names[top]
    said = (
        f"the camera orientations disagree with the boxes as given ({orientation}, {', '.join(order)}): "
        f"in {int(votes[top])} of {int(tell.sum())} sequences that can tell, the boxes fit a static object "
        f"with a median residual of {_px(med_given)} read so, and of {_px(med_other)} read as "
    )
    fixes = []
    if o != orientation:
        fixes.append(
            "the quaternions look world-to-camera: give camera-to-world (the inverse), or add "
            "`--orientation world-to-camera`"
            if o == "world-to-camera"
            else "the quaternions look camera-to-world: drop `--orientation world-to-camera`"
        )
    if k != order:
        fixes.append(
            "w first? the components look written w, x, y, z: add `--quaternion-order wxyz`"
            if k == "wxyz"
            else "the components look written x, y, z, w: drop `--quaternion-order wxyz`"
        )
    return (
        said
        + f"{o}, {', '.join(k)}; "
        + "; and ".join(fixes)
        + " (cam_x, cam_y, cam_z are the camera's centre in the fixed frame either way; docs/own-data.md, "
        "checks before any method runs)"
    )


def _px(v: float) -> str:
    return f"{v:.3g} pixels"


__all__ = [
    "FLOOR_PIXELS",
    "GOOD_SHARE",
    "MIN_SHARE",
    "ORDERS",
    "ORIENTATIONS",
    "RATIO",
    "as_camera_to_world",
    "check_choice",
    "compare",
    "convention_problem",
    "residuals",
]
