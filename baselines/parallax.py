"""Motion parallax from two observations, as in the paper's supplementary material.

The two observations are the end points of each example: ``i = n`` (the last, whose
depth is estimated) and ``j = 1`` (the first). With box centres and sizes normalised by
the image width (``x``, ``w``) or height (``y``, ``h``) and the intrinsics normalised the
same way (``fx / W``, ``cx / W``, ``fy / H``, ``cy / H``), the lateral and vertical
solutions (supplementary equations ``zimp`` and ``zivmp``) are::

    Z_x = (fx/W) (C_Xn - C_X1) / ((x_1 - cx/W) (w_n / w_1) - (x_n - cx/W))
    Z_y = (fy/H) (C_Yn - C_Y1) / ((y_1 - cy/H) (h_n / h_1) - (y_n - cy/H))

and the estimate is their mean ``(Z_x + Z_y) / 2``, over the axes on which the camera
moved (below). The method needs the camera
intrinsics, which come from the set's attributes (:meth:`odmd_bench.Examples.intrinsics`
raises a :class:`odmd_bench.DataError` naming the set when it has none).

Faithful details that the published numbers (ODMD test 0.0 / 33.9 / 51.6 / 65.6) depend
on, reproduced by default:

* Only the two end points are looked at. A missing one of the two takes the box of the
  other (:func:`odmd_bench.fill_missing` with ``use`` = first and last); the other
  observations are not consulted. ``fill="all"`` (opt-in) takes the nearest detected
  observation among all ``n`` instead, which gives 70.9 on the robot test set.
* Where the lateral result ``Z_x`` is not finite (for instance a single detected end
  point copied to the other, so that the denominator is 0), both halves become 1 m, so
  the estimate is 1 m, as the original release does. Counted as ``non_finite_x``.

Further fallbacks (each example is counted once, in this order of precedence):

``no_detection``
    Neither end point (with ``fill="all"``: no observation) has a detection. The
    estimate is ``fallback_depth`` (1 m by default: the original release, whose missing
    boxes are all zeros, gets ``0 / 0`` there and so the 1 m rule above).
``non_finite_x``
    As above: the estimate is ``fallback_depth`` (1 m).
``non_finite_y``
    ``Z_x`` is finite but ``Z_y`` is not: the estimate is ``Z_x`` alone. (The original
    release would return a non-finite number here; this never happens on its sets.)
``non_finite``
    ``combine="lsq"`` only: the combined solution is not finite (both denominators 0,
    for instance a single detected end point copied to the other): ``fallback_depth``.

**One-axis motion.** An axis counts as moved when the camera's travel along it between
the two end points exceeds ``min_axis_travel`` (default :data:`MIN_AXIS_TRAVEL`, one
millionth) times the camera's whole travel between them. Where only one lateral axis
moved (a robot base or a car moving sideways, never up or down) its solution is the
estimate, with either ``combine``: the other axis has no parallax (numerator 0), and the
mean would halve the depth. Where both moved, nothing changes: the smallest share of
one axis in an ODMD set is 3.7e-6 (``odmd-paper`` val object), so every ODMD example
uses both axes as the paper did. An axis that moved a little but more than the threshold
(odometry drift, say) still enters the mean and can ruin it: ``combine="lsq"``
(``--combine lsq``) weights each axis by its parallax.

One more count is not a fallback but a warning, counted besides them:
``no_lateral_motion``, the examples with a detection whose camera moved in neither x
nor y (by the threshold above) between the two end points. Motion parallax needs lateral motion; without it both
numerators are 0 and the formula gives 0 m (or, where a denominator is 0 as well, the
1 m fallback above), which is kept (the paper's formula, and the original release's
output) and scored as given. z-only data (ODMS, a camera driving straight on) gives it
for every example: use Box_LS or DBox there.

Opt-in variant ``combine="lsq"``: instead of averaging ``Z_x = N_x / D_x`` and
``Z_y = N_y / D_y`` (numerators ``N`` = focal length times camera motion, denominators
``D`` = the scale-corrected change in box position), solve the two equations
``D_x Z = N_x`` and ``D_y Z = N_y`` together in the least-squares sense,
``Z = (D_x N_x + D_y N_y) / (D_x^2 + D_y^2)``. The mean is ruined whenever one axis
has little motion (its ``D`` is near 0 and its ``Z`` explodes); the least-squares
combination weights each axis by its parallax. Exact on noise-free data like the
default; on the original sets (chosen on ``val``: 0.00 / 6.70 / 9.27 / 21.58, All
9.39, against 40.84 for the mean) it gives test 0.00 / 6.93 / 8.72 / 20.69, All 9.08.

The output never holds NaN or infinity.

On the original test sets this gives 0.00 / 33.93 / 51.56 / 65.55 (All 37.76). The paper
prints 65.6 for the robot set: its evaluation appears to have read the ground truth back
from the two-observation array after the release's in-place missing-detection filter had
copied the first observation's depth over the last one's, which happens for the 16
robot examples whose last detection is missing; scored against those depths the same
predictions give 65.56 (``tests/test_baselines.py`` checks both).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

import odmd_bench
from odmd_bench.methods import MethodOption

#: Depth (metres) where the lateral solution is not finite, as the original release uses.
DEFAULT_FALLBACK_DEPTH = 1.0

#: Fallback reasons, in order of precedence.
FALLBACKS: tuple[str, ...] = ("no_detection", "non_finite_x", "non_finite_y", "non_finite")

#: Counted besides the fallbacks: examples without lateral camera motion (depth 0 m).
NO_LATERAL_MOTION = "no_lateral_motion"

Fill = Literal["endpoints", "all"]
FILLS: tuple[str, ...] = ("endpoints", "all")

#: An axis counts as moved when its travel exceeds this share of the camera's whole travel.
MIN_AXIS_TRAVEL = 1e-6

Combine = Literal["mean", "lsq"]
COMBINES: tuple[str, ...] = ("mean", "lsq")

#: The options ``odmd-bench baseline`` and ``predict`` give it (see odmd_bench.methods).
OPTIONS = (
    MethodOption(
        "combine",
        str,
        "mean",
        "How the per-axis solutions are combined: mean (the paper) or lsq (least squares, "
        "weighted by each axis's signal).",
        choices=COMBINES,
    ),
)


def check_combine(combine: str) -> None:
    """Raise :class:`odmd_bench.UsageError` unless ``combine`` is one of :data:`COMBINES`."""
    if combine not in COMBINES:
        raise odmd_bench.UsageError(f"unknown combine {combine!r}; expected one of {', '.join(COMBINES)}")


def endpoint_boxes(examples: odmd_bench.Examples, fill: Fill = "endpoints") -> tuple[np.ndarray, np.ndarray]:
    """Boxes of the first and last observation, missing ones filled.

    Args:
        examples: ``N`` examples.
        fill: Where a missing end-point box comes from: ``"endpoints"``, the other end
            point (the paper's rule), or ``"all"``, the nearest detected observation
            among all ``n``.

    Returns:
        ``(boxes, none)``: ``boxes`` (N, 2, 4) ``x, y, w, h`` of the first and the last
        observation; ``none`` (N,) bool, True where no box was available (the boxes
        there are meaningless).

    Raises:
        odmd_bench.UsageError: If ``fill`` is not one of :data:`FILLS`.
    """
    if fill not in FILLS:
        raise odmd_bench.UsageError(f"unknown fill {fill!r}; expected one of {', '.join(FILLS)}")
    n_obs = examples.n_obs
    ends = np.array([0, n_obs - 1])
    detected = examples.detected
    use = ends if fill == "endpoints" else None
    used = detected[:, ends] if fill == "endpoints" else detected
    gaps = ~detected[:, ends].all(axis=1)
    boxes = examples.boxes[:, ends]  # a copy (fancy indexing)
    if gaps.any():
        boxes[gaps] = odmd_bench.fill_missing(examples.boxes[gaps], detected[gaps], use=use)[:, ends]
    none = np.asarray(~used.any(axis=1), dtype=bool)
    return boxes, none


def predict_report(
    examples: odmd_bench.Examples,
    fill: Fill = "endpoints",
    fallback_depth: float = DEFAULT_FALLBACK_DEPTH,
    combine: Combine = "mean",
    min_axis_travel: float = MIN_AXIS_TRAVEL,
) -> tuple[np.ndarray, dict[str, int]]:
    """Two-observation motion-parallax depths and how many examples used each fallback.

    Args:
        examples: ``N`` examples of a set that carries camera intrinsics.
        fill: Missing-box rule, ``"endpoints"`` or ``"all"`` (module docstring);
            ``"endpoints"`` reproduces the paper.
        fallback_depth: Depth (metres) where there is no detection or the lateral
            solution is not finite.
        combine: How the lateral and vertical solutions are combined, ``"mean"`` or
            ``"lsq"`` (module docstring); ``"mean"`` reproduces the paper.
        min_axis_travel: an axis is used where the camera's travel along it exceeds this
            share of its whole travel (module docstring).

    Returns:
        ``(depths, fallbacks)``: ``depths`` (N,) finite depth estimates at the last
        observation, metres; ``fallbacks`` ``{reason: count}`` for every reason in
        :data:`FALLBACKS` and :data:`NO_LATERAL_MOTION` (zeros included).

    Raises:
        odmd_bench.DataError: If the set carries no camera intrinsics.
        odmd_bench.UsageError: If ``fill``, ``combine`` or ``fallback_depth`` is invalid.
    """
    fallback_depth = float(fallback_depth)
    if not np.isfinite(fallback_depth):
        raise odmd_bench.UsageError(f"fallback_depth must be finite, got {fallback_depth}")
    check_combine(combine)
    min_axis_travel = float(min_axis_travel)
    if not (np.isfinite(min_axis_travel) and 0 <= min_axis_travel < 1):
        raise odmd_bench.UsageError(f"min_axis_travel must be in [0, 1), got {min_axis_travel}")
    fx, fy, cx, cy, width, height = examples.intrinsics()
    fx, cx, fy, cy = fx / width, cx / width, fy / height, cy / height
    boxes, none = endpoint_boxes(examples, fill)
    first, last = boxes[:, 0], boxes[:, 1]
    move = examples.camera[:, -1] - examples.camera[:, 0]  # C_n - C_1
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # Z_x = num_x / den_x and Z_y = num_y / den_y (module docstring).
        num_x, num_y = fx * move[:, 0], fy * move[:, 1]
        den_x = (first[:, 0] - cx) * (last[:, 2] / first[:, 2]) - (last[:, 0] - cx)
        den_y = (first[:, 1] - cy) * (last[:, 3] / first[:, 3]) - (last[:, 1] - cy)
    limit = min_axis_travel * np.sqrt((move * move).sum(axis=1))
    moved_x, moved_y = np.abs(move[:, 0]) > limit, np.abs(move[:, 1]) > limit
    one_axis = moved_x ^ moved_y
    depth, counts = combine_halves(
        (num_x, den_x), (num_y, den_y), none | one_axis, fallback_depth, combine, ("x", "y")
    )
    # One lateral axis moved: its solution alone (the other has no parallax to average in).
    for axis, alone, num, den in (
        ("x", moved_x & ~moved_y, num_x, den_x),
        ("y", moved_y & ~moved_x, num_y, den_y),
    ):
        alone = alone & ~none
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            z = num / den
        bad = alone & ~np.isfinite(z)
        depth = np.where(alone, np.where(bad, fallback_depth, z), depth)
        key = f"non_finite_{axis}" if combine == "mean" else "non_finite"
        counts[key] += int(bad.sum())
    flat = ~moved_x & ~moved_y & ~none  # nothing for the formula to work with
    report = {**dict.fromkeys(FALLBACKS, 0), "no_detection": int(none.sum()), **counts}
    return depth, {**report, NO_LATERAL_MOTION: int(flat.sum())}


#: ``input_warnings`` speaks where one lateral axis moved less than this share of the other.
WEAK_AXIS = 0.1


def input_warnings(examples: odmd_bench.Examples, combine: Combine = "mean") -> list[str]:
    """What ``odmd-bench predict`` and ``baseline`` say before running (``odmd_bench.predict.checks``).

    With ``combine="mean"``, the examples whose camera moved along one lateral axis by
    more than the threshold but less than :data:`WEAK_AXIS` of the other: that axis's
    solution, a small motion over a small parallax, is dominated by noise and the mean
    with it (``--combine lsq`` weights it by its parallax).
    """
    if combine != "mean" or len(examples) == 0:
        return []
    move = np.abs(examples.camera[:, -1, :2] - examples.camera[:, 0, :2])
    limit = MIN_AXIS_TRAVEL * np.sqrt((move * move).sum(axis=1))
    small, large = move.min(axis=1), move.max(axis=1)
    weak = int(((small > limit) & (small < WEAK_AXIS * large)).sum())
    if not weak:
        return []
    return [
        f"parallax: in {weak} of {len(examples)} examples the camera moved along one lateral axis less than "
        f"a tenth of the other; there the mean of the two axes' solutions (the paper's) takes half of one "
        "from little motion, which noise ruins: --combine lsq weights each axis by its parallax"
    ]


def combine_halves(
    first: tuple[np.ndarray, np.ndarray],
    second: tuple[np.ndarray, np.ndarray],
    none: np.ndarray,
    fallback_depth: float,
    combine: Combine,
    names: tuple[str, str],
) -> tuple[np.ndarray, dict[str, int]]:
    """Combine two single-cue solutions ``Z = num / den`` (shared with expansion).

    ``"mean"`` (the paper) averages them; where the second is not finite the first is
    used alone, and where the first is not finite the depth is ``fallback_depth`` (the
    original release's rule). ``"lsq"`` solves ``den Z = num`` for both rows by least
    squares. Examples flagged in ``none`` get ``fallback_depth``.

    Returns the depths and the counts ``non_finite_<name>`` (mean) or ``non_finite`` (lsq).
    """
    (num_a, den_a), (num_b, den_b) = first, second
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if combine == "lsq":
            depth = (den_a * num_a + den_b * num_b) / (den_a * den_a + den_b * den_b)
            bad = ~np.isfinite(depth) & ~none
            # + 0.0: a zero numerator over a negative denominator is -0.0, written "-0.0"
            return np.where(none | bad, fallback_depth, depth) + 0.0, {"non_finite": int(bad.sum())}
        z_a, z_b = num_a / den_a, num_b / den_b
        depth = (z_a + z_b) / 2
    bad_a = ~np.isfinite(z_a)
    bad_b = ~np.isfinite(z_b)
    depth = np.where(bad_b, z_a, depth)
    counts = {
        f"non_finite_{names[0]}": int((bad_a & ~none).sum()),
        f"non_finite_{names[1]}": int((bad_b & ~bad_a & ~none).sum()),
    }
    return np.where(none | bad_a, fallback_depth, depth) + 0.0, counts  # + 0.0: no -0.0 (above)


def predict(
    examples: odmd_bench.Examples,
    fill: Fill = "endpoints",
    fallback_depth: float = DEFAULT_FALLBACK_DEPTH,
    combine: Combine = "mean",
    min_axis_travel: float = MIN_AXIS_TRAVEL,
) -> np.ndarray:
    """Two-observation motion-parallax depth at the last observation for every example.

    Args:
        examples: ``N`` examples of a set that carries camera intrinsics.
        fill: Missing-box rule, ``"endpoints"`` (the paper) or ``"all"``.
        fallback_depth: Depth for the fallbacks of the module docstring (1 m, as the
            original release).
        combine: ``"mean"`` (the paper) or the opt-in least-squares ``"lsq"``.
        min_axis_travel: the share of the camera's travel an axis must exceed to be used.

    Returns:
        (N,) finite depths in metres.

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(4, perturbation="normal", rng=0)
        >>> bool(abs(predict(ex) - ex.depth).max() < 1e-9)
        True
    """
    return predict_report(examples, fill, fallback_depth, combine, min_axis_travel)[0]
