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

Error bars: :func:`predict_spread` (:mod:`~odmd_bench_baselines.robust.spread`) gives
each estimate's spread, the posterior standard deviation of ``log Z`` from the box
sizes, which ``odmd-bench baseline robust --interval 0.9`` turns into intervals
calibrated on val (:mod:`odmd_bench.predict.intervals`).

Hyperparameters (:data:`DEFAULT_PARAMS`) were chosen on the ``val`` sets only by
``python -m odmd_bench_baselines.robust_search`` (see that module for the grid and the command).
"""

from __future__ import annotations

from odmd_bench_baselines.robust import model
from odmd_bench_baselines.robust.method import OPTIONS, predict, predict_details, predict_report
from odmd_bench_baselines.robust.model import (
    CHUNK,
    DEFAULT_PARAMS,
    LOSSES,
    MISSING,
    MODES,
    Intrinsics,
    Missing,
    Mode,
    NoiseModel,
    RobustParams,
)
from odmd_bench_baselines.robust.scale import fit_scale
from odmd_bench_baselines.robust.solver import fit
from odmd_bench_baselines.robust.spread import predict_spread

__all__ = [
    "OPTIONS",
    "CHUNK",
    "DEFAULT_PARAMS",
    "LOSSES",
    "MISSING",
    "MODES",
    "Intrinsics",
    "Missing",
    "Mode",
    "NoiseModel",
    "RobustParams",
    "fit",
    "fit_scale",
    "model",
    "predict",
    "predict_details",
    "predict_report",
    "predict_spread",
]
