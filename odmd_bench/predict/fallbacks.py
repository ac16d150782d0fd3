"""Which sequences took a method's fallback, found by running it again (:func:`locate_fallbacks`)."""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples

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
    if accepts(m, "fallback_depth"):
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


def accepts(method: Any, keyword: str) -> bool:
    """Whether a loaded method (or a plain module) takes ``keyword``."""
    if hasattr(method, "accepts"):
        return bool(method.accepts(keyword))
    return all(
        keyword in inspect.signature(getattr(method, f)).parameters
        for f in ("predict", "predict_report")
        if hasattr(method, f)
    )


__all__ = ["LOCATE_RUNS", "accepts", "locate_fallbacks"]
