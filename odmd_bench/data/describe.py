"""What a set of examples looks like: the ranges a method trained elsewhere must cover.

A learned method sees its training distribution; a benchmark set may lie at its edge.
:func:`describe` summarises, per set, the quantities the paper's formulations depend on:

- ``depth``: Z_n, the depth at the last observation (metres);
- ``camera_travel``: L = |c_1 - c_n|, the distance between the first and last camera
  positions (metres), the scale of the relative formulation f_Rel;
- ``depth_over_travel``: Z_n / L, the target f_Rel learns (dimensionless);
- ``forward``: the share of examples whose camera moved forward along its optical
  axis from the first to the last observation (c_1z - c_nz < 0: towards the object);
- ``xy_motion``: the share of examples with an x or y camera offset above 10 % of
  their largest z offset (0 for z-only data);
- missing detections: the share of observations, and of examples with at least one.

Unknown depths (NaN) and examples without camera motion are left out of the ranges
that need them; the counts used are reported.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples

#: Quantiles reported for each range, by name.
QUANTILES: dict[str, float] = {"min": 0.0, "p5": 5.0, "median": 50.0, "p95": 95.0, "max": 100.0}

#: An x or y offset above this share of the largest z offset counts as x,y motion.
XY_RATIO = 0.1


def _range(values: np.ndarray) -> dict[str, float | int | None]:
    values = values[np.isfinite(values)]
    out: dict[str, float | int | None] = {"n": int(values.size)}
    if values.size == 0:
        out.update({k: None for k in (*QUANTILES, "mean")})
        return out
    q = np.percentile(values, list(QUANTILES.values()))
    out.update({k: float(v) for k, v in zip(QUANTILES, q, strict=True)})
    out["mean"] = float(values.mean())
    return out


def describe(examples: Examples) -> dict[str, Any]:
    """Summary of a set's depths, camera motion and missing detections.

    Args:
        examples: any set (a benchmark split's set, a generated batch, one's own data).

    Returns:
        A JSON-ready dict: ``n``, ``n_obs``; ``depth``, ``camera_travel`` and
        ``depth_over_travel``, each ``{n, min, p5, median, p95, max, mean}`` (``n`` the
        examples counted; the others None when there are none); ``forward`` and
        ``xy_motion`` (shares of the examples with camera motion, None without any);
        ``missing_observations`` and ``examples_with_missing`` (shares).

    Example:
        >>> import odmd_bench
        >>> from odmd_bench.data.describe import describe
        >>> d = describe(odmd_bench.generate(200, "odms", "normal", rng=0))
        >>> d["xy_motion"], 0.0 < d["forward"] < 1.0
        (0.0, True)
    """
    n = len(examples)
    camera = np.asarray(examples.camera, dtype=np.float64)
    offsets = camera - camera[:, -1:, :]  # relative to the last observation, whatever the origin
    first = offsets[:, 0, :]  # c_1 - c_n
    travel = np.linalg.norm(first, axis=1)
    depth = np.asarray(examples.depth, dtype=np.float64)
    moved = travel > 0
    ratio = np.where(moved, depth / np.where(moved, travel, 1.0), np.nan)
    z_max = np.abs(offsets[..., 2]).max(axis=1)
    xy_max = np.abs(offsets[..., :2]).max(axis=(1, 2))
    detected = np.asarray(examples.detected, dtype=bool)
    n_moved = int(moved.sum())
    return {
        "n": n,
        "n_obs": int(camera.shape[1]),
        "depth": _range(depth),
        "camera_travel": _range(travel[moved]),
        "depth_over_travel": _range(ratio),
        "forward": float(np.mean(first[moved, 2] < 0)) if n_moved else None,
        "xy_motion": float(np.mean(xy_max[moved] > XY_RATIO * z_max[moved])) if n_moved else None,
        "missing_observations": float(np.mean(~detected)) if detected.size else 0.0,
        "examples_with_missing": float(np.mean(~detected.all(axis=1))) if n else 0.0,
    }


def format_description(name: str, d: dict[str, Any]) -> list[str]:
    """Lines of text for one set's :func:`describe` summary."""

    def num(v: float | None, digits: int) -> str:
        return "-" if v is None else f"{v:.{digits}f}"

    def share(v: float | None) -> str:
        return "-" if v is None else f"{100 * v:.1f} %"

    lines = [f"set {name}: {d['n']} examples x {d['n_obs']} observations"]
    head = "  {:<22} {:>6} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}"
    lines.append(head.format("", "n", "min", "p5", "median", "p95", "max", "mean"))
    for key, label, digits in (
        ("depth", "depth Z_n (m)", 3),
        ("camera_travel", "camera travel L (m)", 3),
        ("depth_over_travel", "Z_n / L", 3),
    ):
        r = d[key]
        lines.append(head.format(label, r["n"], *(num(r[k], digits) for k in (*QUANTILES, "mean"))))
    lines.append(
        f"  camera forward (towards the object): {share(d['forward'])}; x,y motion: "
        f"{share(d['xy_motion'])}; missing detections: {share(d['missing_observations'])} of "
        f"observations, {share(d['examples_with_missing'])} of examples"
    )
    return lines


__all__ = ["QUANTILES", "XY_RATIO", "describe", "format_description"]
