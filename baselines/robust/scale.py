"""``mode="scale"``: the posterior depth from box sizes (see the package docstring)."""

from __future__ import annotations

import numpy as np
from odmd_bench_baselines.robust import model
from odmd_bench_baselines.robust.model import DEFAULT_PARAMS, RobustParams

#: Scale mode: grid points of every zoom round after the first (see ``_scale_posterior``).
_ZOOM_POINTS = 32


def fit_scale(
    boxes: np.ndarray,
    usable: np.ndarray,
    camera: np.ndarray,
    params: RobustParams = DEFAULT_PARAMS,
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """``mode="scale"``: the posterior depth from box sizes (see the module docstring).

    Args:
        boxes: (N, n_obs, 4) boxes; only ``w`` and ``h`` are read.
        usable: (N, n_obs) bool, observations that enter the fit.
        camera: (N, n_obs, 3) camera positions relative to the last observation, m;
            only ``z`` is read.
        params: hyperparameters (``min_depth`` and the ``scale_*`` fields).

    Returns:
        ``(depths (N,), model (N,), counts)`` as :func:`predict_details`; ``model`` is 0
        where the posterior gave the depth and -1 where a fallback did.
    """
    n = boxes.shape[0]
    if n > model.CHUNK:
        return model.chunked(lambda sl: fit_scale(boxes[sl], usable[sl], camera[sl], params), n)
    m = usable.astype(np.float64)  # (N, n_obs)
    k = m.sum(axis=1)
    enough = k >= 2
    cz = np.where(usable, camera[:, :, 2], 0.0)
    nearest = np.max(np.where(usable, cz, -np.inf), axis=1)
    spread = np.where(enough, nearest - np.min(np.where(usable, cz, np.inf), axis=1), 0.0)
    resolvable = enough & (spread > 0)
    z_low = np.maximum(np.where(enough, nearest, 0.0), 0.0) + params.min_depth
    z_high = z_low + params.scale_max_depth_ratio * spread
    depth = np.zeros(n)
    sel = np.flatnonzero(resolvable)
    if sel.size:
        depth[sel] = _scale_posterior(
            np.log(np.where(usable[sel, :, None], boxes[sel, :, 2:4], 1.0)),
            m[sel],
            cz[sel],
            np.log(z_low[sel]),
            np.log(z_high[sel]),
            params,
        )
    counts = {
        "fit_failed": int((enough & ~resolvable).sum()),
        "too_few_detections": int((~enough).sum()),
        "n": int(n),
    }
    return depth, np.where(resolvable, 0, -1), counts


def _scale_posterior(
    log_size: np.ndarray,
    m: np.ndarray,
    cz: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    params: RobustParams,
) -> np.ndarray:
    """The 1/Z-weighted posterior median of ``Z`` on ``[exp(lo), exp(hi)]``, per example.

    Args:
        log_size: (N, n_obs, 2) ``log w, log h`` (anything where ``m`` is 0).
        m: (N, n_obs) 1.0 where an observation is used (at least two per example).
        cz: (N, n_obs) camera ``z`` (0 where unused).
        lo: (N,) log of the prior's smallest depth.
        hi: (N,) log of the prior's largest depth.
        params: ``scale_grid`` and ``scale_refinements``.

    Returns:
        (N,) depths. The integrand per unit ``x = log Z`` is ``RSS(Z)^(-(2k-2)/2)``
        (Gaussian noise in log size, unknown scale under Jeffreys' prior, the two log
        sizes at unit depth integrated out) times ``1/Z`` (the prior, flat in ``1/Z``)
        times ``1/Z`` (the weight of the relative-error loss); it is integrated by the
        trapezoid rule on a grid of ``scale_grid`` points, then, round by round, on
        ``_ZOOM_POINTS`` points across the three cells around the median.
    """
    half_dof = m.sum(axis=1) - 1.0  # (2k - 2) / 2
    msum = m.sum(axis=1)[:, None, None]
    mm = m[:, None, :, None]
    target = np.full(lo.shape, 0.5)  # the median's fraction of the mass in [lo, hi]
    tiny = np.finfo(np.float64).tiny
    x = lo
    for stage in range(params.scale_refinements + 1):
        g = params.scale_grid if stage == 0 else _ZOOM_POINTS
        x = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, g)  # (N, g)
        lam = np.log(np.maximum(np.exp(x)[:, :, None] - cz[:, None, :], tiny))  # (N, g, n_obs)
        v = (log_size[:, None, :, :] + lam[:, :, :, None]) * mm  # (N, g, n_obs, 2)
        mean = v.sum(axis=2, keepdims=True) / msum[:, :, :, None]
        rss = (((v - mean) * mm) ** 2).sum(axis=(2, 3))
        logp = -half_dof[:, None] * np.log(np.maximum(rss, tiny)) - 2.0 * x
        p = np.exp(logp - logp.max(axis=1, keepdims=True))
        cell = 0.5 * (p[:, 1:] + p[:, :-1])  # (N, g - 1); the spacing is equal per example
        cum = np.concatenate([np.zeros((len(x), 1)), np.cumsum(cell, axis=1)], axis=1)  # (N, g)
        want = target * cum[:, -1]
        j = np.clip((cum[:, 1:] < want[:, None]).sum(axis=1), 0, g - 2)  # cell holding the median
        rows = np.arange(len(x))
        if stage == params.scale_refinements:
            frac = (want - cum[rows, j]) / np.maximum(cell[rows, j], tiny)
            xs = x[rows, j] + np.clip(frac, 0.0, 1.0) * (x[rows, j + 1] - x[rows, j])
            return np.exp(xs)
        a = np.maximum(j - 1, 0)
        b = np.minimum(j + 2, g - 1)
        inside = cum[rows, b] - cum[rows, a]
        target = np.clip((want - cum[rows, a]) / np.maximum(inside, tiny), 0.0, 1.0)
        lo, hi = x[rows, a], x[rows, b]
    raise AssertionError("unreachable")  # pragma: no cover
