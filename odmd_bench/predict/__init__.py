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
from typing import Any, Literal

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
        reasons: (N,) why a sequence has no depth (``depth`` NaN), empty where it has
            one: too little forward motion for a method that needs it
            (:data:`MIN_FORWARD_SHARE`), or the method's fallback (``fallback
            no_z_motion``; the benchmarks score the fallback's stand-in depth, as the
            paper does, but an own sequence is given none).
        method_depth: (N,) what the method answered for every sequence, the fallbacks'
            stand-in depths included, as the benchmarks score them (the tables of
            :mod:`odmd_bench.predict.accuracy` do); empty tuple where not given.
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
    reasons: tuple[str, ...] = ()
    method_depth: np.ndarray | tuple[()] = ()
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
    sequences: Sequences,
    method: str | Any,
    missing: Missing | None = None,
    calibration: Any = None,
    **options: Any,
) -> SequenceDepths:
    """The depth at the last observation of every sequence, by a registered method.

    A method whose module declares ``OBSERVATIONS = k`` (DBox: 10) gets ``k``
    observations chosen evenly with the first and the last kept
    (:func:`select_observations`) from a longer sequence; a shorter one is refused.
    Every other method takes all the observations.

    Args:
        sequences: from :func:`read_sequences`.
        method: a registered name (:func:`odmd_bench.methods.load`) or a loaded method.
        missing: missed detections, ``"omit"`` (the default for a method that takes any
            number of observations: the method gets each sequence's detected
            observations only, :func:`omit_missing`) or ``"fill"`` (the paper's rule,
            each method's own; the default for a method built for a fixed number, which
            ``"omit"`` would leave short). A method that takes ``missing=`` itself
            (robust) gets it and applies it to all the observations.
        calibration: an :class:`odmd_bench.predict.intervals.IntervalCalibration` of this method
            (its pooled factor): error bars for every sequence; None: none.
        **options: the method's options (``config=``, ``weights=``, ``mode=``).

    Returns:
        :class:`SequenceDepths`.

    Raises:
        UsageError: an unknown method or option; a method that needs the camera
            intrinsics and none were given; sequences too short for the method;
            ``missing="omit"`` for a method built for a fixed number of observations.
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
    if missing is None:
        missing = "fill" if wanted is not None else "omit"
    if missing not in MISSING:
        raise UsageError(f"unknown missing {missing!r}; expected one of {', '.join(MISSING)}")
    if missing == "omit" and wanted is not None:
        raise UsageError(
            f"method {name!r} takes {wanted} observations per sequence, which omitting the missed "
            "detections would leave short; use --missing fill (missing='fill'), the rule it was built with"
        )
    omit = missing == "omit"
    if _accepts(m, "missing"):  # the method's own rule (robust leaves them out of its fit)
        options = {**options, "missing": missing}
        omit = False
    bars = (
        {c: np.full(n, np.nan) for c in ("depth_lo", "depth_hi", "depth_std")}
        if calibration is not None
        else {}
    )
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
    reasons = np.full(n, "", dtype=object)
    shares: list[tuple[np.ndarray, np.ndarray]] = []
    needs_forward = bool(getattr(m, "NEEDS_FORWARD_MOTION", None) or _module_flag(m, "NEEDS_FORWARD_MOTION"))
    groups: list[tuple[np.ndarray, Examples, np.ndarray | None]] = []
    for index, ex in sequences.groups:
        if omit:
            few, parts = omit_missing(ex)
            for i in few.tolist():
                k = int(ex.detected[i].sum())
                reasons[index[i]] = f"fewer than 2 detections ({k} of {ex.n_obs}; --missing omit)"
                depth[index[i]] = np.nan
                used[index[i]] = detections[index[i]] = k
            groups += [(index[at], sub, shift) for at, sub, shift in parts]
        else:
            groups.append((index, ex, None))
    for index, ex, shift in groups:
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
        reasons[index] = locate_fallbacks(m, run_on, run_options, c, d)
        if shift is not None:  # the depth at the last detection, carried to the last observation
            d = d + shift
        other = ex.extras.get("other_carry_boxes")
        if other is not None:  # (a method that models the turn gets them without the rotation)
            o = _other_depths(m, ex, other, options)
            shaped.append((index, d, o if shift is None else o + shift))
        depth[index] = d
        if needs_forward:
            share = forward_share(ex, d)
            shares.append((index, share))
            little = share < MIN_FORWARD_SHARE
            reasons[index[little]] = [
                f"too little forward motion ({100 * v:.2g} % of the depth; {name} needs {100 * MIN_FORWARD_SHARE:g} %)"
                for v in share[little].tolist()
            ]
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
    said = forward_warning(name, sequences, shares)
    if said:
        warnings.append(said)
    answered = depth.copy()
    depth[reasons != ""] = np.nan
    for values in bars.values():  # no error bars where there is no depth
        values[reasons != ""] = np.nan
    return SequenceDepths(
        names=sequences.names,
        depth=depth,
        truth=sequences.depth,
        observations=used,
        detections=detections,
        counts=counts,
        method=name,
        warnings=tuple(warnings),
        reasons=tuple(str(r) for r in reasons.tolist()),
        method_depth=answered,
        intervals=bars,
        level=None if calibration is None else float(calibration.level),
    )


#: A method that reads depth from the boxes' growth (``NEEDS_FORWARD_MOTION`` in its
#: module: Box_LS, expansion) gives no depth for an own sequence whose camera moved along
#: its optical axis by less than this share of the depth (docs/own-data.md, measured on
#: noisy scenes: below it Box_LS's median error is over 70 %, and it is 100 % with no
#: forward motion at all, where ``parallax`` and ``robust`` are within a few percent).
MIN_FORWARD_SHARE = 0.05


def _module_flag(method: Any, name: str) -> bool:
    module = inspect.getmodule(getattr(method, "predict", method))
    return bool(getattr(module, name, False))


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
    from odmd_bench.data.scale import implied_depth

    travel = np.ptp(examples.camera[:, :, 2], axis=1)
    scale = implied_depth(examples)
    scale = np.where(np.isfinite(scale), scale, np.where(depth > 0, depth, np.nan))
    with np.errstate(divide="ignore", invalid="ignore"):
        share = travel / scale
    return np.where(travel == 0, 0.0, share)


def forward_warning(
    name: str, sequences: Sequences, shares: list[tuple[np.ndarray, np.ndarray]]
) -> str | None:
    """The warning naming the sequences given no depth for too little forward motion, or None."""
    if not shares:
        return None
    index = np.concatenate([i for i, _ in shares])
    share = np.concatenate([s for _, s in shares])
    little = np.flatnonzero(share < MIN_FORWARD_SHARE)
    if not little.size:
        return None
    first = ", ".join(
        f"{show(sequences.names[int(index[i])])} ({100 * share[i]:.2g} %)" for i in little[:SHOWN].tolist()
    )
    return (
        f"{name}: {little.size} of {len(sequences)} sequences have too little forward motion for their depth "
        f"(the camera moved along its optical axis by less than {100 * MIN_FORWARD_SHARE:g} % of the depth; "
        f"first: {first}{', ...' if little.size > SHOWN else ''}): {name} reads depth from how the boxes grow "
        "as the camera moves towards the object, and gives no depth for them (the reason column says so); "
        "`parallax` and `robust` read it from sideways motion too (with --intrinsics)"
    )


#: At most this many extra runs of a method to find which sequences fell back.
LOCATE_RUNS = 256


def _subset(ex: Examples, options: dict[str, Any], idx: np.ndarray) -> tuple[Examples, dict[str, Any]]:
    sub = Examples(
        boxes=ex.boxes[idx],
        detected=ex.detected[idx],
        camera=ex.camera[idx],
        depth=None if ex.depth is None else ex.depth[idx],
        attrs=dict(ex.attrs),
    )
    rotation = options.get("rotation")
    return sub, options if rotation is None else {**options, "rotation": rotation[idx]}


def _call(m: Any, ex: Examples, options: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
    d, c = m.run(ex, **options) if hasattr(m, "run") else m.predict_report(ex.without_truth(), **options)
    return np.asarray(d, dtype=np.float64), dict(c)


def locate_fallbacks(
    m: Any, ex: Examples, options: dict[str, Any], counts: dict[str, Any], depth: np.ndarray
) -> np.ndarray:
    """Which examples took which of the method's declared ``FALLBACKS`` (``"fallback KEY"``, else ``""``).

    A method's report counts its fallbacks; which examples they were is found by running
    it again: once with another ``fallback_depth`` where it takes one (the examples whose
    depth follows it fell back), then on halves of the examples that fell back until
    each part took one kind (at most :data:`LOCATE_RUNS` runs; beyond, ``"fallback"``
    without the kind).

    Args:
        m: the loaded method.
        ex: the examples it ran on (N).
        options: its options.
        counts: its report.
        depth: (N,) its depths.
    """
    from odmd_bench.predict.report import declared

    keys = declared(m, "FALLBACKS")
    out = np.full(len(ex), "", dtype=object)
    if not any(isinstance(counts.get(k), int) and counts[k] for k in keys):
        return out
    idx = np.arange(len(ex))
    if _accepts(m, "fallback_depth"):
        other = -7.25 if options.get("fallback_depth") != -7.25 else -8.25  # (no default is negative)
        moved, _ = _call(m, ex, {**options, "fallback_depth": other})
        idx = np.flatnonzero(moved != depth)
        out[idx] = "fallback"
    runs = 0
    todo = [idx]
    while todo and runs < LOCATE_RUNS:
        part = todo.pop()
        if not part.size:
            continue
        sub, opts = _subset(ex, options, part)
        _, c = _call(m, sub, opts)
        runs += 1
        hit = {k: int(c[k]) for k in keys if isinstance(c.get(k), int) and c[k]}
        if not hit:
            out[part] = ""
        elif len(hit) == 1 and next(iter(hit.values())) == part.size:
            out[part] = f"fallback {next(iter(hit))}"
        elif part.size == 1:
            out[part] = "fallback " + ", ".join(hit)
        else:
            out[part] = "fallback"  # (until a half says which)
            todo += [part[: part.size // 2], part[part.size // 2 :]]
    return out


#: The rules for missed detections ``predict`` offers.
MISSING: tuple[str, ...] = ("omit", "fill")
Missing = Literal["omit", "fill"]


def omit_missing(examples: Examples) -> tuple[np.ndarray, list[tuple[np.ndarray, Examples, np.ndarray]]]:
    """The examples with their missed observations left out, grouped by what remains.

    Each example keeps its detected observations, in order; where the last observation
    is missed, the last detection becomes the example's last: the camera is taken
    relative to it, and the depth estimated there (along the last observation's optical
    axis, where the boxes were carried) becomes the last observation's by adding the
    detection's camera ``z`` relative to the last, ``shift`` (exact for a static object:
    ``Z_last = Z_j + c_jz``). ``extras`` with an observation axis are indexed alike.

    Args:
        examples: N examples.

    Returns:
        ``(few, parts)``: ``few`` the examples with fewer than 2 detections (nothing to
        estimate from), and per number of detections ``k >= 2`` ``(at, examples, shift)``:
        ``at`` the positions in ``examples``, the k-observation examples, ``shift`` (len(at),).
    """
    det = examples.detected
    k = det.sum(axis=1)
    few = np.flatnonzero(k < 2)
    parts = []
    for count in np.unique(k[k >= 2]).tolist():
        at = np.flatnonzero(k == count)
        # The detected observations' indices, in order: a stable sort puts them first.
        idx = np.argsort(~det[at], axis=1, kind="stable")[:, :count]
        rows = at[:, None]
        cam = examples.camera[rows, idx]
        shift = cam[:, -1, 2].copy()
        extras = {
            key: v[rows, idx]
            for key, v in examples.extras.items()
            if v.ndim >= 2 and v.shape[:2] == det.shape
        }
        sub = Examples(
            boxes=examples.boxes[rows, idx],
            detected=np.ones((at.size, count), dtype=bool),
            camera=cam - cam[:, -1:],
            depth=None if examples.depth is None else examples.depth[at],
            attrs=dict(examples.attrs),
            extras=extras,
        )
        parts.append((at, sub, shift))
    return few, parts


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
    ``depth_lo,depth_hi,level,depth_std``, where any truth is given
    ``true_depth,percent_error`` (empty where unknown), and ``reason``: why the depth is
    empty, empty where it is given (the error bars are empty there too).
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
    header.append("reason")
    reasons = result.reasons or ("",) * len(result.names)
    known = np.isfinite(result.truth) & np.isfinite(result.depth)
    pct = np.full(len(result.names), np.nan)
    pct[known] = percent_error(result.truth[known], result.depth[known])
    buf = io.StringIO()
    buf.write(",".join(header) + "\n")
    depth = result.depth.tolist()
    obs, det = result.observations.tolist(), result.detections.tolist()
    truth, err = result.truth.tolist(), pct.tolist()
    for i, name in enumerate(result.names):
        row = f"{text_cell(name)},{number_cell(depth[i])},{obs[i]},{det[i]}"
        if bars:
            row += f",{number_cell(bars[0][i])},{number_cell(bars[1][i])},{result.level!r},{number_cell(bars[2][i])}"
        if has_truth:
            row += f",{number_cell(truth[i])},{number_cell(err[i])}"
        buf.write(row + f",{text_cell(reasons[i])}\n")
    return buf.getvalue()


__all__ = [
    "LOCATE_RUNS",
    "MISSING",
    "MIN_FORWARD_SHARE",
    "SequenceDepths",
    "format_depths",
    "forward_share",
    "locate_fallbacks",
    "method_observations",
    "observation_indices",
    "omit_missing",
    "predict_sequences",
    "select_observations",
]
