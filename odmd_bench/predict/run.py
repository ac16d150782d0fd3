"""The predict run: a registered method on a user's sequences, a depth per sequence.

:func:`predict_sequences` checks the method against the sequences (the rule for missed
detections, the observations it needs), runs it on each group of sequences of one length
(:func:`_run_group`: observations chosen or omitted, a turning camera's boxes, the
method's fallbacks located, error bars), gathers the checks' warnings
(:mod:`odmd_bench.predict.checks`) and returns :class:`SequenceDepths`;
:func:`format_depths` writes them as the CSV ``odmd-bench predict`` writes.
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
from odmd_bench.predict.checks import (
    MIN_FORWARD_SHARE,
    forward_share,
    forward_warning,
    method_warnings,
    scale_warnings,
    shape_warning,
)
from odmd_bench.predict.fallbacks import accepts, locate_fallbacks
from odmd_bench.predict.observations import MISSING, Missing, omit_missing, select_observations
from odmd_bench.predict.sequences import Sequences, number_cell, text_cell


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


@dataclass
class _Run:
    """What a run gathers over the groups of sequences, (N,) arrays in the file's order."""

    m: Any
    name: str
    sequences: Sequences
    options: dict[str, Any]
    wanted: int | None
    calibration: Any
    depth: np.ndarray
    used: np.ndarray
    detections: np.ndarray
    reasons: np.ndarray
    bars: dict[str, np.ndarray]
    warnings: list[str]
    needs_forward: bool
    counts: dict[str, int | str] = field(default_factory=dict)
    shaped: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    shares: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)


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
    missing = _missing_rule(name, wanted, missing)
    omit = missing == "omit"
    if accepts(m, "missing"):  # the method's own rule (robust leaves them out of its fit)
        options = {**options, "missing": missing}
        omit = False
    bars = (
        {c: np.full(n, np.nan) for c in ("depth_lo", "depth_hi", "depth_std")}
        if calibration is not None
        else {}
    )
    _check_length(sequences, name, wanted)
    run = _Run(
        m=m,
        name=name,
        sequences=sequences,
        options=options,
        wanted=wanted,
        calibration=calibration,
        depth=np.empty(n),
        used=np.empty(n, dtype=np.int64),
        detections=np.empty(n, dtype=np.int64),
        reasons=np.full(n, "", dtype=object),
        bars=bars,
        warnings=scale_warnings(ex for _, ex in sequences.groups),
        needs_forward=bool(
            getattr(m, "NEEDS_FORWARD_MOTION", None) or _module_flag(m, "NEEDS_FORWARD_MOTION")
        ),
    )
    for index, ex, shift in _groups(run, omit):
        _run_group(run, index, ex, shift)
    return _result(run)


def _missing_rule(name: str, wanted: int | None, missing: Missing | None) -> Missing:
    """The rule for missed detections: the one given, else the method's default; refused where unknown or short."""
    if missing is None:
        missing = "fill" if wanted is not None else "omit"
    if missing not in MISSING:
        raise UsageError(f"unknown missing {missing!r}; expected one of {', '.join(MISSING)}")
    if missing == "omit" and wanted is not None:
        raise UsageError(
            f"method {name!r} takes {wanted} observations per sequence, which omitting the missed "
            "detections would leave short; use --missing fill (missing='fill'), the rule it was built with"
        )
    return missing


def _check_length(sequences: Sequences, name: str, wanted: int | None) -> None:
    """Refuse sequences shorter than the method's fixed number of observations."""
    if wanted is None:
        return
    short = sequences.n_obs < wanted
    if short.any():
        first = [sequences.names[i] for i in np.flatnonzero(short)[:SHOWN]]
        raise UsageError(
            f"method {name!r} takes {wanted} observations per sequence; "
            f"{int(short.sum())} of {len(sequences)} sequences have fewer: "
            + ", ".join(show(s) for s in first)
            + (", ..." if short.sum() > SHOWN else "")
            + f" (longer sequences give {wanted} chosen evenly, the first and the last kept)"
        )


def _groups(run: _Run, omit: bool) -> list[tuple[np.ndarray, Examples, np.ndarray | None]]:
    """``(index, examples, shift)`` the method runs on: each group, or its parts by detections with ``omit``.

    With ``omit``, a sequence with fewer than 2 detections gets its reason here.
    """
    groups: list[tuple[np.ndarray, Examples, np.ndarray | None]] = []
    for index, ex in run.sequences.groups:
        if omit:
            few, parts = omit_missing(ex)
            for i in few.tolist():
                k = int(ex.detected[i].sum())
                run.reasons[index[i]] = f"fewer than 2 detections ({k} of {ex.n_obs}; --missing omit)"
                run.depth[index[i]] = np.nan
                run.used[index[i]] = run.detections[index[i]] = k
            groups += [(index[at], sub, shift) for at, sub, shift in parts]
        else:
            groups.append((index, ex, None))
    return groups


