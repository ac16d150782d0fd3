"""The spread of a depth estimate: the posterior standard deviation of ``log Z`` from box sizes.

``predict_spread`` (the optional third function of a method, :mod:`odmd_bench.methods`)
for ``robust`` and ``box-ls``: how sure the boxes and the camera's ``z`` make the depth,
whatever estimate a method then gives. It is the posterior of ``mode="scale"`` (the
package docstring): Gaussian noise in log box size of unknown scale (Jeffreys' prior),
the two log sizes at unit depth integrated out, so that the likelihood of ``Z`` is
``RSS(Z)^-(k - 1)`` for ``k`` used observations, and a prior flat in ``1/Z`` on
``[z_low, z_low + max_depth_ratio * travel]`` (the full fit's far bound: the largest
depth, 30 times the camera's travel, on every benchmark; not tuned). The spread is the
posterior standard deviation of ``log Z`` on a grid of ``GRID`` points, so a relative
one: 0.1 means "about 10 % either way". Where the boxes cannot tell depth at all (fewer
than two usable observations, no ``z`` motion) it is :data:`UNRESOLVED`.

It is a *shape* of the uncertainty, not its size: :mod:`odmd_bench.predict.intervals` scales it
by a factor fitted on the val sets (split conformal), so that the intervals cover what
they claim whether or not this model's noise is the data's.
"""

from __future__ import annotations

import numpy as np
from odmd_bench_baselines.robust.model import DEFAULT_PARAMS, RobustParams

from odmd_bench import Examples, fill_missing

#: Points of the grid over log depth.
GRID = 256
#: Examples per block: keeps the (block, GRID, n_obs, 2) temporaries near 20 MB.
_BLOCK = 512
#: The spread where depth is not observable from box sizes (a factor e either way).
UNRESOLVED = 1.0


def posterior_spread(
    boxes: np.ndarray, usable: np.ndarray, camera: np.ndarray, params: RobustParams = DEFAULT_PARAMS
) -> np.ndarray:
    """(N,) the posterior standard deviation of ``log Z`` (module docstring).

    Args:
        boxes: (N, n_obs, 4) boxes; ``w`` and ``h`` are read.
        usable: (N, n_obs) bool, the observations used.
        camera: (N, n_obs, 3) camera positions relative to the last observation; ``z``
            and the travel are read.
        params: ``min_depth`` and ``max_depth_ratio``.

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(8, perturbation="normal", rng=0)
        >>> s = posterior_spread(ex.boxes, ex.detected, ex.camera)
        >>> bool(((s > 0) & (s < 0.1)).all())  # noise-free boxes: a sharp posterior
        True
    """
    n = boxes.shape[0]
    if n > _BLOCK:
        out = np.empty(n)
        for start in range(0, n, _BLOCK):
            sl = slice(start, start + _BLOCK)
            out[sl] = posterior_spread(boxes[sl], usable[sl], camera[sl], params)
        return out
    m = usable.astype(np.float64)
    k = m.sum(axis=1)
    cz = np.where(usable, camera[:, :, 2], 0.0)
    nearest = np.max(np.where(usable, cz, -np.inf), axis=1)
    zspread = np.where(k >= 2, nearest - np.min(np.where(usable, cz, np.inf), axis=1), 0.0)
    ok = (k >= 2) & (zspread > 0)
    out = np.full(n, UNRESOLVED)
    sel = np.flatnonzero(ok)
    if not sel.size:
        return out
    travel = np.sqrt((np.where(usable[sel, :, None], camera[sel], 0.0) ** 2).sum(axis=2)).max(axis=1)
    z_low = np.maximum(nearest[sel], 0.0) + params.min_depth
    z_high = np.maximum(z_low + params.max_depth_ratio * travel, z_low * (1 + 1e-6))
    lo, hi = np.log(z_low), np.log(z_high)
    x = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, GRID)  # (S, g)
    tiny = np.finfo(np.float64).tiny
    ms = m[sel]
    log_size = np.log(np.where(usable[sel, :, None], boxes[sel, :, 2:4], 1.0))
    lam = np.log(np.maximum(np.exp(x)[:, :, None] - cz[sel][:, None, :], tiny))  # (S, g, n_obs)
    mm = ms[:, None, :, None]
    v = (log_size[:, None, :, :] + lam[:, :, :, None]) * mm
    mean = v.sum(axis=2, keepdims=True) / ms.sum(axis=1)[:, None, None, None]
    rss = (((v - mean) * mm) ** 2).sum(axis=(2, 3))
    logp = -(k[sel] - 1.0)[:, None] * np.log(np.maximum(rss, tiny)) - x  # prior flat in 1/Z
    p = np.exp(logp - logp.max(axis=1, keepdims=True))
    p /= p.sum(axis=1, keepdims=True)
    mu = (p * x).sum(axis=1)
    sd = np.sqrt(np.maximum((p * (x - mu[:, None]) ** 2).sum(axis=1), 0.0))
    # Never below a quarter of a grid step (the grid's resolution), never 0.
    out[sel] = np.maximum(sd, 0.25 * (hi - lo) / (GRID - 1))
    return out


def predict_spread(
    examples: Examples, *_args: object, missing: str = "omit", **_options: object
) -> np.ndarray:
    """(N,) the spread of ``robust``'s (and ``box-ls``'s) estimates: :func:`posterior_spread`.

    Takes the method's options and ignores all but ``missing`` (``"fill"``: missing
    boxes filled by the shared rule, as Box_LS does, instead of left out).
    """
    boxes = np.asarray(examples.boxes, dtype=np.float64)
    detected = np.asarray(examples.detected, dtype=bool)
    if missing == "fill":
        boxes = fill_missing(boxes, detected)
        detected = np.broadcast_to(detected.any(axis=1, keepdims=True), detected.shape)
    camera = np.asarray(examples.camera, dtype=np.float64)
    usable = detected & np.isfinite(boxes).all(axis=2) & (boxes[:, :, 2] > 0) & (boxes[:, :, 3] > 0)
    usable &= np.isfinite(camera).all(axis=2)
    return posterior_spread(boxes, usable, camera)


def box_ls_spread(examples: Examples, *_args: object, **_options: object) -> np.ndarray:
    """(N,) the spread of ``box-ls``'s estimates: :func:`predict_spread` with missing boxes filled, as Box_LS does."""
    return predict_spread(examples, missing="fill")
