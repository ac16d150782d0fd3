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
_DEBUG = False
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
    enough = usable.sum(axis=1) >= 2
    prob = _Problem.build(boxes, usable, camera, cam_model, params)
    z0 = _linear_start(prob, params)
    depth = z0
    failed = np.zeros(n, dtype=bool)
    if params.iterations > 0:
        z, cost_end, cost_start = _gauss_newton(prob, z0, params)
        ok = np.isfinite(z) & (z >= prob.z_low - 1e-12) & np.isfinite(cost_end) & (cost_end <= cost_start)
        failed = enough & ~ok
        depth = np.where(ok, z, z0)
    depth = np.where(enough, depth, 0.0)
    counts = {
        "fit_failed": int(failed.sum()),
        "too_few_detections": int((~enough).sum()),
        "n": int(n),
    }
    return depth, counts


@dataclass(frozen=True)
class _Problem:
    """The arrays of a fit, one (N, n_obs) array per box coordinate in use.

    ``g[c]`` is coordinate ``c`` centred on the principal point (``x - u0``, ``y - v0``,
    ``w``, ``h``), zero where unused; ``k[c]`` the offset the camera's lateral motion
    adds (``-a C_X`` for x, ``-b C_Y`` for y, 0 for sizes); ``beta[c]`` the box-noise
    variance; ``dcam[c]`` the scale of the lateral camera-noise term (``a^2``, ``b^2``,
    0, 0). ``coords`` lists the coordinates in use (all four, or ``w, h``).
    """

    coords: tuple[int, ...]
    g: tuple[np.ndarray, ...]
    k: tuple[np.ndarray, ...]
    beta: tuple[np.ndarray, ...]
    dcam: tuple[float, ...]
    m: np.ndarray
    cam: np.ndarray
    z_low: np.ndarray
    a: float
    b: float

    @classmethod
    def build(
        cls,
        boxes: np.ndarray,
        usable: np.ndarray,
        camera: np.ndarray,
        cam_model: tuple[float, float, float, float] | None,
        params: RobustParams,
    ) -> _Problem:
        a, b, u0, v0 = cam_model if cam_model is not None else (0.0, 0.0, 0.0, 0.0)
        coords = (0, 1, 2, 3) if cam_model is not None else (2, 3)
        centre = (u0, v0, 0.0, 0.0)
        g = tuple(np.where(usable, boxes[:, :, c] - centre[c], 0.0) for c in range(4))
        zero = np.zeros(usable.shape)
        k = (-a * camera[:, :, 0], -b * camera[:, :, 1], zero, zero)
        sizes = (g[2], g[3], g[2], g[3])
        beta = tuple(params.sigma_box**2 + (params.rel_box * sizes[c]) ** 2 for c in range(4))
        cam = np.moveaxis(camera, 2, 0).copy()  # (3, N, n)
        z_low = np.max(np.where(usable, cam[2], -np.inf), axis=1) + params.min_depth
        z_low = np.where(np.isfinite(z_low), z_low, params.min_depth)
        return cls(coords, g, k, beta, (a * a, b * b, 0.0, 0.0), usable.astype(np.float64), cam, z_low, a, b)

    def take(self, idx: np.ndarray) -> _Problem:
        """The problem restricted to the examples ``idx``."""
        return _Problem(
            self.coords,
            tuple(x[idx] for x in self.g),
            tuple(x[idx] for x in self.k),
            tuple(x[idx] for x in self.beta),
            self.dcam,
            self.m[idx],
            self.cam[:, idx],
            self.z_low[idx],
            self.a,
            self.b,
        )


def _weights(s: np.ndarray, loss: str, scale: float) -> np.ndarray:
    """IRLS weights ``rho'(s)`` for squared Mahalanobis distances ``s`` (any shape)."""
    u = s / scale**2
    if loss == "cauchy":
        return 1.0 / (1.0 + u)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + u)
    if loss == "huber":
        return np.minimum(1.0, 1.0 / np.sqrt(np.maximum(u, 1e-300)))
    return np.ones_like(s)


