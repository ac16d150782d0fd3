"""Writing the predictions format (docs/format.md, "Predictions").

Reading it is :mod:`odmd_bench.evaluation.parse`'s job, checking it against the sets
:mod:`odmd_bench.evaluation.coverage`'s.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping

import numpy as np

from odmd_bench.data.registry import check_split
from odmd_bench.errors import UsageError
from odmd_bench.outputs import atomic_write

COLUMNS = ("split", "set", "index", "depth")


def format_predictions(
    split: str,
    depths: Mapping[str, np.ndarray],
    benchmark: str | None = None,
    uncertainty: Mapping[str, Mapping[str, np.ndarray]] | None = None,
    level: float | None = None,
) -> str:
    """The CSV text for ``{set name: (N,) depths}`` of one split.

    Depths are written with ``repr`` precision (17 significant digits), so a file read
    back gives exactly the same floats.

    Args:
        split: ``val`` or ``test``.
        depths: ``{set: (N,)}``.
        benchmark: written as a ``benchmark`` column when given.
        uncertainty: ``{set: {"depth_lo": (N,), "depth_hi": (N,)}}`` and/or
            ``"depth_std"``, the same columns for every set (docs/format.md, "Uncertainty").
        level: the interval's nominal coverage; needed with ``depth_lo``/``depth_hi``.
    """
    check_split(split)
    extra = _uncertainty_columns(depths, uncertainty, level)
    buf = io.StringIO()
    header = list(COLUMNS) + extra + (["benchmark"] if benchmark else [])
    buf.write(",".join(header) + "\n")
    for set_name, values in depths.items():
        arr = np.asarray(values, dtype=np.float64)
        if arr.ndim != 1:
            raise UsageError(f"depths for set {set_name!r} must be 1-D, got shape {arr.shape}")
        tail = f",{benchmark}" if benchmark else ""
        if not extra:
            for i, v in enumerate(arr.tolist()):
                buf.write(f"{split},{set_name},{i},{v!r}{tail}\n")
            continue
        cols = (uncertainty or {})[set_name]
        cells = [
            [repr(level)] * arr.size
            if c == "level"
            else [repr(v) for v in np.asarray(cols[c], dtype=np.float64).tolist()]
            for c in extra
        ]
        for i, v in enumerate(arr.tolist()):
            buf.write(f"{split},{set_name},{i},{v!r}," + ",".join(col[i] for col in cells) + f"{tail}\n")
    return buf.getvalue()


def _uncertainty_columns(
    depths: Mapping[str, np.ndarray],
    uncertainty: Mapping[str, Mapping[str, np.ndarray]] | None,
    level: float | None,
) -> list[str]:
    """The uncertainty columns to write, in the format's order; every problem named at once."""
    if not uncertainty:
        return []
    problems = []
    first = next(iter(uncertainty.values()), {})
    given = [c for c in ("depth_lo", "depth_hi", "depth_std") if c in first]
    if ("depth_lo" in given) != ("depth_hi" in given):
        problems.append("depth_lo and depth_hi come together")
    if "depth_lo" in given and not (level is not None and 0 < level < 1):
        problems.append(f"an interval needs its level in (0, 1), got {level!r}")
    for s, values in depths.items():
        cols = uncertainty.get(s, {})
        if sorted(cols) != sorted(given):
            problems.append(f"set {s!r} has the uncertainty columns {sorted(cols)}, expected {sorted(given)}")
            continue
        for c in given:
            if np.shape(cols[c]) != np.shape(values):
                problems.append(
                    f"set {s!r}: {c} has shape {np.shape(cols[c])}, its depths {np.shape(values)}"
                )
    if problems:
        raise UsageError("cannot write the uncertainty columns", problems)
    order = [c for c in ("depth_lo", "depth_hi") if c in given]
    return order + (["level"] if order else []) + (["depth_std"] if "depth_std" in given else [])


def write_predictions(
    path: str | os.PathLike[str],
    split: str,
    depths: Mapping[str, np.ndarray],
    benchmark: str | None = None,
    uncertainty: Mapping[str, Mapping[str, np.ndarray]] | None = None,
    level: float | None = None,
) -> None:
    """Write a predictions CSV atomically (see :func:`format_predictions`)."""
    text = format_predictions(split, depths, benchmark, uncertainty, level)
    with atomic_write(path, "w") as fh:
        fh.write(text)
