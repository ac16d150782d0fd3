"""The scale a set's boxes and camera motion imply, before any method runs.

Checks of units and of a method's validity need a depth to compare with: a wrong unit
of the camera travel, say, makes every depth wrong by the same factor, and a network
trained on depths under a metre cannot answer at 30 m. :func:`implied_depth` gives the
depth at the last observation that the boxes and camera positions imply, by linear
least squares on the equations that every box coordinate gives for a static object
(the equations the robust method starts from):

    Z (w_k - w_n) = w_k c_kz                                 (size, also h)
    Z (x_k - x_n) = (x_k - u0) c_kz - a c_kx                 (position, also y)

``c_k`` the camera position relative to the last, ``a = fx / W`` and ``u0 = cx / W``;
the position equations are used only where the intrinsics are known. Exact on
noise-free data; a rough scale (not an estimate to report) on noisy data.
:func:`implied_size` turns it into the object's width in metres.
"""

from __future__ import annotations

import numpy as np

from odmd_bench.data.examples import Examples, fill_missing


def implied_depth(examples: Examples) -> np.ndarray:
    """The depth at the last observation implied by the boxes and camera motion (module docstring).

    Args:
        examples: any set; its intrinsics are used where its ``attrs`` carry them.

    Returns:
        (N,) metres; NaN where nothing implies a depth (no detection, or no camera
        motion that the available equations can see).

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(3, perturbation="normal", rng=0)
        >>> bool(np.allclose(implied_depth(ex), ex.depth))
        True
    """
    n = len(examples)
    if n == 0:
        return np.zeros(0)
    boxes = fill_missing(examples.boxes, examples.detected)
    cam = np.asarray(examples.camera, dtype=np.float64)
    last = boxes[:, -1:, :]
    num = np.zeros(n)
    den = np.zeros(n)
    for c in (2, 3):  # w, h
        d = boxes[:, :, c] - last[:, :, c]
        r = boxes[:, :, c] * cam[:, :, 2]
        num += (d * r).sum(axis=1)
        den += (d * d).sum(axis=1)
    attrs = examples.attrs
    keys = ("fx", "fy", "cx", "cy", "image_width", "image_height")
    if all(attrs.get(k) is not None for k in keys):
        fx, fy, cx, cy, width, height = (float(attrs[k]) for k in keys)
        for c, a, u0 in ((0, fx / width, cx / width), (1, fy / height, cy / height)):
            d = boxes[:, :, c] - last[:, :, c]
            r = (boxes[:, :, c] - u0) * cam[:, :, 2] - a * cam[:, :, c]
            num += (d * r).sum(axis=1)
            den += (d * d).sum(axis=1)
    seen = examples.detected.any(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = num / den
    return np.where(seen & (den > 0) & np.isfinite(z) & (z > 0), z, np.nan)


def implied_size(examples: Examples, depth: np.ndarray, focal: float | None = None) -> np.ndarray:
    """The object's width (metres) at ``depth`` (N,) given its box at the last observation.

    ``focal``: the focal length in pixels; default the set's ``fx``.

    Returns:
        (N,) ``w W Z / fx``; NaN where the last box is missing or ``depth`` is NaN.
    """
    attrs = examples.attrs
    width = float(attrs.get("image_width") or np.nan)
    f = float(focal if focal is not None else attrs.get("fx") or np.nan)
    w = np.where(examples.detected[:, -1], examples.boxes[:, -1, 2], np.nan)
    return np.asarray(w * width * depth / f, dtype=np.float64)


__all__ = ["implied_depth", "implied_size"]
