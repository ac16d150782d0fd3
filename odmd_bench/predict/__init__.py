"""A registered method run on a user's own sequences (:mod:`odmd_bench.predict.sequences`).

:func:`predict_sequences` gives each sequence's depth at its last observation, choosing
observations evenly for a method built for a fixed number of them
(:func:`select_observations`); :func:`format_depths` writes the result as the CSV that
``odmd-bench predict`` writes, with the percent error where the truth is known.
"""

from __future__ import annotations

import inspect
import io
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DataError, DepthRangeError, UsageError
from odmd_bench.evaluation.metrics import percent_error
from odmd_bench.inputs.bounds import MAX_ABS_DEPTH, depth_problems
from odmd_bench.inputs.problems import SHOWN, show
from odmd_bench.predict.checks import method_warnings, scale_warnings
from odmd_bench.predict.sequences import Sequences, number_cell, text_cell


def select_observations(examples: Examples, count: int) -> Examples:
    """``count`` observations chosen evenly, the first and the last kept.

    Observation ``round((n_obs - 1) * i / (count - 1))`` for ``i = 0 .. count - 1``
    (halves rounded up): distinct because the spacing is at least 1. The last is the
    one whose depth is estimated and the camera stays relative to it.

    Args:
        examples: examples of ``n_obs >= count`` observations.
        count: observations to keep, >= 2.

    Returns:
        The same examples with ``count`` observations (``examples`` itself when
        ``n_obs == count``); ``extras`` with an observation axis are indexed, the
        others dropped.

    Raises:
        DataError: fewer than ``count`` observations.

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(2, rng=0)
        >>> select_observations(ex, 4).n_obs
        4
        >>> observation_indices(10, 4).tolist()
        [0, 3, 6, 9]
    """
    if count < 2:
        raise UsageError(f"count must be >= 2, got {count}")
    n_obs = examples.n_obs
    if n_obs < count:
        raise DataError(f"{count} observations are needed, the examples have {n_obs}")
    if n_obs == count:
        return examples
    idx = observation_indices(n_obs, count)
    return Examples(
        boxes=examples.boxes[:, idx],
        detected=examples.detected[:, idx],
        camera=examples.camera[:, idx],
        depth=examples.depth.copy(),
        observation_depth=None if examples.observation_depth is None else examples.observation_depth[:, idx],
        extras={k: v[:, idx] for k, v in examples.extras.items() if v.ndim >= 2 and v.shape[1] == n_obs},
        attrs=dict(examples.attrs),
    )


def observation_indices(n_obs: int, count: int) -> np.ndarray:
    """The ``count`` observation indices :func:`select_observations` keeps out of ``n_obs``."""
    return np.floor(np.linspace(0.0, n_obs - 1, count) + 0.5).astype(np.intp)


@dataclass(frozen=True)
class SequenceDepths:
    """What :func:`predict_sequences` gives.

    Attributes:
        names: (N,) sequence names.
        depth: (N,) the estimated depth at each sequence's last observation, metres.
        truth: (N,) the true depth where the file gives it, else NaN.
        observations: (N,) int, observations the method was given (all, or the count
            it declares; a method may look at fewer, e.g. expansion at the two ends).
        detections: (N,) int, how many of those had a detection.
        counts: the method's counted fallbacks, summed over the sequences, and what it
            says of its run (strings).
        method: the method's name.
        warnings: what the checks of :mod:`odmd_bench.predict.checks` found (the scale
            of the data, the method's validity on them), one line each.
        intervals: ``{"depth_lo", "depth_hi", "depth_std"}`` (N,) error bars, with
            ``calibration`` given (:mod:`odmd_bench.predict.intervals`); else empty.
        level: their nominal coverage, or None.
    """

    names: tuple[str, ...]
    depth: np.ndarray
    truth: np.ndarray
    observations: np.ndarray
    detections: np.ndarray
    counts: dict[str, int | str]
    method: str
    warnings: tuple[str, ...] = ()
    intervals: dict[str, np.ndarray] = field(default_factory=dict)
    level: float | None = None


def method_observations(method: Any) -> int | None:
    """The number of observations a method is built for, or None where it takes any number.

    Read from the method's ``observations``, else from ``OBSERVATIONS`` in the module that
    defines its ``predict``.
    """
    value = getattr(method, "observations", None)
    if value is None:
        module = inspect.getmodule(getattr(method, "predict", method))
        value = getattr(module, "OBSERVATIONS", None)
    return None if value is None else int(value)