def _run_group(run: _Run, index: np.ndarray, ex: Examples, shift: np.ndarray | None) -> None:
    """Run the method on one group (``index`` its positions) and keep what it gives in ``run``."""
    m, options = run.m, run.options
    if run.wanted is not None:
        ex = select_observations(ex, run.wanted)
    for line in method_warnings(m, ex.without_truth(), options):
        if line not in run.warnings:
            run.warnings.append(line)
    run_on, run_options = _turned(m, ex, options)
    d, c = _solve(run, index, run_on, run_options, ex)
    run.reasons[index] = locate_fallbacks(m, run_on, run_options, c, d)
    if shift is not None:  # the depth at the last detection, carried to the last observation
        d = d + shift
    other = ex.extras.get("other_carry_boxes")
    if other is not None:  # (a method that models the turn gets them without the rotation)
        o = _other_depths(m, ex, other, options)
        run.shaped.append((index, d, o if shift is None else o + shift))
    run.depth[index] = d
    if run.needs_forward:
        share = forward_share(ex, d)
        run.shares.append((index, share))
        little = share < MIN_FORWARD_SHARE
        run.reasons[index[little]] = [
            f"too little forward motion ({100 * v:.2g} % of the depth; {run.name} needs {100 * MIN_FORWARD_SHARE:g} %)"
            for v in share[little].tolist()
        ]
    if run.calibration is not None:
        from odmd_bench.predict.intervals import POOLED, method_spread

        spread = method_spread(m, run_on, run_options) if hasattr(m, "spread") else None
        for column, values in run.calibration.intervals(d, spread, key=POOLED).items():
            run.bars[column][index] = values
    run.used[index] = ex.n_obs
    run.detections[index] = ex.detected.sum(axis=1)
    _add_counts(run.counts, c)


def _turned(m: Any, ex: Examples, options: dict[str, Any]) -> tuple[Examples, dict[str, Any]]:
    """What the method runs on: for a method that models the turn itself, the boxes as seen and the rotations."""
    rotation = ex.extras.get("rotation")
    if rotation is None or not accepts(m, "rotation"):
        return ex, options
    run_on = Examples(
        boxes=ex.extras["turned_boxes"],
        detected=ex.detected,
        camera=ex.camera,
        depth=ex.depth,
        attrs=dict(ex.attrs),
    )
    return run_on, {**options, "rotation": rotation}


def _solve(
    run: _Run, index: np.ndarray, run_on: Examples, run_options: dict[str, Any], ex: Examples
) -> tuple[np.ndarray, dict[str, Any]]:
    """The method's depths and report on one group, its errors naming the sequences."""
    m, name, names = run.m, run.name, run.sequences.names
    try:
        d, c = (
            m.run(run_on, **run_options)
            if hasattr(m, "run")
            else m.predict_report(run_on.without_truth(), **run_options)
        )
    except DepthRangeError as e:
        bad = [names[int(index[i])] for i in e.where]
        raise DepthRangeError(
            e.message.replace("examples", "sequences"),
            [
                "sequences "
                + ", ".join(show(x) for x in bad[:SHOWN])
                + (", ..." if len(bad) > SHOWN else ""),
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
        bad = [names[int(i)] for i in index[far][:SHOWN]]
        raise DepthRangeError(
            f"method {name!r} gives depths that are not finite or beyond {MAX_ABS_DEPTH:.0e} m for "
            f"{int(far.sum())} of {len(index)} sequences",
            ["sequences " + ", ".join(show(x) for x in bad) + (", ..." if far.sum() > SHOWN else "")],
            where=index[far].tolist(),
        )
    return d, c


def _add_counts(counts: dict[str, int | str], report: dict[str, Any]) -> None:
    """Add a group's report to the run's: counts summed, strings (what the method says of its run) kept."""
    for key, value in report.items():
        if isinstance(value, str):  # what the method says of its run (e.g. the weights)
            counts[key] = value
        elif key != "n":
            before = counts.get(key, 0)
            counts[key] = (before if isinstance(before, int) else 0) + int(value)


def _result(run: _Run) -> SequenceDepths:
    """The run's :class:`SequenceDepths`: the shape and forward-motion warnings added, no depth where a reason."""
    sequences, warnings, reasons = run.sequences, run.warnings, run.reasons
    said = shape_warning(run.name, sequences.names, sequences.turn, run.shaped)
    if said:
        warnings.append(said)
    said = forward_warning(run.name, sequences.names, run.shares)
    if said:
        warnings.append(said)
    depth = run.depth
    answered = depth.copy()
    depth[reasons != ""] = np.nan
    for values in run.bars.values():  # no error bars where there is no depth
        values[reasons != ""] = np.nan
    return SequenceDepths(
        names=sequences.names,
        depth=depth,
        truth=sequences.depth,
        observations=run.used,
        detections=run.detections,
        counts=run.counts,
        method=run.name,
        warnings=tuple(warnings),
        reasons=tuple(str(r) for r in reasons.tolist()),
        method_depth=answered,
        intervals=run.bars,
        level=None if run.calibration is None else float(run.calibration.level),
    )


def _module_flag(method: Any, name: str) -> bool:
    module = inspect.getmodule(getattr(method, "predict", method))
    return bool(getattr(module, name, False))


def _other_depths(m: Any, ex: Examples, boxes: np.ndarray, options: dict[str, Any]) -> np.ndarray:
    """The method's depths from the boxes carried the other way (NaN where it fell back)."""
    other = Examples(boxes=boxes, detected=ex.detected, camera=ex.camera, attrs=dict(ex.attrs))
    try:
        d, _ = m.run(other, **options) if hasattr(m, "run") else m.predict_report(other, **options)
    except (DepthRangeError, DataError):
        return np.full(len(ex), np.nan)
    return np.asarray(d, dtype=np.float64)


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


__all__ = ["SequenceDepths", "format_depths", "method_observations", "predict_sequences"]
