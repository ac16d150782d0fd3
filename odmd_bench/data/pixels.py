"""Pixel boxes and camera positions as the arrays of :class:`~odmd_bench.data.examples.Examples`: the conversion, both ways.

Detectors give box corners in pixels; the package's convention (docs/format.md#words) is
centre and size divided by the image width and height. The conversion is exact up to
rounding::

    x = (x1 + x2) / 2 / W      w = (x2 - x1) / W      (W, H: image width, height)
    y = (y1 + y2) / 2 / H      h = (y2 - y1) / H
    camera_k = cam_k - cam_last

Missed detections (NaN in all four corners) become ``detected = False`` with a zero box
(as the original release stores them); each method then applies the shared
missing-detection rule. :mod:`odmd_bench.predict.sequences` reads and writes these arrays
as a CSV file.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from odmd_bench.errors import DataError, UsageError
from odmd_bench.inputs.bounds import (
    MAX_ABS_DEPTH,
    MAX_PIXELS,
    MIN_PIXELS,
    MIN_TRUE_DEPTH,
    option_problems,
    outside,
)
from odmd_bench.inputs.problems import SHOWN


def image_size_of(image_size: Sequence[float]) -> tuple[float, float]:
    """``(width, height)`` as floats, checked.

    Raises:
        UsageError: not two finite numbers from :data:`~odmd_bench.inputs.bounds.MIN_PIXELS`
            to :data:`~odmd_bench.inputs.bounds.MAX_PIXELS`.
    """
    size = tuple(float(v) for v in image_size)
    if len(size) != 2 or not all(np.isfinite(v) and v > 0 for v in size):
        raise UsageError(
            f"image size must be two positive numbers (width, height) in pixels, got {image_size}"
        )
    out = option_problems("image size", size, MIN_PIXELS, MAX_PIXELS, "pixels")
    if out:
        raise UsageError("image size (width, height) out of range", out)
    return size[0], size[1]


def intrinsics_of(intrinsics: Sequence[float] | None) -> tuple[float, float, float, float] | None:
    """``(fx, fy, cx, cy)`` as floats, checked; None stays None.

    Raises:
        UsageError: not four finite numbers, or ``fx`` or ``fy`` not > 0, or out of the
            bounds (:mod:`odmd_bench.inputs.bounds`: ``fx``, ``fy`` from ``MIN_PIXELS`` to
            ``MAX_PIXELS``, ``|cx|``, ``|cy|`` at most ``MAX_PIXELS``).
    """
    if intrinsics is None:
        return None
    k = tuple(float(v) for v in intrinsics)
    if len(k) != 4 or not all(np.isfinite(v) for v in k) or k[0] <= 0 or k[1] <= 0:
        raise UsageError(
            f"intrinsics must be four finite numbers fx fy cx cy in pixels, fx and fy > 0; got {intrinsics}"
        )
    out = option_problems("intrinsics fx fy", k[:2], MIN_PIXELS, MAX_PIXELS, "pixels")
    out += option_problems("intrinsics cx cy", k[2:], -MAX_PIXELS, MAX_PIXELS, "pixels")
    if out:
        raise UsageError("intrinsics (fx, fy, cx, cy) out of range", out)
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
    width, height = image_size_of(image_size)
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
    width, height = image_size_of(image_size)
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


def pixel_fields(
    corners: Any,
    camera: Any,
    image_size: Sequence[float],
    depth: Any = None,
    *,
    intrinsics: Sequence[float] | None = None,
    observation_depth: Any = None,
    attrs: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The fields of :class:`Examples` from pixel boxes and camera positions in a fixed frame.

    :meth:`Examples.from_pixels <odmd_bench.data.examples.Examples.from_pixels>` makes the
    examples of them.

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
        ``boxes``, ``detected``, ``camera``, ``depth``, ``observation_depth`` and
        ``attrs`` (holding ``image_width``, ``image_height`` and, when given, ``fx, fy,
        cx, cy``), the keyword arguments of :class:`Examples`.

    Raises:
        DataError: wrong shapes, a box partly NaN, with ``x2 <= x1`` or ``y2 <= y1``,
            non-finite numbers, or a known depth that is not > 0 (every problem named).

    Example:
        >>> import numpy as np
        >>> corners = np.array([[[280.0, 200.0, 360.0, 280.0], [270.0, 190.0, 370.0, 290.0]]])
        >>> camera = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.2]]])
        >>> ex = pixel_fields(corners, camera, (640, 480))
        >>> ex["boxes"][0, 1].tolist(), ex["camera"][0, 0].tolist(), bool(np.isnan(ex["depth"][0]))
        ([0.5, 0.5, 0.15625, 0.20833333333333334], [0.0, 0.0, -0.2], True)
    """
    width, height = image_size_of(image_size)
    k = intrinsics_of(intrinsics)
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
    far = outside(c, -MAX_PIXELS, MAX_PIXELS).any(axis=2)
    if far.any():
        problems.append(f"box corner beyond {MAX_PIXELS:g} pixels: {_where(far, 'observation')}")
    far = outside(cam, -MAX_ABS_DEPTH, MAX_ABS_DEPTH).any(axis=2)
    if far.any():
        problems.append(f"camera position beyond {MAX_ABS_DEPTH:g} m: {_where(far, 'observation')}")
    for name, values in (("known depth", d), ("observation depth", od)):
        if values is None:
            continue
        with np.errstate(invalid="ignore"):
            far = outside(values, MIN_TRUE_DEPTH, MAX_ABS_DEPTH) & (values > 0)  # <= 0: named above
        if far.any():
            problems.append(f"{name} outside {MIN_TRUE_DEPTH:g} to {MAX_ABS_DEPTH:g} m: {_where(far)}")
    if problems:
        raise DataError("cannot convert pixel boxes", problems)
    boxes, detected = corners_to_boxes(c, (width, height))
    meta: dict[str, Any] = {"source": "pixels", "image_width": width, "image_height": height}
    if k is not None:
        meta.update(fx=k[0], fy=k[1], cx=k[2], cy=k[3])
    meta.update(attrs or {})
    return {
        "boxes": boxes,
        "detected": detected,
        "camera": cam - cam[:, -1:, :],
        "depth": d.copy(),
        "observation_depth": None if od is None else od.copy(),
        "attrs": meta,
    }


__all__ = ["boxes_to_corners", "corners_to_boxes", "image_size_of", "intrinsics_of", "pixel_fields"]
