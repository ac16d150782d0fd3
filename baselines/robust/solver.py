"""The full fit: linear start, robust Gauss-Newton, the noise model per example.

See steps 1 to 5 of the package docstring.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from odmd_bench_baselines.robust import model
from odmd_bench_baselines.robust.model import DEFAULT_PARAMS, NoiseModel, RobustParams


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
    if n > model.CHUNK:
        return model.chunked(lambda sl: fit(boxes[sl], usable[sl], camera[sl], cam_model, params), n)
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
