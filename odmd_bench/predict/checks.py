"""Units and scale checks on a user's data, before any method runs (``docs/own-data.md``).

The rule: **refused** (exit status 2, naming the likely cause and the fix) where the data
contradict the format's units in a way real data cannot, so that every depth would be
wrong and an option or a conversion fixes it; **warned** (a line on standard error, the
depths still written) where the data may be right but probably are not, or where a
method is used outside what it can do.

- Refused: every box coordinate within ``[0, FRACTION_MAX]`` while the image is at
  least ``MIN_IMAGE_PIXELS`` pixels wide and high: the boxes are fractions of the image
  (fix: multiply by W and H, or ``--normalized-boxes``).
- Warned: the camera travel implausible for the depths the boxes imply: the object's
  width at the implied depth (:mod:`odmd_bench.data.scale`), median over the sequences,
  above ``SIZE_RANGE[1]`` (travel in millimetres given as metres, likely) or below
  ``SIZE_RANGE[0]`` (the reverse) for every focal length from ``FOCAL_GUESS[0]`` to
  ``FOCAL_GUESS[1]`` times the image width when the intrinsics are not given.
- Warned: a method outside its validity, as the method itself says
  (:func:`method_warnings`: DBox's absolute-depth configurations beyond the depths
  they were trained on, its z-only configurations on sideways motion).

Elsewhere, by the same rule: the quaternions' convention is refused where another
explains the boxes clearly better (:mod:`odmd_bench.predict.convention`, run by the
reader), quaternions off unit length are refused with their lines
(:mod:`odmd_bench.predict.sequence_rows`), and a method that needs forward motion gets
no depth, with a warning, where the camera moved too little along its optical axis
(:data:`odmd_bench.predict.MIN_FORWARD_SHARE`).
"""

from __future__ import annotations

import inspect
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.data.scale import implied_depth, implied_size

#: Largest box coordinate, in image widths or heights, of boxes taken for fractions.
FRACTION_MAX = 1.5
#: Fractions are recognised only in images at least this many pixels wide and high.
MIN_IMAGE_PIXELS = 20.0
#: The plausible object widths, metres (a millimetre to fifty metres).
SIZE_RANGE = (1e-3, 50.0)
#: Focal lengths assumed without intrinsics, as multiples of the image width (fields of
#: view of 28 to 90 degrees: phones, webcams, dashboard and robot cameras).
FOCAL_GUESS = (0.5, 2.0)


def fraction_boxes_problem(
    corners: np.ndarray, image_size: tuple[float, float], normalized: bool
) -> str | None:
    """The refusal for boxes given as fractions of the image, or None.

    Args:
        corners: (M, 4) ``x1, y1, x2, y2`` as read (NaN: missed).
        image_size: ``(W, H)`` pixels.
        normalized: the boxes were declared fractions (``--normalized-boxes``).
    """
    w, h = image_size
    found = np.isfinite(corners).all(axis=1)
    if not found.any():
        return None
    top = float(np.abs(corners[found]).max())
    if normalized:
        if top > FRACTION_MAX:
            return (
                f"--normalized-boxes was given, but box coordinates reach {top:g}: fractions of the "
                "image lie within 0 and 1 (drop --normalized-boxes for boxes in pixels)"
            )
        return None
    if min(w, h) >= MIN_IMAGE_PIXELS and (corners[found] >= 0).all() and top <= FRACTION_MAX:
        return (
            f"every box coordinate lies within 0 and {top:g} while the image is {w:g} x {h:g} pixels: "
            "the boxes look like fractions of the image, not pixels; multiply x1, x2 by the width and "
            "y1, y2 by the height, or give --normalized-boxes (normalized_boxes=True from Python)"
        )
    return None


def scale_warnings(sets: Iterable[Examples], what: str = "sequences") -> list[str]:
    """A warning when the camera travel is implausible for the depths the boxes imply.

    Args:
        sets: the examples (one file's groups, or one benchmark set).
        what: what the examples are called in the message.
    """
    lo_sizes, hi_sizes, depths = [], [], []
    for ex in sets:
        z = implied_depth(ex)
        if ex.attrs.get("fx") is not None:
            s = implied_size(ex, z)
            lo_sizes.append(s)
            hi_sizes.append(s)
        else:
            width = float(ex.attrs.get("image_width") or np.nan)
            hi_sizes.append(implied_size(ex, z, FOCAL_GUESS[0] * width))
            lo_sizes.append(implied_size(ex, z, FOCAL_GUESS[1] * width))
        depths.append(z)
    if not depths:
        return []
    lo, hi, z = (np.concatenate(a) for a in (lo_sizes, hi_sizes, depths))
    known = np.isfinite(lo) & np.isfinite(hi) & (z > 0)
    if not known.any():
        return []
    small, large = float(np.median(lo[known])), float(np.median(hi[known]))
    depth = float(np.median(z[known]))
    if small > SIZE_RANGE[1]:
        return [
            f"the camera travel is implausible for the boxes: with it the {what} imply a median depth of "
            f"{depth:.4g} m and objects {small:.4g} m wide or more; are cam_x, cam_y, cam_z in metres "
            "(millimetres given as metres would make every depth 1000 times too large)?"
        ]
    if large < SIZE_RANGE[0]:
        return [
            f"the camera travel is implausible for the boxes: with it the {what} imply a median depth of "
            f"{depth:.4g} m and objects {large * 1000:.3g} mm wide or less; are cam_x, cam_y, cam_z in "
            "metres (metres divided by 1000 would make every depth 1000 times too small)?"
        ]
    return []


def method_warnings(method: Any, examples: Examples, options: Mapping[str, Any]) -> list[str]:
    """What a method says of its use on ``examples`` with ``options`` (its validity).

    A method declares ``input_warnings(examples, **options) -> list[str]`` as an
    attribute or in the module of its ``predict``; it gets the options it takes.
    """
    check = getattr(method, "input_warnings", None)
    if check is None:
        module = inspect.getmodule(getattr(method, "predict", method))
        check = getattr(module, "input_warnings", None)
    if check is None:
        return []
    params = inspect.signature(check).parameters
    takes_all = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    given = {k: v for k, v in options.items() if takes_all or k in params}
    return [str(w) for w in check(examples, **given)]


__all__ = [
    "FOCAL_GUESS",
    "FRACTION_MAX",
    "MIN_IMAGE_PIXELS",
    "SIZE_RANGE",
    "fraction_boxes_problem",
    "method_warnings",
    "scale_warnings",
]
