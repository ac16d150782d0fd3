"""The guard's steps around DBox, in numpy only: wrong starts, their repair, blend, cap.

Every function works on all examples at once (no loop over examples), so the steps
cost little beside the network (``benchmarks/bench_dbox_guard.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from odmd_bench import Examples, fill_missing

#: The longest wrong start looked for: observations 0 to 4 (one to five boxes).
MAX_RUN = 5


def flag_wrong_starts(boxes: np.ndarray, detected: np.ndarray, tau: float | None) -> np.ndarray:
    """Observations that open a sequence with boxes of something else.

    With ``w`` the widths of the filled boxes (:func:`odmd_bench.fill_missing`), the
    transitions ``k -> k+1`` for ``k < MAX_RUN`` where ``w[k+1] < tau * w[k]`` are drops
    that forward motion cannot make; the observations ``0 ... j`` are flagged, ``j``
    the last such ``k``.

    Args:
        boxes: (N, n_obs, 4) ``x, y, w, h``.
        detected: (N, n_obs) bool.
        tau: the drop ratio; ``None`` flags nothing.

    Returns:
        (N, n_obs) bool, True at the flagged observations.

    Example:
        >>> import numpy as np
        >>> w = np.array([[0.1, 0.1, 0.04, 0.05, 0.06]])
        >>> b = np.zeros((1, 5, 4)); b[:, :, 2] = w; b[:, :, 3] = w
        >>> flag_wrong_starts(b, np.ones((1, 5), bool), 0.5)[0].tolist()
        [True, True, False, False, False]
    """
    n, n_obs = detected.shape
    flagged = np.zeros((n, n_obs), dtype=bool)
    if tau is None or n_obs < 2 or n == 0:
        return flagged
    w = fill_missing(boxes, detected)[:, :, 2]
    k = min(MAX_RUN, n_obs - 1)
    drop = w[:, 1 : k + 1] < tau * w[:, :k]  # NaN compares False: never flagged
    last = k - 1 - np.argmax(drop[:, ::-1], axis=1)
    flagged[:] = np.arange(n_obs)[None, :] <= last[:, None]
    flagged &= np.asarray(drop.any(axis=1))[:, None]
    return flagged


def _extrapolate(
    size: np.ndarray, cz: np.ndarray, keep: np.ndarray, flagged: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Sizes at the flagged observations from the line ``1/size = a + b cz`` over ``keep``.

    Returns:
        (values (N, n_obs), ok (N,)): ``ok`` where at least two observations were kept,
        the line describes an approach (``b < 0``) and gives positive sizes at every
        flagged observation.
    """
    m = keep & (size > 0) & np.isfinite(size) & np.isfinite(cz)
    with np.errstate(divide="ignore", invalid="ignore"):
        y = np.where(m, 1.0 / np.where(m, size, 1.0), 0.0)
    x = np.where(m, cz, 0.0)
    cnt = m.sum(axis=1).astype(np.float64)
    sx, sy = x.sum(axis=1), y.sum(axis=1)
    sxx, sxy = (x * x).sum(axis=1), (x * y).sum(axis=1)
    den = cnt * sxx - sx * sx
    with np.errstate(divide="ignore", invalid="ignore"):
        b = (cnt * sxy - sx * sy) / den
        a = (sy - b * sx) / cnt
        inv = a[:, None] + b[:, None] * cz
        values = 1.0 / inv
    positive = np.where(flagged, inv > 0, True).all(axis=1)
    ok = (cnt >= 2) & (den > 0) & (b < 0) & positive & np.isfinite(values).all(axis=1, where=flagged)
    return values, ok


def repair(examples: Examples, flagged: np.ndarray) -> Examples:
    """``examples`` with the flagged boxes replaced by the pinhole extrapolation of the rest.

    Over the kept observations (detected, not flagged) the least-squares lines
    ``1/w = a + b c_z`` and ``1/h = a' + b' c_z`` are fitted; where both describe an
    approach (``b, b' < 0``) and give positive sizes at the flagged observations, those
    get the extrapolated width and height, the centre of the nearest kept box, and count
    as detected. Elsewhere the flagged boxes are marked missing (the shared
    nearest-box rule fills them). Examples with nothing flagged are unchanged.

    Returns:
        New :class:`~odmd_bench.Examples` (truth and attributes kept).
    """
    if not flagged.any():
        return examples
    keep = examples.detected & ~flagged
    filled = fill_missing(examples.boxes, keep)
    cz = examples.camera[:, :, 2]
    w, w_ok = _extrapolate(filled[:, :, 2], cz, keep, flagged)
    h, h_ok = _extrapolate(filled[:, :, 3], cz, keep, flagged)
    ok = (w_ok & h_ok)[:, None] & flagged
    boxes = np.array(examples.boxes, dtype=np.float64, copy=True)
    boxes[flagged] = filled[flagged]
    boxes[:, :, 2] = np.where(ok, w, boxes[:, :, 2])
    boxes[:, :, 3] = np.where(ok, h, boxes[:, :, 3])
    detected = keep | ok
    return dataclasses.replace(examples, boxes=boxes, detected=detected)


def blend(dbox_depth: np.ndarray, ls_depth: np.ndarray, alpha: float) -> np.ndarray:
    """``(1 - alpha) z_D + alpha clip(z_LS, z_D / 2, 2 z_D)``.

    Box_LS is kept within a factor of two of DBox, so that its failures (a fallback 0, a
    negative or a huge least-squares answer) move the depth by at most ``alpha``.
    """
    if alpha == 0:
        return np.asarray(dbox_depth, dtype=np.float64)
    lo = np.minimum(dbox_depth / 2, 2 * dbox_depth)
    hi = np.maximum(dbox_depth / 2, 2 * dbox_depth)
    return (1 - alpha) * dbox_depth + alpha * np.minimum(np.maximum(ls_depth, lo), hi)


def travel(examples: Examples) -> np.ndarray:
    """``L = |c_1 - c_n|``, the camera travel of each example (metres)."""
    return np.linalg.norm(np.asarray(examples.camera[:, 0], dtype=np.float64), axis=1)


def cap(depth: np.ndarray, travel_m: np.ndarray, c: float | None) -> np.ndarray:
    """``min(depth, c L)``; ``None`` leaves the depths as they are."""
    if c is None:
        return np.asarray(depth, dtype=np.float64)
    return np.minimum(depth, c * travel_m)
