"""The numeric bounds, shared: every number that enters (cells, options, weights) or leaves.

One set of limits, far beyond any real scene or camera, and small enough that nothing
computed from numbers within them (squares summed for a standard deviation, a ratio of
box sizes, a network's activations) overflows float64. Where a number enters, a value
outside its bound is refused naming it (the cell's line, the option, the weights file);
where a number leaves (a method's depths, the statistics of a table), one outside is
refused naming what made it, so that no command prints a depth of 1e200 m, ``inf`` or a
300-digit cell.

====================  ============  ===============================================
bound                 value         applies to
====================  ============  ===============================================
``MAX_ABS_DEPTH``     1e12 m        depths in a predictions file or from a method;
                                    camera positions and true depths in a
                                    sequences file (any length in metres)
``MIN_TRUE_DEPTH``    1e-6 m        a true depth (the percent error divides by it)
``MAX_PIXELS``        1e6 px        image width and height, box corners, the
                                    intrinsics fx, fy, cx, cy
``MIN_PIXELS``        1 px          image width and height, fx and fy
``MAX_ABS_WEIGHT``    1e6           every value of a network's weights
====================  ============  ===============================================
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

#: Estimates and lengths beyond this magnitude (metres) are refused: no scene is that
#: deep, and the squares summed for the standard deviation of their errors could overflow.
MAX_ABS_DEPTH = 1e12
#: The smallest true depth (metres): a percent error divides by it.
MIN_TRUE_DEPTH = 1e-6
#: The largest image side, box corner or intrinsic, in pixels (a gigapixel image is 4e4 wide).
MAX_PIXELS = 1e6
#: The smallest image side and focal length, in pixels (boxes are divided by the sides).
MIN_PIXELS = 1.0
#: The largest magnitude of a network weight (the shipped DBox weights stay below 10).
MAX_ABS_WEIGHT = 1e6


def outside(values: np.ndarray, low: float, high: float) -> np.ndarray:
    """Where finite ``values`` lie outside ``[low, high]`` (NaN and infinities: False; checked apart)."""
    v = np.asarray(values, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return np.isfinite(v) & ((v < low) | (v > high))


def option_problems(name: str, values: Sequence[float], low: float, high: float, unit: str) -> list[str]:
    """Why an option's numbers are not finite numbers within ``[low, high]`` (empty: they are).

    Examples:
        >>> option_problems("--image-size", [640, 1e-300], MIN_PIXELS, MAX_PIXELS, "px")
        ['--image-size: 1e-300 is outside 1 to 1e+06 px']
        >>> option_problems("--image-size", [640, 480], MIN_PIXELS, MAX_PIXELS, "px")
        []
    """
    problems = []
    for v in values:
        if not math.isfinite(v):
            problems.append(f"{name}: {v:g} is not a finite number")
        elif not low <= v <= high:
            problems.append(f"{name}: {v:g} is outside {low:g} to {high:g} {unit}")
    return problems


def depth_problems(depths: np.ndarray) -> np.ndarray:
    """Where estimated depths are NaN, infinite or beyond :data:`MAX_ABS_DEPTH` (a bool mask)."""
    d = np.asarray(depths, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return ~(np.abs(d) <= MAX_ABS_DEPTH)


__all__ = [
    "MAX_ABS_DEPTH",
    "MAX_ABS_WEIGHT",
    "MAX_PIXELS",
    "MIN_PIXELS",
    "MIN_TRUE_DEPTH",
    "depth_problems",
    "option_problems",
    "outside",
]
