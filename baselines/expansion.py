"""Optical expansion from two observations, as in the paper's supplementary material.

The two observations are the end points of each example: ``i = n`` (the last, whose
depth is estimated) and ``j = 1`` (the first). The paper's equation ``zi`` with the width
and with the height ratio::

    Z_w = (C_Z1 - C_Zn) / (1 - w_n / w_1)
    Z_h = (C_Z1 - C_Zn) / (1 - h_n / h_1)

and the estimate is their mean ``(Z_w + Z_h) / 2``. No camera intrinsics are needed.

Faithful details that the published numbers (ODMD test 0.0 / 5.2 / 80.9 / 124.1) depend
on, reproduced by default:

* Only the two end points are looked at. A missing one of the two takes the box of the
  other (:func:`odmd_bench.fill_missing` with ``use`` = first and last); the other
  observations are not consulted. ``fill="all"`` (opt-in) takes the nearest detected
  observation among all ``n`` instead, which gives 147.7 on the robot test set.
* Where the width result ``Z_w`` is not finite (for instance a single detected end point
  copied to the other, so that ``w_n / w_1 = 1``), both halves become 1 m, so the
  estimate is 1 m, as the original release does. Counted as ``non_finite_w``.

Further fallbacks (each example is counted once, in this order of precedence):

``no_detection``
    Neither end point (with ``fill="all"``: no observation) has a detection. The
    estimate is ``fallback_depth`` (1 m by default: the original release, whose missing
    boxes are all zeros, gets ``0 / 0`` there and so the 1 m rule above).
``non_finite_w``
    As above: the estimate is ``fallback_depth`` (1 m).
``non_finite_h``
    ``Z_w`` is finite but ``Z_h`` is not: the estimate is ``Z_w`` alone. (The original
    release would return a non-finite number here; this never happens on its sets.)
``non_finite``
    ``combine="lsq"`` only: the combined solution is not finite (for instance a single
    detected end point copied to the other): ``fallback_depth``.

Opt-in variant ``combine="lsq"``: with ``a_w = 1 - w_n / w_1`` and ``a_h = 1 - h_n / h_1``,
solve ``a_w Z = a_h Z = C_Z1 - C_Zn`` together in the least-squares sense,
``Z = (C_Z1 - C_Zn) (a_w + a_h) / (a_w^2 + a_h^2)``, instead of averaging the two
ratios' solutions, which explodes when one of ``a_w``, ``a_h`` is near 0. Exact on
noise-free data like the default; on the original sets (val 0.00 / 5.53 / 18.26 /
25.58, All 12.34, against 36.95 for the mean) it gives test 0.00 / 5.23 / 17.69 /
25.84, All 12.19.

The output never holds NaN or infinity.
"""

from __future__ import annotations

import numpy as np
from odmd_bench_baselines import parallax
from odmd_bench_baselines.parallax import Combine, Fill, check_combine, combine_halves, endpoint_boxes

import odmd_bench

#: Depth (metres) where the width solution is not finite, as the original release uses.
DEFAULT_FALLBACK_DEPTH = 1.0

#: The method reads depth from the boxes' growth as the camera moves along its optical axis:
#: ``odmd-bench predict`` gives no depth where it moved too little (``odmd_bench.predict``).
NEEDS_FORWARD_MOTION = True

#: Fallback reasons, in order of precedence.
FALLBACKS: tuple[str, ...] = ("no_detection", "non_finite_w", "non_finite_h", "non_finite")

#: The options ``odmd-bench baseline`` and ``predict`` give it: parallax's (``combine``), declared once.
OPTIONS = parallax.OPTIONS


def predict_report(
    examples: odmd_bench.Examples,
    fill: Fill = "endpoints",
    fallback_depth: float = DEFAULT_FALLBACK_DEPTH,
    combine: Combine = "mean",
) -> tuple[np.ndarray, dict[str, int]]:
    """Two-observation optical-expansion depths and how many examples used each fallback.

    Args:
        examples: ``N`` examples.
        fill: Missing-box rule, ``"endpoints"`` or ``"all"`` (module docstring);
            ``"endpoints"`` reproduces the paper.
        fallback_depth: Depth (metres) where there is no detection or the width
            solution is not finite.
        combine: How the width and height solutions are combined, ``"mean"`` or
            ``"lsq"`` (module docstring); ``"mean"`` reproduces the paper.

    Returns:
        ``(depths, fallbacks)``: ``depths`` (N,) finite depth estimates at the last
        observation, metres; ``fallbacks`` ``{reason: count}`` for every reason in
        :data:`FALLBACKS` (zeros included).

    Raises:
        odmd_bench.UsageError: If ``fill``, ``combine`` or ``fallback_depth`` is invalid.
    """
    fallback_depth = float(fallback_depth)
    if not np.isfinite(fallback_depth):
        raise odmd_bench.UsageError(f"fallback_depth must be finite, got {fallback_depth}")
    check_combine(combine)
    boxes, none = endpoint_boxes(examples, fill)
    first, last = boxes[:, 0], boxes[:, 1]
    move_z = examples.camera[:, 0, 2] - examples.camera[:, -1, 2]  # C_Z1 - C_Zn
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # Z_w = move_z / a_w and Z_h = move_z / a_h (module docstring).
        a_w = 1 - last[:, 2] / first[:, 2]
        a_h = 1 - last[:, 3] / first[:, 3]
    depth, counts = combine_halves((move_z, a_w), (move_z, a_h), none, fallback_depth, combine, ("w", "h"))
    return depth, {**dict.fromkeys(FALLBACKS, 0), "no_detection": int(none.sum()), **counts}


def predict(
    examples: odmd_bench.Examples,
    fill: Fill = "endpoints",
    fallback_depth: float = DEFAULT_FALLBACK_DEPTH,
    combine: Combine = "mean",
) -> np.ndarray:
    """Two-observation optical-expansion depth at the last observation for every example.

    Args:
        examples: ``N`` examples.
        fill: Missing-box rule, ``"endpoints"`` (the paper) or ``"all"``.
        fallback_depth: Depth for the fallbacks of the module docstring (1 m, as the
            original release).
        combine: ``"mean"`` (the paper) or the opt-in least-squares ``"lsq"``.

    Returns:
        (N,) finite depths in metres.

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(4, perturbation="normal", rng=0)
        >>> bool(abs(predict(ex) - ex.depth).max() < 1e-9)
        True
    """
    return predict_report(examples, fill, fallback_depth, combine)[0]
