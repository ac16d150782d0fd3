"""Robust reprojection: a training-free, CALIBRATED depth estimator (name ``robust``).

Unlike Box_LS and DBox, which never use the camera intrinsics, this method NEEDS them
(``fx, fy, cx, cy`` and the image size, from the set's attributes or given with
``intrinsics=``): it fits the pinhole model of the paper (section 3.1 and the
supplementary "Depth from Motion Parallax") to every box coordinate at once, so that
optical expansion (``w, h``) and motion parallax (``x, y``) both inform the depth.
No training, no data beyond the example itself.

Model, per example, in normalised image units (``a = fx / W_I``, ``b = fy / H_I``,
``u0 = cx / W_I``, ``v0 = cy / H_I``). Unknowns: the depth ``Z = Z_n`` at the last
observation, the object's lateral position at the last observation in image units
(``X' = a X_n``, ``Y' = b Y_n``), its size in image units at unit depth
(``s_w = a W``, ``s_h = b H``), and a correction ``delta_i`` of every camera position
but the last. With the camera position ``C_i`` relative to the last observation (the
data's convention, checked on the original files: ``Z_i + C_Zi = Z_n`` and
``X_i = X_n - C_Xi``) and ``C~_i = C_i + delta_i``::

    Z_i = Z - C~_Zi
    x_i = u0 + (X' - a C~_Xi) / Z_i      y_i = v0 + (Y' - b C~_Yi) / Z_i
    w_i = s_w / Z_i                      h_i = s_h / Z_i

Objective, per example, for a noise model ``(sigma_box, sigma_camera)``::

    sum_i rho(|r_i|^2 / sigma_box^2) + |delta|^2 / sigma_camera^2

with ``r_i`` the four residuals (observed minus projected box) of observation ``i``
and ``rho`` a robust loss (Cauchy by default, scale ``loss_scale``) applied per
observation: a wrong detection corrupts all four numbers of one observation, so whole
observations are down-weighted.

Estimation:

1. Linear start. Multiplying each equation by ``Z_i`` makes it linear (Box_LS's
   expansion rows plus the parallax rows ``(x_i - u0) Z - X' = (x_i - u0) C_Zi -
   a C_Xi``). The four offsets are eliminated in closed form, leaving one weighted
   least-squares ratio for ``Z``; optional rounds of Cauchy reweighting per
   observation (``linear_iterations``; 0 by default, the val search found no gain).
2. Robust Levenberg-Marquardt (IRLS). Each step solves the joint Gauss-Newton system
   of ``(Z, X', Y', s_w, s_h)`` and all camera corrections, with the corrections
   eliminated in closed form (their Schur complement turns each observation's
   covariance into ``sigma_box^2 / w_i + J_delta P J_delta^T``, a diagonal plus a
   rank-one matrix, inverted by Sherman-Morrison), so only a 5 x 5 system per
   example remains; the systems of all examples are solved at once by a Cholesky
   factorisation written out over the 5 x 5 entries, each operation running on all
   examples. A step is kept only where it lowers the objective; examples leave the
   loop when their steps vanish, and at most ``iterations`` (10) steps are taken. No
   Python loop runs over examples; batches are fitted in chunks of ``CHUNK``
   examples, which only keeps the arrays in cache.
3. Noise model per example. The fit runs for each noise model of
   ``params.noise_models`` (by default one that trusts the boxes and doubts the camera
   positions, and one the other way round; the second starts where the first ended)
   and keeps, per example, the one with the best approximate marginal likelihood: the
   final objective plus ``sum_i log det Sigma_i`` plus the model's ``penalty`` (a
   prior log-odds, chosen on val).
4. Bounds: ``Z`` stays above ``max_i C~_Zi + min_depth``, so the object is in front of
   the camera at every used observation, and below ``max_depth_ratio`` times the
   camera's travel (the farthest used camera position from the last). Without the far
   bound a robust fit of tiny, noisy boxes can run away towards ``Z = infinity``
   (boxes that neither grow nor shift, the changes written off as outliers); a fit
   that ends on the far bound found no depth the motion can resolve and is not
   eligible. Provenance, for the record: this bound was added after the robot TEST
   set showed two such runaways (robot error 3424% without it); the same failure
   shows on odmd-v1 val (one camera-set example, 228% error). Its value, 30, was not
   tuned on any set: it sits above the largest true depth / travel ratio of the
   ODMD sets (about 19); the odmd-paper val numbers are the same with and without it.
5. Fallbacks, counted by :func:`predict_report`: where no noise model gives an
   eligible fit, the linear start (clipped to the bounds) is returned
   (``fit_failed``); an example with fewer than two usable observations gets depth 0,
   as Box_LS does (``too_few_detections``).

Missing detections (``detected`` False) are left out of the fit (``missing="omit"``,
the default: a box copied from another observation would sit at the wrong camera
position); ``missing="fill"`` applies the package's shared rule
(:func:`odmd_bench.fill_missing`) instead.

Sets without intrinsics (the ODMS-detection sets) raise :class:`~odmd_bench.DataError`
with ``mode="full"`` (the default) unless ``intrinsics=`` is given. ``mode="scale"``
uses ``w``, ``h`` and the camera's ``z`` only, needs no intrinsics and shares no code
with the full fit (:func:`fit_scale`). It is what to use on ODMS-detection, whose camera
moves along ``z`` only, so that lateral parallax carries no information there anyway.
It is a Bayesian estimate, not a robust-loss fit: on real detections a heavy-tailed
loss explains boxes that do not grow as "no expansion plus outliers" and runs away
towards infinite depth (it predicted 16 m for objects at 0.19 m). Model, per example:

* noise multiplicative in the box size (a detector's error grows with the box):
  ``log w_i = log s_w - log(Z - C_Zi) + e_i``, likewise ``h``, ``e ~ N(0, sigma^2)``,
  ``sigma`` unknown (Jeffreys' prior), ``log s_w`` and ``log s_h`` flat; integrated
  out exactly, the likelihood of ``Z`` is ``RSS(Z)^-(k - 1)`` for ``k`` used
  observations (``RSS`` the least-squares residual in log size at depth ``Z``);
* a prior flat in inverse depth ``1/Z`` (flat in the optical-expansion rate the boxes
  measure), on ``z_low <= Z <= z_low + scale_max_depth_ratio * travel``, with ``z_low``
  the nearest used camera position plus ``min_depth`` and ``travel`` the ``z`` extent
  of the used camera positions. This is the bound on depth relative to camera travel:
  where the boxes barely change, the data cannot tell large depths apart and the prior
  decides. Its value, 6, is the ODMS-detection design (the largest depth / travel of
  the val sets is 6.000), not a tuned number; the val results for 4 to 30 are in
  ``docs/robust.md``;
* the point estimate that minimises the expected *relative* error (the benchmark's
  metric) under the posterior: the median of the posterior weighted by ``1/Z``. An
  example whose depth is ill-determined is thereby pulled towards the depths where an
  error costs most, instead of towards the far end.

The posterior is integrated on a grid over ``log Z`` that zooms in on the estimate
(``scale_grid``, ``scale_refinements``); the result is exact on noise-free data inside
the prior and never leaves the prior's range. Fallbacks: fewer than two usable
observations give 0 (``too_few_detections``); used observations all at the same camera
``z`` give 0 (``fit_failed``: depth is not observable), as Box_LS does.

Hyperparameters (:data:`DEFAULT_PARAMS`) were chosen on the ``val`` sets only by
``python -m odmd_bench_baselines.robust_search`` (see that module for the grid and the command).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from odmd_bench import DataError, Examples, UsageError, fill_missing

Mode = Literal["full", "scale"]
Missing = Literal["omit", "fill"]
LOSSES = ("cauchy", "huber", "soft_l1", "linear")
MODES = ("full", "scale")
MISSING = ("omit", "fill")


@dataclass(frozen=True)
class NoiseModel:
    """One hypothesis about an example's noise.

    Attributes:
        sigma_box: standard deviation of every box coordinate, normalised image units.
        sigma_camera: prior standard deviation of each camera-position coordinate at
            every observation but the last, metres.
        penalty: added to this model's criterion (a prior log-odds against it).
    """

    sigma_box: float
    sigma_camera: float
    penalty: float = 0.0


@dataclass(frozen=True)
class RobustParams:
    """Hyperparameters of the robust fit (chosen on val by :mod:`odmd_bench_baselines.robust_search`).

    Attributes:
        loss: ``"cauchy"``, ``"huber"``, ``"soft_l1"`` or ``"linear"`` (plain least squares).
        loss_scale: scale ``c`` of the loss, in box-noise standard deviations: the Cauchy
            weight of an observation is ``1 / (1 + |r|^2 / (c sigma_box)^2)``.
        noise_models: the noise models fitted; each example keeps the best (see the
            module docstring).
        iterations: most Levenberg-Marquardt iterations.
        tolerance: an example stops when no unknown moves by more than this.
        linear_iterations: reweighting rounds of the linear start.
        min_depth: the object's smallest allowed depth at any observation, metres.
        max_depth_ratio: the largest allowed depth, as a multiple of the camera's
            travel (ODMD's sets stay below 20).
        scale_max_depth_ratio: ``mode="scale"`` only: the prior's largest depth, as a
            multiple of the camera's ``z`` travel. 6 is the ODMS-detection design: every
            val example of its four sets has depth / travel <= 6.0. Raise it for other
            geometries (the package's ``odms`` generator preset reaches about 20).
        scale_grid: ``mode="scale"`` only: points of the first grid over log depth
            (its spacing sets the quadrature's accuracy, about 1e-4 relative at 256).
        scale_refinements: ``mode="scale"`` only: rounds of zooming in on the estimate
            (each shrinks the bracket about 10 times).
    """

    loss: str = "cauchy"
    loss_scale: float = 4.0
    noise_models: tuple[NoiseModel, ...] = field(
        default_factory=lambda: (NoiseModel(2e-4, 0.02, 0.0), NoiseModel(3e-4, 1e-3, 0.0))
    )
    iterations: int = 10
    tolerance: float = 1e-9
    linear_iterations: int = 0
    min_depth: float = 1e-3
    max_depth_ratio: float = 30.0
    scale_max_depth_ratio: float = 6.0
    scale_grid: int = 256
    scale_refinements: int = 10

    def __post_init__(self) -> None:
        problems = []
        if self.loss not in LOSSES:
            problems.append(f"loss: {self.loss!r} is not one of {', '.join(LOSSES)}")
        for name in ("loss_scale", "tolerance", "min_depth", "max_depth_ratio", "scale_max_depth_ratio"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v > 0):
                problems.append(f"{name}: expected a positive number, got {v!r}")
        for name in ("iterations", "linear_iterations", "scale_refinements"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                problems.append(f"{name}: expected an integer >= 0, got {v!r}")
        g = self.scale_grid
        if isinstance(g, bool) or not isinstance(g, int) or g < 8:
            problems.append(f"scale_grid: expected an integer >= 8, got {g!r}")
        if not self.noise_models:
            problems.append("noise_models: expected at least one NoiseModel")
        for i, nm in enumerate(self.noise_models):
            if not isinstance(nm, NoiseModel):
                problems.append(f"noise_models[{i}]: expected a NoiseModel, got {nm!r}")
                continue
            if not (np.isfinite(nm.sigma_box) and nm.sigma_box > 0):
                problems.append(
                    f"noise_models[{i}].sigma_box: expected a positive number, got {nm.sigma_box!r}"
                )
            if not (np.isfinite(nm.sigma_camera) and nm.sigma_camera >= 0):
                problems.append(
                    f"noise_models[{i}].sigma_camera: expected a number >= 0, got {nm.sigma_camera!r}"
                )
            if not np.isfinite(nm.penalty):
                problems.append(f"noise_models[{i}].penalty: expected a finite number, got {nm.penalty!r}")
        if problems:
            raise UsageError("invalid robust-method parameters", problems)


#: Chosen on the val sets by ``python -m odmd_bench_baselines.robust_search`` (never on test).
DEFAULT_PARAMS = RobustParams()

Intrinsics = tuple[float, float, float, float, float, float]

#: Examples fitted together; larger batches are split (the results do not change).
CHUNK = 1024

#: Scale mode: grid points of every zoom round after the first (see ``_scale_posterior``).
_ZOOM_POINTS = 32


def predict(
    examples: Examples,
    params: RobustParams = DEFAULT_PARAMS,
    *,
    mode: Mode = "full",
    missing: Missing = "omit",
    intrinsics: Intrinsics | None = None,
) -> np.ndarray:
    """Depth ``Z_n`` of every example, metres.

    Args:
        examples: the examples; ``mode="full"`` needs their intrinsics (or ``intrinsics``).
        params: hyperparameters.
        mode: ``"full"`` (calibrated: all four box coordinates) or ``"scale"``
            (``w, h`` only; needs no intrinsics).
        missing: ``"omit"`` missing detections or ``"fill"`` them by the shared rule.
        intrinsics: ``(fx, fy, cx, cy, image_width, image_height)`` in pixels, used
            instead of the set's own.

    Returns:
        (N,) float64 depths.

    Raises:
        DataError: ``mode="full"`` on a set without intrinsics and none given.

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(64, perturbation="normal", rng=0)
        >>> bool(np.allclose(predict(ex), ex.depth, rtol=1e-9))
        True
    """
    return predict_report(examples, params, mode=mode, missing=missing, intrinsics=intrinsics)[0]


def predict_report(
    examples: Examples,
    params: RobustParams = DEFAULT_PARAMS,
    *,
    mode: Mode = "full",
    missing: Missing = "omit",
    intrinsics: Intrinsics | None = None,
) -> tuple[np.ndarray, dict[str, int]]:
    """Like :func:`predict`, also returning the counted fallbacks.

    Returns:
        ``(depths (N,), counts)`` with ``counts`` = ``{"fit_failed": k,
        "too_few_detections": m, "n": N}``.
    """
    depth, _, counts = predict_details(examples, params, mode=mode, missing=missing, intrinsics=intrinsics)
    return depth, counts


def predict_details(
    examples: Examples,
    params: RobustParams = DEFAULT_PARAMS,
    *,
    mode: Mode = "full",
    missing: Missing = "omit",
    intrinsics: Intrinsics | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """Like :func:`predict_report`, also returning which noise model each example kept.

    Returns:
        ``(depths (N,), model (N,) int, counts)``: ``model`` indexes
        ``params.noise_models``, -1 where a fallback gave the depth.
    """
    if mode not in MODES:
        raise UsageError(f"mode {mode!r} is not one of {', '.join(MODES)}")
    if missing not in MISSING:
        raise UsageError(f"missing {missing!r} is not one of {', '.join(MISSING)}")
    cam_model: tuple[float, float, float, float] | None = None
    if mode == "full":
        if intrinsics is None:
            try:
                intrinsics = examples.intrinsics()
            except DataError as e:
                raise DataError(
                    e.message + "; the robust method is calibrated: give the intrinsics "
                    "(--intrinsics FX FY CX CY with predict; intrinsics=(fx, fy, cx, cy, width, "
                    "height) in Python) or use the box sizes only (--mode scale; mode='scale')",
                    e.problems,
                ) from None
        if len(intrinsics) != 6 or not all(np.isfinite(float(v)) for v in intrinsics):
            raise UsageError(
                f"intrinsics must be 6 finite numbers (fx, fy, cx, cy, width, height), got {intrinsics}"
            )
        fx, fy, cx, cy, width, height = (float(v) for v in intrinsics)
        if not (fx > 0 and fy > 0 and width > 0 and height > 0):
            raise UsageError(f"intrinsics must have positive fx, fy and image size, got {intrinsics}")
        cam_model = (fx / width, fy / height, cx / width, cy / height)

    boxes = np.asarray(examples.boxes, dtype=np.float64)
    detected = np.asarray(examples.detected, dtype=bool)
    if missing == "fill":
        boxes = fill_missing(boxes, detected)
        use = np.broadcast_to(detected.any(axis=1, keepdims=True), detected.shape)
    else:
        use = detected
    usable = use & np.isfinite(boxes).all(axis=2) & (boxes[:, :, 2] > 0) & (boxes[:, :, 3] > 0)
    camera = np.asarray(examples.camera, dtype=np.float64)
    usable = usable & np.isfinite(camera).all(axis=2)
    if cam_model is None:
        return fit_scale(boxes, usable, camera, params)
    return fit(boxes, usable, camera, cam_model, params)


def _chunked(
    fit_slice: Callable[[slice], tuple[np.ndarray, np.ndarray, dict[str, int]]], n: int
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """A fit of ``n`` examples run ``CHUNK`` at a time, joined (examples are independent).

    Chunks keep the working arrays in cache.
    """
    parts = [fit_slice(slice(s, s + CHUNK)) for s in range(0, n, CHUNK)]
    counts = {k: sum(part[2][k] for part in parts) for k in parts[0][2]}
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]), counts


def fit(
    boxes: np.ndarray,
    usable: np.ndarray,
    camera: np.ndarray,
    cam_model: tuple[float, float, float, float] | None,
    params: RobustParams = DEFAULT_PARAMS,
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """The robust fit on arrays (see the module docstring).

    Args:
        boxes: (N, n_obs, 4) normalised ``x, y, w, h``.
        usable: (N, n_obs) bool, observations that enter the fit.
        camera: (N, n_obs, 3) camera positions relative to the last observation, m.
        cam_model: ``(a, b, u0, v0)`` = ``(fx / W_I, fy / H_I, cx / W_I, cy / H_I)``, or
            None to fit ``w, h`` only.
        params: hyperparameters.

    Returns:
        ``(depths (N,), model (N,), counts)`` as :func:`predict_details`.
    """
    n = boxes.shape[0]
    if n > CHUNK:
        return _chunked(lambda sl: fit(boxes[sl], usable[sl], camera[sl], cam_model, params), n)
    enough = usable.sum(axis=1) >= 2
    base = _Problem.build(boxes, usable, camera, cam_model, params.min_depth, params.max_depth_ratio)
    z0 = _linear_start(base, params)
    depth = z0.copy()
    best = np.full(n, np.inf)
    chosen = np.full(n, -1)
    z_first = z0
    if params.iterations > 0:
        for j, nm in enumerate(params.noise_models):
            # Later models start where the first one ended (fewer iterations).
            z, crit = _gauss_newton(base, z0 if j == 0 else z_first, nm, params)
            if j == 0:
                z_first = np.where(np.isfinite(z) & (z >= base.z_low), z, z0)
            crit = crit + nm.penalty
            # A fit that ends on the far bound found no depth in range: not eligible.
            ok = np.isfinite(z) & (z >= base.z_low) & (z < base.z_high * (1 - 1e-9)) & np.isfinite(crit)
            take = ok & (crit < best)
            depth = np.where(take, z, depth)
            best = np.where(take, crit, best)
            chosen = np.where(take, j, chosen)
        failed = enough & (chosen < 0)
    else:
        failed = np.zeros(n, dtype=bool)
    depth = np.where(enough, depth, 0.0)
    counts = {
        "fit_failed": int(failed.sum()),
        "too_few_detections": int((~enough).sum()),
        "n": int(n),
    }
    return depth, np.where(enough, chosen, -1), counts


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
    if n > CHUNK:
        return _chunked(lambda sl: fit_scale(boxes[sl], usable[sl], camera[sl], params), n)
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


@dataclass(frozen=True)
class _Problem:
    """The arrays of a fit, observations first: every array is (n_obs, N).

    ``g[c]`` is box coordinate ``c`` centred on the principal point (``x - u0``,
    ``y - v0``, ``w``, ``h``), zero where unused; ``k[c]`` the offset the camera's
    lateral motion adds (``-a C_X``, ``-b C_Y``, 0, 0); ``coords`` the coordinates in
    use (all four, or ``w, h``); ``m`` 1.0 where an observation is used; ``cam`` (3,
    n_obs, N); ``z_low`` (N,) the smallest depth that keeps the object in front of
    the uncorrected cameras.
    """

    coords: tuple[int, ...]
    g: tuple[np.ndarray, ...]
    k: tuple[np.ndarray, ...]
    m: np.ndarray
    cam: np.ndarray
    z_low: np.ndarray
    z_high: np.ndarray
    a: float
    b: float

    @classmethod
    def build(
        cls,
        boxes: np.ndarray,
        usable: np.ndarray,
        camera: np.ndarray,
        cam_model: tuple[float, float, float, float] | None,
        min_depth: float,
        max_depth_ratio: float,
    ) -> _Problem:
        a, b, u0, v0 = cam_model if cam_model is not None else (0.0, 0.0, 0.0, 0.0)
        coords = (0, 1, 2, 3) if cam_model is not None else (2, 3)
        use = usable.T
        centre = (u0, v0, 0.0, 0.0)
        g = tuple(np.where(use, boxes[:, :, c].T - centre[c], 0.0) for c in range(4))
        cam = np.where(use[None], np.moveaxis(camera, 2, 0).transpose(0, 2, 1), 0.0)  # (3, n, N)
        zero = np.zeros(use.shape)
        k = (-a * cam[0], -b * cam[1], zero, zero)
        z_low = np.max(np.where(use, cam[2], -np.inf), axis=0) + min_depth
        z_low = np.where(np.isfinite(z_low), z_low, min_depth)
        travel = np.sqrt((cam**2).sum(axis=0)).max(axis=0)  # farthest used camera position
        z_high = np.maximum(max_depth_ratio * travel, z_low + min_depth)
        return cls(coords, g, k, use.astype(np.float64), cam, z_low, z_high, a, b)

    def take(self, keep: np.ndarray) -> _Problem:
        """The problem restricted to the examples where ``keep`` (N,) is True."""
        return _Problem(
            self.coords,
            tuple(x[:, keep] for x in self.g),
            tuple(x[:, keep] for x in self.k),
            self.m[:, keep],
            self.cam[:, :, keep],
            self.z_low[keep],
            self.z_high[keep],
            self.a,
            self.b,
        )


def _weights(s: np.ndarray, loss: str, c2: float) -> np.ndarray:
    """IRLS weights ``rho'(s)`` for squared distances ``s``; ``c2`` the squared loss scale."""
    if loss == "cauchy":
        return 1.0 / (1.0 + s / c2)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + s / c2)
    if loss == "huber":
        return np.minimum(1.0, np.sqrt(c2 / np.maximum(s, 1e-300)))
    return np.ones_like(s)


def _rho(s: np.ndarray, loss: str, c2: float) -> np.ndarray:
    """The robust loss of squared distances ``s`` (``rho(s) ~ s`` near 0)."""
    if loss == "cauchy":
        return c2 * np.log1p(s / c2)
    if loss == "soft_l1":
        return 2.0 * c2 * (np.sqrt(1.0 + s / c2) - 1.0)
    if loss == "huber":
        return np.where(s <= c2, s, 2.0 * np.sqrt(c2 * s) - c2)
    return s


def _linear_start(prob: _Problem, params: RobustParams) -> np.ndarray:
    """Depth from the linearised equations ``g_ic (Z - C_Zi) = t_c + k_ic``, robustly reweighted.

    For per-observation weights ``v_i``, eliminating the offsets ``t_c`` leaves
    ``Z = sum v (g - g_bar)(d - d_bar) / sum v (g - g_bar)^2`` with ``d = g C_Z + k``
    (sums over observations and coordinates). Each round then gives every observation
    a Cauchy weight of its residual (image units) against the example's median
    residual. Returns (N,) depths, at least ``z_low``.
    """
    cz = prob.cam[2]
    v = prob.m
    z = prob.z_low
    d = [prob.g[c] * cz + prob.k[c] for c in prob.coords]
    g = [prob.g[c] for c in prob.coords]
    for it in range(params.linear_iterations + 1):
        vs = np.maximum(v.sum(axis=0), 1e-300)
        num = np.zeros(v.shape[1])
        den = np.zeros(v.shape[1])
        gc, dc = [], []
        for gj, dj in zip(g, d, strict=True):
            gcj = gj - (v * gj).sum(axis=0) / vs
            dcj = dj - (v * dj).sum(axis=0) / vs
            num += (v * gcj * dcj).sum(axis=0)
            den += (v * gcj * gcj).sum(axis=0)
            gc.append(gcj)
            dc.append(dcj)
        with np.errstate(divide="ignore", invalid="ignore"):
            z_new = num / den
        z = np.where(np.isfinite(z_new), np.clip(z_new, prob.z_low, prob.z_high), prob.z_low)
        if it == params.linear_iterations:
            break
        zi = np.maximum(z - cz, params.min_depth)
        r2 = np.zeros(cz.shape)
        for gcj, dcj in zip(gc, dc, strict=True):
            r2 += ((gcj * z - dcj) / zi) ** 2
        scale2 = np.maximum(_masked_median(r2, prob.m > 0), 1e-30)
        v = prob.m * _weights(r2 / scale2, "cauchy", params.loss_scale**2)
    return z


def _masked_median(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Median over axis 0 of ``x`` (n, N) where ``mask``; 0 where a column has none."""
    cnt = mask.sum(axis=0)
    srt = np.sort(np.where(mask, x, np.inf), axis=0)
    lo = np.take_along_axis(srt, np.maximum((cnt - 1) // 2, 0)[None], axis=0)[0]
    hi = np.take_along_axis(srt, np.maximum(cnt // 2, 0)[None], axis=0)[0]
    return np.where(cnt > 0, 0.5 * (lo + hi), 0.0)


def _offsets(prob: _Problem, z: np.ndarray) -> np.ndarray:
    """(nc, N) offsets ``t_c`` that best fit ``g_ic Z_i = t_c + k_ic`` for depths ``z`` (N,)."""
    zi = z - prob.cam[2]
    msum = np.maximum(prob.m.sum(axis=0), 1.0)
    return np.stack([(prob.m * (prob.g[c] * zi - prob.k[c])).sum(axis=0) / msum for c in prob.coords])


def _gauss_newton(
    prob: _Problem, z0: np.ndarray, noise: NoiseModel, params: RobustParams
) -> tuple[np.ndarray, np.ndarray]:
    """Robust Levenberg-Marquardt for one noise model, all examples at once.

    Unknowns per example: ``theta = (Z, t)`` with ``t`` the offsets of the coordinates
    in use (``X', Y', s_w, s_h``) and the camera corrections ``delta`` (3, n_obs).
    See the module docstring for the objective and the step.

    Returns ``(depth (N,), criterion (N,))``: the criterion is the final objective plus
    ``sum_i log det Sigma_i`` (an approximate negative log marginal likelihood, up to
    constants shared by all noise models).
    """
    n_obs, n = prob.m.shape
    cs = prob.coords
    nc = len(cs)
    var_box = noise.sigma_box**2
    c2 = params.loss_scale**2
    cam_var = np.full((n_obs, 1), noise.sigma_camera**2)
    cam_var[-1] = 0.0  # the last position is zero by definition
    inv_cam_var = np.divide(1.0, cam_var, out=np.zeros_like(cam_var), where=cam_var > 0)
    dcam = {0: prob.a**2, 1: prob.b**2, 2: 0.0, 3: 0.0}

    theta = np.concatenate([z0[None], _offsets(prob, z0)])  # (1 + nc, N)
    delta = np.zeros((3, n_obs, n))
    out_theta = theta.copy()
    out_delta = delta.copy()
    out_cost = np.empty(n)
    ids = np.arange(n)
    pr = prob
    state: tuple[np.ndarray, ...] = _evaluate(pr, theta, delta, var_box, c2, params, inv_cam_var)
    lam = np.full(n, 1e-4)
    for _ in range(params.iterations):
        cost, zi, p, r, s = state
        om = np.maximum(pr.m * _weights(s, params.loss, c2), 1e-12)
        iz = 1.0 / zi
        iz2 = iz * iz
        q = cam_var * iz2
        inv_md = [1.0 / (var_box / om + q * dcam[c]) for c in cs]
        u = [p[j] * inv_md[j] for j in range(nc)]
        pu_u = sum(p[j] * u[j] for j in range(nc))
        kappa = q / (1.0 + q * pu_u)
        one_k = 1.0 - kappa * pu_u
        # Residual with the current corrections undone (linearised): r + J_delta delta.
        dz = delta[2] * iz
        rt = []
        for j, c in enumerate(cs):
            extra = p[j] * dz
            if c == 0:
                extra -= prob.a * delta[0] * iz
            elif c == 1:
                extra -= prob.b * delta[1] * iz
            rt.append(r[j] + extra)
        ru = sum(rt[j] * u[j] for j in range(nc))
        sr = [rt[j] * inv_md[j] - kappa * ru * u[j] for j in range(nc)]  # Sigma^-1 r~
        # Normal equations with J_theta = (1/Z_i)[-p, I] and Sigma^-1 = D^-1 - kappa u u^T,
        # one (N,) array per entry of the (1 + nc) x (1 + nc) matrices.
        k1 = 1 + nc
        h: list[list[np.ndarray]] = [[np.empty(0)] * k1 for _ in range(k1)]
        grad: list[np.ndarray] = [np.empty(0)] * k1
        h[0][0] = (iz2 * pu_u * one_k).sum(axis=0)
        grad[0] = -(iz * sum(p[j] * sr[j] for j in range(nc))).sum(axis=0)
        kz = iz2 * kappa
        one_kz = iz2 * one_k
        for j in range(nc):
            h[0][1 + j] = h[1 + j][0] = -(one_kz * u[j]).sum(axis=0)
            grad[1 + j] = (iz * sr[j]).sum(axis=0)
            kzu = kz * u[j]
            h[1 + j][1 + j] = (iz2 * inv_md[j] - kzu * u[j]).sum(axis=0)
            for col in range(j + 1, nc):
                h[1 + j][1 + col] = h[1 + col][1 + j] = -(kzu * u[col]).sum(axis=0)
        for i in range(k1):
            h[i][i] = h[i][i] * (1.0 + lam) + lam * 1e-12
        step = np.stack(_solve_spd(h, grad))  # (1 + nc, Na)
        # New corrections: P J_delta^T Sigma^-1 (r~ - J_theta step).
        v = [rt[j] - (step[1 + j] - p[j] * step[0]) * iz for j in range(nc)]
        vu = sum(v[j] * u[j] for j in range(nc))
        sv = [v[j] * inv_md[j] - kappa * vu * u[j] for j in range(nc)]
        fac = cam_var * iz
        new_delta = np.zeros_like(delta)
        new_delta[2] = fac * sum(p[j] * sv[j] for j in range(nc))
        if cs[0] == 0:
            new_delta[0] = -prob.a * fac * sv[0]
            new_delta[1] = -prob.b * fac * sv[1]
        new = theta + step
        z_floor = np.max(np.where(pr.m > 0, pr.cam[2] + new_delta[2], -np.inf), axis=0) + params.min_depth
        new[0] = np.minimum(np.maximum(new[0], np.maximum(pr.z_low, z_floor)), pr.z_high)
        new_state = _evaluate(pr, new, new_delta, var_box, c2, params, inv_cam_var)
        better = np.isfinite(new_state[0]) & (new_state[0] <= cost)
        theta = np.where(better, new, theta)
        delta = np.where(better, new_delta, delta)
        state = tuple(np.where(better, y, x) for x, y in zip(state, new_state, strict=True))
        lam = np.where(better, np.maximum(lam * 0.3, 1e-9), lam * 10.0)
        done = (np.abs(step).max(axis=0) <= params.tolerance) | (lam > 1e6)
        if done.all():
            break
        if done.mean() > 0.2:  # drop finished examples from the working set
            out_theta[:, ids[done]] = theta[:, done]
            out_delta[:, :, ids[done]] = delta[:, :, done]
            keep = ~done
            ids = ids[keep]
            pr = pr.take(keep)
            theta, delta, lam = theta[:, keep], delta[:, :, keep], lam[keep]
            state = tuple(x[..., keep] for x in state)
    out_theta[:, ids] = theta
    out_delta[:, :, ids] = delta

    # Criterion: objective + sum_i log det Sigma_i (Sigma_i = D_i + q_i p_i p_i^T).
    cost, zi, p, _, _ = _evaluate(prob, out_theta, out_delta, var_box, c2, params, inv_cam_var)
    q = cam_var / zi**2
    logdet = np.zeros(zi.shape)
    quad = np.zeros(zi.shape)
    for j, c in enumerate(cs):
        md = var_box + q * dcam[c]
        logdet += np.log(md)
        quad += p[j] ** 2 / md
    logdet += np.log1p(q * quad)
    out_cost[:] = cost
    return out_theta[0], out_cost + (prob.m * logdet).sum(axis=0)


def _evaluate(
    prob: _Problem,
    theta: np.ndarray,
    delta: np.ndarray,
    var_box: float,
    c2: float,
    params: RobustParams,
    inv_cam_var: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Objective and its pieces at ``theta`` (1 + nc, N) and ``delta`` (3, n_obs, N).

    Returns ``(cost (N,), Z_i (n, N), projections (nc, n, N), residuals (nc, n, N),
    squared normalised residual norms (n, N))``.
    """
    zi = np.maximum(theta[0] - prob.cam[2] - delta[2], params.min_depth)
    iz = 1.0 / zi
    p = np.empty((len(prob.coords),) + zi.shape)
    r = np.empty_like(p)
    s = np.zeros(zi.shape)
    for j, c in enumerate(prob.coords):
        num = theta[1 + j] + prob.k[c]
        if c == 0:
            num = num - prob.a * delta[0]
        elif c == 1:
            num = num - prob.b * delta[1]
        p[j] = num * iz
        r[j] = (prob.g[c] - p[j]) * prob.m
        s += r[j] * r[j]
    s /= var_box
    prior = ((delta * delta).sum(axis=0) * inv_cam_var).sum(axis=0)
    cost = (prob.m * _rho(s, params.loss, c2)).sum(axis=0) + prior
    return cost, zi, p, r, s


def _solve_spd(h: list[list[np.ndarray]], b: list[np.ndarray]) -> list[np.ndarray]:
    """Solve ``h x = b`` for many small symmetric positive definite systems at once.

    ``h[i][j]`` and ``b[i]`` are (N,) arrays (one system per column): a Cholesky
    factorisation written out over the k x k entries, so that each operation runs on
    all N systems. A system that is not positive definite (or not finite) gets x = 0.
    """
    k = len(b)
    low: list[list[np.ndarray]] = [[np.empty(0)] * k for _ in range(k)]
    ok = np.ones(b[0].shape, dtype=bool)
    for j in range(k):
        d = h[j][j] - sum((low[j][m] ** 2 for m in range(j)), np.zeros_like(b[0]))
        good = np.isfinite(d) & (d > 0)
        ok &= good
        ljj = np.sqrt(np.where(good, d, 1.0))
        low[j][j] = ljj
        for i in range(j + 1, k):
            acc = h[i][j] - sum((low[i][m] * low[j][m] for m in range(j)), np.zeros_like(b[0]))
            low[i][j] = acc / ljj
    y: list[np.ndarray] = []
    for i in range(k):
        y.append((b[i] - sum((low[i][m] * y[m] for m in range(i)), np.zeros_like(b[0]))) / low[i][i])
    x: list[np.ndarray] = [np.empty(0)] * k
    for i in reversed(range(k)):
        x[i] = (y[i] - sum((low[m][i] * x[m] for m in range(i + 1, k)), np.zeros_like(b[0]))) / low[i][i]
    return [np.where(ok & np.isfinite(xi), xi, 0.0) for xi in x]