def predict_sequences(
    sequences: Sequences, method: str | Any, calibration: Any = None, **options: Any
) -> SequenceDepths:
    """The depth at the last observation of every sequence, by a registered method.

    A method whose module declares ``OBSERVATIONS = k`` (DBox: 10) gets ``k``
    observations chosen evenly with the first and the last kept
    (:func:`select_observations`) from a longer sequence; a shorter one is refused.
    Every other method takes all the observations.

    Args:
        sequences: from :func:`read_sequences`.
        method: a registered name (:func:`odmd_bench.methods.load`) or a loaded method.
        calibration: an :class:`odmd_bench.predict.intervals.IntervalCalibration` of this method
            (its pooled factor): error bars for every sequence; None: none.
        **options: the method's options (``config=``, ``weights=``, ``mode=``).

    Returns:
        :class:`SequenceDepths`.

    Raises:
        UsageError: an unknown method or option; a method that needs the camera
            intrinsics and none were given; sequences too short for the method.
        DepthRangeError: depths not finite or beyond the shared bound, naming the sequences.
    """
    from odmd_bench import methods  # (imported on use: the package's import stays light)

    m = methods.load(method) if isinstance(method, str) else method
    name = str(getattr(m, "name", method))
    wanted = method_observations(m)
    n = len(sequences)
    depth = np.empty(n)
    used = np.empty(n, dtype=np.int64)
    detections = np.empty(n, dtype=np.int64)
    counts: dict[str, int | str] = {}
    bars = {c: np.empty(n) for c in ("depth_lo", "depth_hi", "depth_std")} if calibration is not None else {}
    if wanted is not None:
        short = sequences.n_obs < wanted
        if short.any():
            first = [sequences.names[i] for i in np.flatnonzero(short)[:SHOWN]]
            raise UsageError(
                f"method {name!r} takes {wanted} observations per sequence; "
                f"{int(short.sum())} of {n} sequences have fewer: "
                + ", ".join(show(s) for s in first)
                + (", ..." if short.sum() > SHOWN else "")
                + f" (longer sequences give {wanted} chosen evenly, the first and the last kept)"
            )
    warnings = scale_warnings(ex for _, ex in sequences.groups)
    shaped: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    for index, ex in sequences.groups:
        if wanted is not None:
            ex = select_observations(ex, wanted)
        for line in method_warnings(m, ex.without_truth(), options):
            if line not in warnings:
                warnings.append(line)
        run_on, run_options = ex, options
        rotation = ex.extras.get("rotation")
        if rotation is not None and _accepts(m, "rotation"):
            # The method models the turn itself: the boxes as seen, and the rotations.
            run_on = Examples(
                boxes=ex.extras["turned_boxes"],
                detected=ex.detected,
                camera=ex.camera,
                depth=ex.depth,
                attrs=dict(ex.attrs),
            )
            run_options = {**options, "rotation": rotation}
        try:
            d, c = (
                m.run(run_on, **run_options)
                if hasattr(m, "run")
                else m.predict_report(run_on.without_truth(), **run_options)
            )
        except DepthRangeError as e:
            names = [sequences.names[int(index[i])] for i in e.where]
            raise DepthRangeError(
                e.message.replace("examples", "sequences"),
                [
                    "sequences "
                    + ", ".join(show(x) for x in names[:SHOWN])
                    + (", ..." if len(names) > SHOWN else ""),
                    *e.problems[1:],
                ],
                where=[int(index[i]) for i in e.where],
            ) from None
        except DataError as e:
            if "intrinsics" in e.message and ex.attrs.get("fx") is None:
                raise UsageError(
                    f"method {name!r} needs the camera intrinsics: give them with --intrinsics FX FY CX CY "
                    "(pixels, in the same pixel frame as the boxes), or intrinsics= from Python"
                ) from None
            raise
        far = depth_problems(d)
        if far.any():  # a method object without ``run`` (``Method.run`` checks its own)
            bad = [sequences.names[int(i)] for i in index[far][:SHOWN]]
            raise DepthRangeError(
                f"method {name!r} gives depths that are not finite or beyond {MAX_ABS_DEPTH:.0e} m for "
                f"{int(far.sum())} of {len(index)} sequences",
                ["sequences " + ", ".join(show(x) for x in bad) + (", ..." if far.sum() > SHOWN else "")],
                where=index[far].tolist(),
            )
        other = ex.extras.get("other_carry_boxes")
        if other is not None:  # (a method that models the turn gets them without the rotation)
            shaped.append((index, d, _other_depths(m, ex, other, options)))
        depth[index] = d
        if calibration is not None:
            from odmd_bench.predict.intervals import POOLED, method_spread

            spread = method_spread(m, run_on, run_options) if hasattr(m, "spread") else None
            for column, values in calibration.intervals(d, spread, key=POOLED).items():
                bars[column][index] = values
        used[index] = ex.n_obs
        detections[index] = ex.detected.sum(axis=1)
        for key, value in c.items():
            if isinstance(value, str):  # what the method says of its run (e.g. the weights)
                counts[key] = value
            elif key != "n":
                before = counts.get(key, 0)
                counts[key] = (before if isinstance(before, int) else 0) + int(value)
    said = shape_warning(name, sequences, shaped)
    if said:
        warnings.append(said)
    return SequenceDepths(
        names=sequences.names,
        depth=depth,
        truth=sequences.depth,
        observations=used,
        detections=detections,
        counts=counts,
        method=name,
        warnings=tuple(warnings),
        intervals=bars,
        level=None if calibration is None else float(calibration.level),
    )