def _rho(s: np.ndarray, loss: str, scale: float) -> np.ndarray:
    """The robust loss of squared Mahalanobis distances ``s`` (``rho(s) = s`` near 0)."""
    c2 = scale**2
    u = s / c2
    if loss == "cauchy":
        return c2 * np.log1p(u)
    if loss == "soft_l1":
        return 2.0 * c2 * (np.sqrt(1.0 + u) - 1.0)
    if loss == "huber":
        return np.where(u <= 1.0, s, c2 * (2.0 * np.sqrt(u) - 1.0))
    return s


def _linear_start(prob: _Problem, params: RobustParams) -> np.ndarray:
    """Depth from the linearised equations ``g_ic (Z - C_Zi) = t_c + k_ic``, robustly reweighted.

    For per-observation weights ``v_i``, eliminating the offsets ``t_c`` leaves
    ``Z = sum v (g - g_bar)(d - d_bar) / sum v (g - g_bar)^2`` with ``d = g C_Z + k``
    (sums over observations and coordinates). Then Cauchy weights of each
    observation's residual (in image units, against the example's median residual)
    and again. Returns (N,) depths, at least ``z_low``.
    """
    cz = prob.cam[2]
    v = prob.m
    z = prob.z_low
    d = {c: prob.g[c] * cz + prob.k[c] for c in prob.coords}
    for it in range(params.linear_iterations + 1):
        vs = np.maximum(v.sum(axis=1, keepdims=True), 1e-300)
        num = np.zeros(v.shape[0])
        den = np.zeros(v.shape[0])
        gc, dc = {}, {}
        for c in prob.coords:
            gc[c] = prob.g[c] - (v * prob.g[c]).sum(axis=1, keepdims=True) / vs
            dc[c] = d[c] - (v * d[c]).sum(axis=1, keepdims=True) / vs
            num += (v * gc[c] * dc[c]).sum(axis=1)
            den += (v * gc[c] * gc[c]).sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            z_new = num / den
        z = np.where(np.isfinite(z_new), np.maximum(z_new, prob.z_low), prob.z_low)
        if it == params.linear_iterations:
            break
        zi = np.maximum(z[:, None] - cz, params.min_depth)
        r2 = sum(((gc[c] * z[:, None] - dc[c]) / zi) ** 2 for c in prob.coords)
        assert isinstance(r2, np.ndarray)
        scale2 = np.maximum(_masked_median(r2, prob.m > 0), len(prob.coords) * params.sigma_box**2)
        v = prob.m * _weights(r2 / scale2[:, None], "cauchy", params.loss_scale)
    return z


