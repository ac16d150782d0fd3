"""Robust reprojection: a training-free, CALIBRATED depth estimator (name ``robust``).

Unlike Box_LS and DBox, which never use the camera intrinsics, this method NEEDS them
(``fx, fy, cx, cy`` and the image size, from the set's attributes or given
explicitly): it fits the pinhole model of the paper (section 3.1 and the
supplementary "Depth from Motion Parallax") to every box coordinate at once, so that
optical expansion (``w, h``) and motion parallax (``x, y``) both inform the depth.

Model, per example, in normalised image units (``a = fx / W_I``, ``b = fy / H_I``,
``u0 = cx / W_I``, ``v0 = cy / H_I``). Unknowns ``theta = (Z, X', Y', s_w, s_h)``: the
depth ``Z = Z_n`` at the last observation, the object's lateral position at the last
observation scaled to image units (``X' = a X_n``, ``Y' = b Y_n``) and its size in
image units at unit depth (``s_w = a W``, ``s_h = b H``). With the camera position
``C_i`` relative to the last observation (the data's convention, checked on the
original files: ``Z_i + C_Zi = Z_n`` and ``X_i = X_n - C_Xi``)::

    Z_i = Z - C_Zi
    x_i = u0 + (X' - a C_Xi) / Z_i      y_i = v0 + (Y' - b C_Yi) / Z_i
    w_i = s_w / Z_i                     h_i = s_h / Z_i

Estimation:

1. Linear start. Multiplying each equation by ``Z_i`` gives equations linear in
   ``theta`` (Box_LS's expansion rows plus the parallax rows
   ``(x_i - u0) Z - X' = (x_i - u0) C_Zi - a C_Xi``). The four offsets
   ``X', Y', s_w, s_h`` are eliminated in closed form, which leaves one weighted
   least-squares ratio for ``Z``; a few iteratively reweighted rounds (Cauchy
   weights per observation) make it robust to a wrong box.
2. Robust Gauss-Newton (IRLS) on the reprojection residuals ``r_i`` (4 per detected
   observation). The camera-position errors are nuisance parameters with a Gaussian
   prior ``N(0, sigma_camera^2)`` per axis at every observation but the last (whose
   position is zero by definition); they are marginalised in closed form (the
   Schur complement of their block is a per-observation covariance
   ``Sigma_i = B_i + J_C,i sigma_camera^2 J_C,i^T``, box noise ``B_i`` diagonal with
   ``sigma_box^2 + (rel_box * size)^2``). Each observation gets the weight of a
   robust loss (Cauchy, Huber or soft-L1, scale ``loss_scale``) of its Mahalanobis
   distance ``r_i^T Sigma_i^-1 r_i``: a wrong detection corrupts all four numbers of
   one observation, so observations, not coordinates, are down-weighted.
   The 5 x 5 normal equations of all examples are solved at once
   (``np.linalg.solve`` on stacked matrices) with Levenberg-Marquardt damping and a
   vectorised accept/reject of each step; there is no Python loop over examples.
3. Bounds: ``Z`` stays above ``max_i C_Zi + min_depth`` (the object in front of the
   camera at every used observation) and the sizes positive.
4. Fallbacks, counted in :func:`predict_report`: if the fit does not give a finite
   depth inside the bound, or ends with a larger robust cost than its start, the
   linear start is returned (``fit_failed``); an example with fewer than two usable
   observations gets depth 0, as Box_LS does (``too_few_detections``).

Missing detections (``detected`` False) are left out of the fit (``missing="omit"``,
the default, chosen on val); ``missing="fill"`` applies the package's shared rule
(:func:`odmd_bench.fill_missing`) instead.

Sets without intrinsics (the ODMS-detection sets) raise :class:`~odmd_bench.DataError`
with ``mode="full"`` (the default) unless intrinsics are given (``intrinsics=``).
``mode="scale"`` fits ``w`` and ``h`` only (``Z, s_w, s_h``): it needs no intrinsics,
so it is a robust, nonlinear, uncalibrated counterpart of Box_LS, and it is what this
method does on ODMS-detection (whose camera moves along ``z`` only, so parallax would
carry no information anyway).

Hyperparameters (:data:`DEFAULT_PARAMS`) were chosen on the ``val`` sets only by
``python -m baselines.robust_search`` (see that module).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from odmd_bench import DataError, Examples, UsageError, fill_missing

Mode = Literal["full", "scale"]
Missing = Literal["omit", "fill"]
LOSSES = ("cauchy", "huber", "soft_l1", "linear")
MODES = ("full", "scale")
MISSING = ("omit", "fill")


@dataclass(frozen=True)
class RobustParams:
    """Hyperparameters of the robust fit (chosen on val; see :mod:`baselines.robust_search`).

    Attributes:
        loss: ``"cauchy"``, ``"huber"``, ``"soft_l1"`` or ``"linear"`` (plain least squares).
        loss_scale: scale ``c`` of the loss on the Mahalanobis distance (in standard
            deviations): Cauchy weight ``1 / (1 + d^2 / c^2)``.
        sigma_box: absolute standard deviation of every box coordinate (normalised units).
        rel_box: standard deviation relative to the box size (``w`` for ``x, w``;
            ``h`` for ``y, h``), added in quadrature to ``sigma_box``.
        sigma_camera: prior standard deviation of each camera-position coordinate (m)
            at every observation but the last.
        iterations: Gauss-Newton iterations (fixed count; converged examples stay put).
        linear_iterations: reweighting rounds of the linear start.
        min_depth: the object's smallest allowed depth at any observation (m).
    """

    loss: str = "cauchy"
    loss_scale: float = 3.0
    sigma_box: float = 1e-3
    rel_box: float = 0.0
    sigma_camera: float = 0.01
    iterations: int = 20
    linear_iterations: int = 5
    min_depth: float = 1e-3

    def __post_init__(self) -> None:
        problems = []
        if self.loss not in LOSSES:
            problems.append(f"loss: {self.loss!r} is not one of {', '.join(LOSSES)}")
        for name in ("loss_scale", "sigma_box", "min_depth"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v > 0):
                problems.append(f"{name}: expected a positive number, got {v!r}")
        for name in ("rel_box", "sigma_camera"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v >= 0):
                problems.append(f"{name}: expected a number >= 0, got {v!r}")
        for name in ("iterations", "linear_iterations"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                problems.append(f"{name}: expected an integer >= 0, got {v!r}")
        if problems:
            raise UsageError("invalid robust-method parameters", problems)


#: Chosen on the val sets by ``python -m baselines.robust_search`` (never on test).
DEFAULT_PARAMS = RobustParams()


def predict(
    examples: Examples,
    params: RobustParams = DEFAULT_PARAMS,
    *,
    mode: Mode = "full",
    missing: Missing = "omit",
    intrinsics: tuple[float, float, float, float, float, float] | None = None,
) -> np.ndarray:
    """Depth ``Z_n`` of every example, metres.

    Args:
        examples: the examples; ``mode="full"`` needs their intrinsics (or ``intrinsics``).
        params: hyperparameters.
        mode: ``"full"`` (calibrated: all four box coordinates) or ``"scale"``
            (``w, h`` only; needs no intrinsics).
        missing: ``"omit"`` missing detections or ``"fill"`` them by the shared rule.
        intrinsics: ``(fx, fy, cx, cy, image_width, image_height)`` in pixels, to use
            instead of the set's own.

    Returns:
        (N,) float64 depths.

    Raises:
        DataError: ``mode="full"`` on a set without intrinsics and none given.
    """
    return predict_report(examples, params, mode=mode, missing=missing, intrinsics=intrinsics)[0]


def predict_report(
    examples: Examples,
    params: RobustParams = DEFAULT_PARAMS,
    *,
    mode: Mode = "full",
    missing: Missing = "omit",
    intrinsics: tuple[float, float, float, float, float, float] | None = None,
) -> tuple[np.ndarray, dict[str, int]]:
    """Like :func:`predict`, also returning the counted fallbacks.

    Returns:
        ``(depths (N,), counts)`` with ``counts`` = ``{"fit_failed": k,
        "too_few_detections": m, "n": N}``.
    """
    if mode not in MODES:
        raise UsageError(f"mode {mode!r} is not one of {', '.join(MODES)}")
    if missing not in MISSING:
        raise UsageError(f"missing {missing!r} is not one of {', '.join(MISSING)}")
    if mode == "full":
        if intrinsics is None:
            try:
                intrinsics = examples.intrinsics()
            except DataError as e:
                raise DataError(
                    e.message + "; the robust method is calibrated: give intrinsics=... "
                    "(CLI: --intrinsics) or use mode='scale' (box sizes only, no intrinsics)",
                    e.problems,
                ) from None
        fx, fy, cx, cy, width, height = (float(v) for v in intrinsics)
        if not (fx > 0 and fy > 0 and width > 0 and height > 0):
            raise UsageError(f"intrinsics must have positive fx, fy and image size, got {intrinsics}")
        cam_model: tuple[float, float, float, float] | None = (fx / width, fy / height, cx / width, cy / height)
    else:
        cam_model = None

    boxes = np.asarray(examples.boxes, dtype=np.float64)
    detected = np.asarray(examples.detected, dtype=bool)
    if missing == "fill":
        boxes = fill_missing(boxes, detected)
        use = np.broadcast_to(detected.any(axis=1, keepdims=True), detected.shape)
    else:
        use = detected
    usable = use & np.isfinite(boxes).all(axis=2) & (boxes[:, :, 2] > 0) & (boxes[:, :, 3] > 0)
    return fit(boxes, usable, np.asarray(examples.camera, dtype=np.float64), cam_model, params)


def fit(
    boxes: np.ndarray,
    usable: np.ndarray,
    camera: np.ndarray,
    cam_model: tuple[float, float, float, float] | None,
    params: RobustParams = DEFAULT_PARAMS,
) -> tuple[np.ndarray, dict[str, int]]:
    """The robust fit on arrays (see the module docstring).

    Args:
        boxes: (N, n_obs, 4) normalised ``x, y, w, h``.
        usable: (N, n_obs) bool, observations that enter the fit.
        camera: (N, n_obs, 3) camera positions relative to the last observation, m.
        cam_model: ``(a, b, u0, v0)`` = ``(fx / W_I, fy / H_I, cx / W_I, cy / H_I)``, or
            None to fit ``w, h`` only.
        params: hyperparameters.

    Returns:
        ``(depths (N,), counts)`` as :func:`predict_report`.
    """
    n = boxes.shape[0]
    m = usable.astype(np.float64)
    enough = usable.sum(axis=1) >= 2
    # Coordinates used: all four, or only w, h.
    coord_on = np.array([1.0, 1.0, 1.0, 1.0]) if cam_model is not None else np.array([0.0, 0.0, 1.0, 1.0])
    a, b, u0, v0 = cam_model if cam_model is not None else (0.0, 0.0, 0.0, 0.0)

    # Observations centred on the principal point: g = (x - u0, y - v0, w, h).
    g = boxes - np.array([u0, v0, 0.0, 0.0])
    g = np.where(usable[:, :, None], g, 0.0)
    cz = camera[:, :, 2]
    # Offsets that the camera's lateral motion adds: x-row target X' - a C_X.
    k = np.zeros_like(g)
    k[:, :, 0] = -a * camera[:, :, 0]
    k[:, :, 1] = -b * camera[:, :, 1]

    z_low = np.max(np.where(usable, cz, -np.inf), axis=1) + params.min_depth
    z_low = np.where(enough, z_low, params.min_depth)

    z0 = _linear_start(g, k, cz, m, coord_on, z_low, params)
    theta0 = _offsets_given_z(z0, g, k, cz, m)
    depth = z0.copy()
    failed = np.zeros(n, dtype=bool)
    if params.iterations > 0:
        theta, cost_end, cost_start = _gauss_newton(theta0, g, k, camera, m, coord_on, z_low, (a, b), params)
        z = theta[:, 0]
        ok = np.isfinite(z) & (z >= z_low - 1e-12) & np.isfinite(cost_end) & (cost_end <= cost_start * (1 + 1e-9) + 1e-300)
        failed = enough & ~ok
        depth = np.where(ok, z, z0)
    depth = np.where(enough, depth, 0.0)
    counts = {
        "fit_failed": int(failed.sum()),
        "too_few_detections": int((~enough).sum()),
        "n": int(n),
    }
    return depth, counts


def _offsets_given_z(z: np.ndarray, g: np.ndarray, k: np.ndarray, cz: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``theta = (Z, X', Y', s_w, s_h)`` with the offsets that best fit ``g_i Z_i = t + k_i``.

    Shapes: z (N,), g and k (N, n_obs, 4), cz and m (N, n_obs). Returns (N, 5).
    """
    zi = z[:, None] - cz
    msum = np.maximum(m.sum(axis=1), 1.0)
    t = np.einsum("no,noc->nc", m, g * zi[:, :, None] - k) / msum[:, None]
    return np.concatenate([z[:, None], t], axis=1)