#: A translation-only method's depth may change by this fraction between boxes carried as
#: a flat object's and as a round one's before ``predict`` warns.
SHAPE_TOLERANCE = 0.05


def _other_depths(m: Any, ex: Examples, boxes: np.ndarray, options: dict[str, Any]) -> np.ndarray:
    """The method's depths from the boxes carried the other way (NaN where it fell back)."""
    other = Examples(boxes=boxes, detected=ex.detected, camera=ex.camera, attrs=dict(ex.attrs))
    try:
        d, _ = m.run(other, **options) if hasattr(m, "run") else m.predict_report(other, **options)
    except (DepthRangeError, DataError):
        return np.full(len(ex), np.nan)
    return np.asarray(d, dtype=np.float64)


def shape_warning(
    name: str, sequences: Sequences, shaped: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
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
        sequences: the sequences read.
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
    first = ", ".join(
        f"{show(sequences.names[int(index[i])])} ({100 * change[i]:.0f} %)" for i in order[:SHOWN]
    )
    return (
        f"{name}: the depths of {bad.size} of {len(sequences)} sequences depend on the object's shape by more "
        f"than {100 * SHAPE_TOLERANCE:.0f} % (first: {first}): the camera turns (by up to "
        f"{float(sequences.turn[index[bad]].max()):.3g} degrees), a turn changes a box according to the "
        "object's shape, and the method amplifies that where the camera moves little for the depth; the "
        "depths given are a flat object's facing the last observation, a round object's differ by the "
        "percentages named (docs/own-data.md, a camera that turns)"
    )


def _accepts(method: Any, keyword: str) -> bool:
    """Whether a loaded method (or a plain module) takes ``keyword``."""
    if hasattr(method, "accepts"):
        return bool(method.accepts(keyword))
    return all(
        keyword in inspect.signature(getattr(method, f)).parameters
        for f in ("predict", "predict_report")
        if hasattr(method, f)
    )


def format_depths(result: SequenceDepths) -> str:
    """The output CSV of the depths per sequence.

    Columns ``sequence,depth,observations,detections``, with error bars
    ``depth_lo,depth_hi,level,depth_std``, and, where any truth is given,
    ``true_depth,percent_error`` (empty where unknown).
    """
    has_truth = bool(np.isfinite(result.truth).any())
    header = ["sequence", "depth", "observations", "detections"]
    bars = (
        [result.intervals[c].tolist() for c in ("depth_lo", "depth_hi", "depth_std")]
        if result.intervals
        else []
    )
    if bars:
        header += ["depth_lo", "depth_hi", "level", "depth_std"]
    if has_truth:
        header += ["true_depth", "percent_error"]
    known = np.isfinite(result.truth) & np.isfinite(result.depth)
    pct = np.full(len(result.names), np.nan)
    pct[known] = percent_error(result.truth[known], result.depth[known])
    buf = io.StringIO()
    buf.write(",".join(header) + "\n")
    depth = result.depth.tolist()
    obs, det = result.observations.tolist(), result.detections.tolist()
    truth, err = result.truth.tolist(), pct.tolist()
    for i, name in enumerate(result.names):
        row = f"{text_cell(name)},{depth[i]!r},{obs[i]},{det[i]}"
        if bars:
            row += f",{bars[0][i]!r},{bars[1][i]!r},{result.level!r},{bars[2][i]!r}"
        if has_truth:
            row += f",{number_cell(truth[i])},{number_cell(err[i])}"
        buf.write(row + "\n")
    return buf.getvalue()


__all__ = [
    "SequenceDepths",
    "format_depths",
    "method_observations",
    "observation_indices",
    "predict_sequences",
    "select_observations",
]