def _masked_median(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Median of ``x`` (N, n) over ``mask`` per row (0 where the mask is empty)."""
    filled = np.where(mask, x, np.inf)
    cnt = mask.sum(axis=1)
    srt = np.sort(filled, axis=1)
    lo = np.take_along_axis(srt, np.maximum((cnt - 1) // 2, 0)[:, None], axis=1)[:, 0]
    hi = np.take_along_axis(srt, np.maximum(cnt // 2, 0)[:, None], axis=1)[:, 0]
    return np.where(cnt > 0, 0.5 * (lo + hi), 0.0)


def _offsets(prob: _Problem, z: np.ndarray) -> np.ndarray:
    """(len(coords), N) offsets ``t_c`` that best fit ``g_ic Z_i = t_c + k_ic`` for depths ``z``."""
    zi = z[:, None] - prob.cam[2]
    msum = np.maximum(prob.m.sum(axis=1), 1.0)
    return np.stack([(prob.m * (prob.g[c] * zi - prob.k[c])).sum(axis=1) / msum for c in prob.coords])


def _gauss_newton(
    prob: _Problem, z0: np.ndarray, params: RobustParams
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robust Levenberg-Marquardt on the reprojection residuals, all examples at once.

    Unknowns per example: ``Z``, the offsets ``t_c`` of the coordinates in use
    (``X', Y', s_w, s_h``) and camera corrections ``delta`` (3, n_obs) with the prior
    ``N(0, sigma_camera^2)`` (none at the last observation, which is zero by
    definition). Objective: ``sum_i m_i rho(r_i^T B_i^-1 r_i) + |delta|^2 /
    sigma_camera^2``, with ``B_i`` the box-noise variances and ``r_i`` the residuals at
    the corrected camera positions. Each step solves the joint Gauss-Newton system
    with ``delta`` eliminated in closed form: the Schur complement is a small system in
    ``(Z, t)`` whose per-observation covariance ``B_i / w_i + J_delta P J_delta^T``
    (``w_i`` the IRLS weight) is a diagonal plus a rank-one term, inverted by
    Sherman-Morrison; ``delta`` follows from the step. Damping acts on ``(Z, t)``; a
    step is kept only where it lowers the objective; examples leave the loop once
    their steps vanish.

    Returns ``(depth (N,), final objective (N,), starting objective (N,))``.
    """
    n, n_obs = prob.m.shape
    cs = prob.coords
    nc = len(cs)
    cam_var = np.full(n_obs, params.sigma_camera**2)
    cam_var[-1] = 0.0
    inv_cam_var = np.divide(1.0, cam_var, out=np.zeros(n_obs), where=cam_var > 0)

    theta = np.concatenate([z0[None], _offsets(prob, z0)])  # (1 + nc, N)
    delta = np.zeros((3, n, n_obs))
    out_theta = theta.copy()
    pr = prob
    state = _evaluate(pr, theta, delta, params, inv_cam_var)
    cost_start = state[0].copy()
    out_cost = cost_start.copy()
    ids = np.arange(n)
    lam = np.full(n, 1e-4)
    diag = np.eye(1 + nc, dtype=bool)
    for _ in range(params.iterations):
        cost, zi, p, r, s = state
        om = np.maximum(pr.m * _weights(s, params.loss, params.loss_scale), 1e-12)
        iz = 1.0 / zi
        iz2 = iz * iz
        q = cam_var * iz2
        mdiag = [pr.beta[c] / om + q * pr.dcam[c] for c in cs]
        u = [p[j] / mdiag[j] for j in range(nc)]
        pu_u = sum(p[j] * u[j] for j in range(nc))
        kappa = q / (1.0 + q * pu_u)
        one_k = 1.0 - kappa * pu_u
        # Residual with the current corrections undone (linearised): r + J_delta delta.
        dz = delta[2] * iz
        rt = []
        for j, c in enumerate(cs):
            extra = p[j] * dz
            if c == 0:
                extra = extra - prob.a * delta[0] * iz
            elif c == 1:
                extra = extra - prob.b * delta[1] * iz
            rt.append(r[j] + extra)
        ru = sum(rt[j] * u[j] for j in range(nc))
        sr = [rt[j] / mdiag[j] - kappa * ru * u[j] for j in range(nc)]
        psr = sum(p[j] * sr[j] for j in range(nc))
        # Normal equations with J_theta = (1/Z_i)[-p, I].
        h = np.empty((len(ids), 1 + nc, 1 + nc))
        grad = np.empty((len(ids), 1 + nc))
        h[:, 0, 0] = (iz2 * pu_u * one_k).sum(axis=1)
        grad[:, 0] = -(iz * psr).sum(axis=1)
        kz = iz2 * kappa
        for j in range(nc):
            h[:, 0, 1 + j] = h[:, 1 + j, 0] = -(iz2 * u[j] * one_k).sum(axis=1)
            grad[:, 1 + j] = (iz * sr[j]).sum(axis=1)
            h[:, 1 + j, 1 + j] = (iz2 / mdiag[j] - kz * u[j] * u[j]).sum(axis=1)
            for l in range(j + 1, nc):
                h[:, 1 + j, 1 + l] = h[:, 1 + l, 1 + j] = -(kz * u[j] * u[l]).sum(axis=1)
        damped = h + (lam[:, None] * (h[:, diag] + 1e-12))[:, :, None] * np.eye(1 + nc)
        step = _solve(damped, grad).T  # (1 + nc, Na)
        # New corrections: eps = P J_delta^T Sigma^-1 (r~ - J_theta step).
        v = [rt[j] - (step[1 + j][:, None] - p[j] * step[0][:, None]) * iz for j in range(nc)]
        vu = sum(v[j] * u[j] for j in range(nc))
        sv = [v[j] / mdiag[j] - kappa * vu * u[j] for j in range(nc)]
        fac = cam_var * iz
        new_delta = np.zeros_like(delta)
        new_delta[2] = fac * sum(p[j] * sv[j] for j in range(nc))
        if cs[0] == 0:
            new_delta[0] = -prob.a * fac * sv[0]
            new_delta[1] = -prob.b * fac * sv[1]
        new = theta + step
        z_floor = np.max(np.where(pr.m > 0, pr.cam[2] + new_delta[2], -np.inf), axis=1) + params.min_depth
        new[0] = np.maximum(new[0], np.maximum(pr.z_low, z_floor))
        new_state = _evaluate(pr, new, new_delta, params, inv_cam_var)
        better = np.isfinite(new_state[0]) & (new_state[0] <= cost)
        theta = np.where(better, new, theta)
        delta = np.where(better[:, None], new_delta, delta)
        state = tuple(np.where(better if x.ndim == 1 else better[..., None], y, x) for x, y in zip(state, new_state, strict=True))
        lam = np.where(better, np.maximum(lam * 0.3, 1e-9), lam * 10.0)
        tiny = np.abs(step).max(axis=0) <= 1e-10 * (1.0 + np.abs(theta).max(axis=0))
        done = tiny | (lam > 1e6)
        out_theta[:, ids] = theta
        out_cost[ids] = state[0]
        if done.all():
            break
        if _DEBUG:
            print(len(ids), int(done.sum()), int(better.sum()))
        if done.mean() > 0.25:
            keep = ~done
            ids = ids[keep]
            pr = pr.take(keep)
            theta, delta, lam = theta[:, keep], delta[:, keep], lam[keep]
            state = tuple(x[:, keep] if x.ndim == 3 else x[keep] for x in state)
    return out_theta[0], out_cost, cost_start


def _evaluate(
    prob: _Problem, theta: np.ndarray, delta: np.ndarray, params: RobustParams, inv_cam_var: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Objective and its pieces at ``theta`` (1 + nc, N) and ``delta`` (3, N, n_obs).

    Returns ``(cost (N,), Z_i (N, n), predictions (nc, N, n), residuals (nc, N, n),
    squared box-noise Mahalanobis distances (N, n))``.
    """
    zi = np.maximum(theta[0][:, None] - prob.cam[2] - delta[2], params.min_depth)
    iz = 1.0 / zi
    p = np.empty((len(prob.coords),) + zi.shape)
    r = np.empty_like(p)
    s = np.zeros(zi.shape)
    for j, c in enumerate(prob.coords):
        num = theta[1 + j][:, None] + prob.k[c]
        if c == 0:
            num = num - prob.a * delta[0]
        elif c == 1:
            num = num - prob.b * delta[1]
        p[j] = num * iz
        r[j] = (prob.g[c] - p[j]) * prob.m
        s += r[j] * r[j] / prob.beta[c]
    prior = ((delta * delta).sum(axis=0) * inv_cam_var).sum(axis=1)
    cost = (prob.m * _rho(s, params.loss, params.loss_scale)).sum(axis=1) + prior
    return cost, zi, p, r, s


def _solve(h: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Solve the stacked systems ``h x = grad`` (N, k, k) (N, k); a singular one gives a zero step."""
    ok = np.isfinite(h).all(axis=(1, 2)) & np.isfinite(grad).all(axis=1)
    hh = np.where(ok[:, None, None], h, np.eye(h.shape[1]))
    gg = np.where(ok[:, None], grad, 0.0)
    try:
        x = np.linalg.solve(hh, gg[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        x = np.zeros_like(gg)
        for i in np.flatnonzero(ok):  # only when some matrix is exactly singular: rare
            try:
                x[i] = np.linalg.solve(hh[i], gg[i])
            except np.linalg.LinAlgError:
                x[i] = 0.0
    return np.where(np.isfinite(x), x, 0.0)