def _weights(s: np.ndarray, loss: str, scale: float) -> np.ndarray:
    """IRLS weights for squared Mahalanobis distances ``s`` (any shape)."""
    u = s / scale**2
    if loss == "cauchy":
        return 1.0 / (1.0 + u)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + u)
    if loss == "huber":
        return np.minimum(1.0, 1.0 / np.sqrt(np.maximum(u, 1e-300)))
    return np.ones_like(s)


def _rho(s: np.ndarray, loss: str, scale: float) -> np.ndarray:
    """The robust loss of squared Mahalanobis distances ``s`` (its derivative / 1 is :func:`_weights`)."""
    c2 = scale**2
    u = s / c2
    if loss == "cauchy":
        return c2 * np.log1p(u)
    if loss == "soft_l1":
        return 2.0 * c2 * (np.sqrt(1.0 + u) - 1.0)
    if loss == "huber":
        r = np.sqrt(u)
        return np.where(u <= 1.0, s, c2 * (2.0 * r - 1.0))
    return s


def _linear_start(
    g: np.ndarray,
    k: np.ndarray,
    cz: np.ndarray,
    m: np.ndarray,
    coord_on: np.ndarray,
    z_low: np.ndarray,
    params: RobustParams,
) -> np.ndarray:
    """Depth from the linearised equations ``g_ic (Z - C_Zi) = t_c + k_ic``, robustly reweighted.

    For fixed per-observation weights ``v_i``, eliminating the offsets ``t_c`` leaves
    ``Z = sum v (g - g_bar)(d - d_bar) / sum v (g - g_bar)^2`` with ``d = g C_Z + k``
    (sums over observations and coordinates). Returns (N,) depths clipped to ``z_low``.
    """
    d = g * cz[:, :, None] + k
    v = m.copy()
    z = z_low
    for it in range(params.linear_iterations + 1):
        vs = np.maximum(v.sum(axis=1, keepdims=True), 1e-300)
        gbar = np.einsum("no,noc->nc", v, g)[:, None, :] / vs[:, :, None]
        dbar = np.einsum("no,noc->nc", v, d)[:, None, :] / vs[:, :, None]
        gc = (g - gbar) * coord_on
        dc = d - dbar
        num = np.einsum("no,noc,noc->n", v, gc, dc)
        den = np.einsum("no,noc,noc->n", v, gc, gc)
        with np.errstate(divide="ignore", invalid="ignore"):
            z_new = num / den
        z = np.where(np.isfinite(z_new), np.maximum(z_new, z_low), z_low)
        if it == params.linear_iterations:
            break
        # Residuals in image units: divide the linear residual by Z_i.
        zi = np.maximum(z[:, None] - cz, params.min_depth)
        res = (gc * z[:, None, None] - dc) / zi[:, :, None] * coord_on
        # Scale per example: median absolute residual of the used coordinates.
        r2 = (res**2).sum(axis=2)
        sig = np.sqrt(_masked_median(r2, m > 0) / max(coord_on.sum(), 1.0))
        sig = np.maximum(sig, params.sigma_box)
        v = m * _weights(r2 / (sig[:, None] ** 2 * coord_on.sum()), "cauchy", params.loss_scale)
    return z


