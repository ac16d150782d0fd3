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
- Warned, by the reader: boxes wholly outside the image (:func:`outside_image`), ignored
  columns named like an orientation or a depth (:func:`pose_like`, :func:`depth_like`).

Elsewhere, by the same rule: the quaternions' convention is refused where another
explains the boxes clearly better (:mod:`odmd_bench.predict.convention`, run by the
reader), quaternions off unit length are refused with their lines
(:mod:`odmd_bench.predict.sequence_rows`), and a method that needs forward motion gets
no depth, with a warning, where the camera moved too little along its optical axis
(:data:`MIN_FORWARD_SHARE`); a turning camera's depths that depend on the object's
shape are warned of (:func:`shape_warning`).
"""

from __future__ import annotations

import inspect
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.data.scale import implied_depth, implied_size
from odmd_bench.inputs.problems import SHOWN, show

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


#: A method that reads depth from the boxes' growth (``NEEDS_FORWARD_MOTION`` in its
#: module: Box_LS, expansion) gives no depth for an own sequence whose camera moved along
#: its optical axis by less than this share of the depth (docs/own-data.md, measured on
#: noisy scenes: below it Box_LS's median error is over 70 %, and it is 100 % with no
#: forward motion at all, where ``parallax`` and ``robust`` are within a few percent).
MIN_FORWARD_SHARE = 0.05


def forward_share(examples: Examples, depth: np.ndarray) -> np.ndarray:
    """The camera's travel along the last optical axis as a share of the depth, per example.

    The travel is the extent of the camera's ``z`` over the observations; the depth is
    the one the boxes and the camera motion imply (:func:`odmd_bench.implied_depth`: the
    sizes and, with the intrinsics, the positions of the boxes), else the method's own
    where that is positive. 0 where the camera's ``z`` never changes; NaN where no depth
    is known.

    Args:
        examples: (N examples), as the method was given them.
        depth: (N,) the method's depths.
    """
    travel = np.ptp(examples.camera[:, :, 2], axis=1)
    scale = implied_depth(examples)
    scale = np.where(np.isfinite(scale), scale, np.where(depth > 0, depth, np.nan))
    with np.errstate(divide="ignore", invalid="ignore"):
        share = travel / scale
    return np.where(travel == 0, 0.0, share)


def forward_warning(
    name: str, names: Sequence[str], shares: list[tuple[np.ndarray, np.ndarray]]
) -> str | None:
    """The warning naming the sequences given no depth for too little forward motion, or None.

    Args:
        name: the method's name.
        names: (N,) the names of the sequences read.
        shares: ``(index, share)`` per group: the positions in ``names``, and
            :func:`forward_share` of each.
    """
    if not shares:
        return None
    index = np.concatenate([i for i, _ in shares])
    share = np.concatenate([s for _, s in shares])
    little = np.flatnonzero(share < MIN_FORWARD_SHARE)
    if not little.size:
        return None
    first = ", ".join(
        f"{show(names[int(index[i])])} ({100 * share[i]:.2g} %)" for i in little[:SHOWN].tolist()
    )
    return (
        f"{name}: {little.size} of {len(names)} sequences have too little forward motion for their depth "
        f"(the camera moved along its optical axis by less than {100 * MIN_FORWARD_SHARE:g} % of the depth; "
        f"first: {first}{', ...' if little.size > SHOWN else ''}): {name} reads depth from how the boxes grow "
        "as the camera moves towards the object, and gives no depth for them (the reason column says so); "
        "`parallax` and `robust` read it from sideways motion too (with --intrinsics)"
    )


#: A translation-only method's depth may change by this fraction between boxes carried as
#: a flat object's and as a round one's before ``predict`` warns.
SHAPE_TOLERANCE = 0.05


def shape_warning(
    name: str, names: Sequence[str], turn: np.ndarray, shaped: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
) -> str | None:
    """A warning naming the turned sequences whose depth depends on the object's shape.

    A turn changes an object's box in a way that depends on its shape (flat or round);
    the boxes are carried into the last orientation as a flat object's
    (:mod:`odmd_bench.predict.orientation`), and the methods read depth from how the
    boxes change, which amplifies that difference where the camera moves little compared
    with the depth (Box_LS: by about ``(1 + t) / t`` for a forward travel ``t`` times the
    last depth). Each method is run again on the boxes carried as a round object's
    (``other_carry_boxes``; without the rotation for a method that models the turn).

    Args:
        name: the method's name.
        names: (N,) the names of the sequences read.
        turn: (N,) each one's largest turn, degrees (:attr:`~odmd_bench.predict.sequences.Sequences.turn`).
        shaped: ``(index, depths, other_depths)`` per group, ``other_depths`` from the
            boxes carried the other way.
    """
    index = np.concatenate([i for i, _, _ in shaped]) if shaped else np.zeros(0, dtype=np.int64)
    if not index.size:
        return None
    d = np.concatenate([x for _, x, _ in shaped])
    o = np.concatenate([x for _, _, x in shaped])
    with np.errstate(divide="ignore", invalid="ignore"):
        change = np.abs(d / o - 1)
    bad = np.flatnonzero(np.isfinite(change) & (change > SHAPE_TOLERANCE))
    if not bad.size:
        return None
    order = bad[np.argsort(-change[bad], kind="stable")]
    first = ", ".join(f"{show(names[int(index[i])])} ({100 * change[i]:.0f} %)" for i in order[:SHOWN])
    return (
        f"{name}: the depths of {bad.size} of {len(names)} sequences depend on the object's shape by more "
        f"than {100 * SHAPE_TOLERANCE:.0f} % (first: {first}): the camera turns (by up to "
        f"{float(turn[index[bad]].max()):.3g} degrees), a turn changes a box according to the "
        "object's shape, and the method amplifies that where the camera moves little for the depth; the "
        "depths given are a flat object's facing the last observation, a round object's differ by the "
        "percentages named (docs/own-data.md, a camera that turns)"
    )


def pose_like(ignored: tuple[str, ...]) -> tuple[str, ...]:
    """One warning naming the ignored columns whose names look like an orientation or a pose."""
    found = []
    for name in ignored:
        low = name.lower()
        if low.startswith(("q", "rot")) or any(w in low for w in ("quat", "roll", "pitch", "yaw")):
            found.append(name)
    if not found:
        return ()
    many = len(found) > 1
    return (
        f"column{'s' if many else ''} {', '.join(show(n) for n in found)} look{'' if many else 's'} like a "
        f"camera orientation but {'are' if many else 'is'} not read: the orientation is read from cam_qx, "
        "cam_qy, cam_qz, cam_qw (a unit quaternion, x y z w, rotating camera coordinates into the fixed "
        "frame; --quaternion-order wxyz and --orientation world-to-camera for the other conventions; "
        "docs/own-data.md)",
    )


def depth_like(ignored: tuple[str, ...], has_depth: bool) -> tuple[str, ...]:
    """A warning where no ``depth`` column is read but an ignored one is named much like it."""
    if has_depth:
        return ()
    import difflib

    near = difflib.get_close_matches("depth", [n.lower() for n in ignored], n=1, cutoff=0.6)
    if not near:
        return ()
    name = next(n for n in ignored if n.lower() == near[0])
    return (
        f"column {show(name)} is not read: did you mean `depth` (the true depth in metres, which the "
        "estimates are scored against)? Without a column named depth no error is given",
    )


def outside_image(corners: np.ndarray, lines: np.ndarray, size: tuple[float, float]) -> tuple[str, ...]:
    """A warning when detected boxes lie wholly outside the image: a wrong image size, likely.

    Box_LS notices only a wrong aspect ratio (it uses ratios of box sizes), but every
    method that reads positions or sizes relative to the image does, DBox first among them.
    """
    w, h = size
    x1, y1, x2, y2 = corners.T
    with np.errstate(invalid="ignore"):  # NaN: a missed detection, never outside
        outside = (x2 <= 0) | (x1 >= w) | (y2 <= 0) | (y1 >= h)
    if not outside.any():
        return ()
    n_boxes = int(np.isfinite(corners).all(axis=1).sum())
    first = ", ".join(str(x) for x in lines[outside][:3].tolist())
    return (
        f"{int(outside.sum())} of {n_boxes} boxes lie wholly outside the {w:g} x {h:g} image "
        f"(line{'s' if outside.sum() > 1 else ''} {first}{', ...' if outside.sum() > 3 else ''}): "
        "is the image size that of the images the boxes were drawn in (width, height, pixels)?",
    )


__all__ = [
    "MIN_FORWARD_SHARE",
    "SHAPE_TOLERANCE",
    "FOCAL_GUESS",
    "FRACTION_MAX",
    "MIN_IMAGE_PIXELS",
    "SIZE_RANGE",
    "forward_share",
    "forward_warning",
    "fraction_boxes_problem",
    "depth_like",
    "method_warnings",
    "outside_image",
    "pose_like",
    "scale_warnings",
    "shape_warning",
]