def _masked_median(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Median of ``x`` (N, n) over ``mask`` per row (0 where the mask is empty)."""
    filled = np.where(mask, x, np.nan)
    with np.errstate(all="ignore"):
        cnt = mask.sum(axis=1)
        srt = np.sort(filled, axis=1)  # NaNs last
        lo = np.take_along_axis(srt, np.maximum((cnt - 1) // 2, 0)[:, None], axis=1)[:, 0]
        hi = np.take_along_axis(srt, np.maximum(cnt // 2, 0)[:, None], axis=1)[:, 0]
    med = 0.5 * (lo + hi)
    return np.where(cnt > 0, med, 0.0)


def _gauss_newton(
    theta: np.ndarray,
    g: np.ndarray,
    k: np.ndarray,
    camera: np.ndarray,
    m: np.ndarray,
    coord_on: np.ndarray,
    z_low: np.ndarray,
    ab: tuple[float, float],
    params: RobustParams,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robust Levenberg-Marquardt on the reprojection residuals, all examples at once.

    Unknowns: ``theta`` (N, 5) and camera corrections ``delta`` (N, n_obs, 3) with the
    prior ``N(0, sigma_camera^2)`` (zero variance at the last observation). Objective
    per example: ``sum_i m_i rho(r_i^T B_i^-1 r_i) + |delta|^2 / sigma_camera^2``, with
    ``B_i`` the box-noise variances. Each step solves the joint Gauss-Newton system
    with ``delta`` eliminated in closed form (Schur complement: a 5 x 5 system whose
    per-observation covariance ``B_i / w_i + J_delta P J_delta^T`` is inverted by
    Sherman-Morrison), then recovers ``delta``. Damping acts on ``theta``; a step is
    kept only where it lowers the objective.

    Returns ``(theta (N, 5), final cost (N,), starting cost (N,))``.
    """
    a, b = ab
    n_obs = camera.shape[1]
    cam_var = np.full(n_obs, params.sigma_camera**2)
    cam_var[-1] = 0.0  # the last position is zero by definition
    inv_cam_var = np.where(cam_var > 0, 1.0 / np.where(cam_var > 0, cam_var, 1.0), 0.0)
    dcam = np.array([a * a, b * b, 0.0, 0.0])
    ident = np.eye(5)
    # Box-noise variances from the observed sizes (constant, so the objective is fixed).
    size = np.abs(g[:, :, [2, 3, 2, 3]])
    beta = params.sigma_box**2 + (params.rel_box * size) ** 2  # (N, n, 4)

    def predict_at(th: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        zi = np.maximum(th[:, :1] - camera[:, :, 2] - dl[:, :, 2], params.min_depth)
        kk = k.copy()
        kk[:, :, 0] -= a * dl[:, :, 0]
        kk[:, :, 1] -= b * dl[:, :, 1]
        p = (th[:, None, 1:] + kk) / zi[:, :, None]
        return zi, p

    def objective(th: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, ...]:
        zi, p = predict_at(th, dl)
        r = (g - p) * coord_on
        s = (r * r / beta).sum(axis=2)
        prior = ((dl * dl).sum(axis=2) * inv_cam_var).sum(axis=1)
        cost = (m * _rho(s, params.loss, params.loss_scale)).sum(axis=1) + prior
        return cost, zi, p, r, s

    delta = np.zeros(camera.shape)
    cost, zi, p, r, s = objective(theta, delta)
    cost_start = cost.copy()
    lam = np.full(theta.shape[0], 1e-4)
    for _ in range(params.iterations):
        om = np.maximum(m * _weights(s, params.loss, params.loss_scale), 1e-12)  # (N, n)
        q = cam_var / zi**2  # (N, n)
        mdiag = beta / om[:, :, None] + q[:, :, None] * dcam  # (N, n, 4)
        pu = p * coord_on
        # Residual with the current corrections undone (linearised): r + J_delta delta.
        jd = np.empty_like(r)
        jd[:, :, 0] = -a * delta[:, :, 0] + p[:, :, 0] * delta[:, :, 2]
        jd[:, :, 1] = -b * delta[:, :, 1] + p[:, :, 1] * delta[:, :, 2]
        jd[:, :, 2] = p[:, :, 2] * delta[:, :, 2]
        jd[:, :, 3] = p[:, :, 3] * delta[:, :, 2]
        rt = r + jd / zi[:, :, None] * coord_on
        # Sigma^-1 = diag(1/mdiag) - kappa u u^T, u = p / mdiag (Sherman-Morrison).
        u = pu / mdiag
        pu_u = (pu * u).sum(axis=2)
        kappa = q / (1.0 + q * pu_u)
        one_k = 1.0 - kappa * pu_u
        ru = (rt * u).sum(axis=2)
        sr = rt / mdiag * coord_on - (kappa * ru)[:, :, None] * u  # Sigma^-1 r~
        psr = (pu * sr).sum(axis=2)
        sp = u * one_k[:, :, None]  # Sigma^-1 p
        psp = pu_u * one_k
        iz2 = 1.0 / zi**2
        iz = 1.0 / zi
        # J_theta = (1/Z_i)[-p, I4].
        h = np.empty(theta.shape[:1] + (5, 5))
        h[:, 0, 0] = (iz2 * psp).sum(axis=1)
        h[:, 0, 1:] = -np.einsum("no,noc->nc", iz2, sp)
        h[:, 1:, 0] = h[:, 0, 1:]
        h[:, 1:, 1:] = np.einsum("no,noc,cd->ncd", iz2, coord_on / mdiag, np.eye(4)) - np.einsum(
            "no,noc,nod->ncd", iz2 * kappa, u, u
        )
        h[:, 1:, 1:] += np.diag(1.0 - coord_on)  # unused coordinates: pin X', Y'
        grad = np.empty(theta.shape[:1] + (5,))
        grad[:, 0] = -(iz * psr).sum(axis=1)
        grad[:, 1:] = np.einsum("no,noc->nc", iz, sr)
        damped = h + lam[:, None, None] * (h * ident + 1e-12 * ident)
        step = _solve(damped, grad)
        # New corrections: eps = P J_delta^T Sigma^-1 (r~ - J_theta step).
        jstep = (-(p * step[:, None, :1]) + step[:, None, 1:]) * iz[:, :, None] * coord_on
        v = rt - jstep
        vu = (v * u).sum(axis=2)
        sv = v / mdiag * coord_on - (kappa * vu)[:, :, None] * u
        pz = (p * sv * coord_on).sum(axis=2)
        new_delta = np.empty_like(delta)
        new_delta[:, :, 0] = -a * sv[:, :, 0]
        new_delta[:, :, 1] = -b * sv[:, :, 1]
        new_delta[:, :, 2] = pz
        new_delta *= (cam_var * iz)[:, :, None]
        new = theta + step
        zl = np.maximum(z_low, np.max(np.where(m > 0, camera[:, :, 2] + new_delta[:, :, 2], -np.inf), axis=1) + params.min_depth)
        new[:, 0] = np.maximum(new[:, 0], zl)
        new_cost, nzi, np_, nr, ns = objective(new, new_delta)
        better = np.isfinite(new_cost) & (new_cost <= cost)
        theta = np.where(better[:, None], new, theta)
        delta = np.where(better[:, None, None], new_delta, delta)
        cost = np.where(better, new_cost, cost)
        lam = np.where(better, np.maximum(lam * 0.3, 1e-9), lam * 10.0)
        b2 = better[:, None]
        zi = np.where(b2, nzi, zi)
        s = np.where(b2, ns, s)
        p = np.where(b2[:, :, None], np_, p)
        r = np.where(b2[:, :, None], nr, r)
    return theta, cost, cost_start


def _solve(h: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Solve the stacked systems ``h x = grad``; singular ones give a zero step."""
    ok = np.isfinite(h).all(axis=(1, 2)) & np.isfinite(grad).all(axis=1)
    hh = np.where(ok[:, None, None], h, np.eye(h.shape[1]))
    gg = np.where(ok[:, None], grad, 0.0)
    try:
        x = np.linalg.solve(hh, gg[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        x = np.zeros_like(gg)
        for i in np.flatnonzero(ok):  # rare: only when some matrix is exactly singular
            try:
                x[i] = np.linalg.solve(hh[i], gg[i])
            except np.linalg.LinAlgError:
                x[i] = 0.0
    return np.where(np.isfinite(x), x, 0.0)
