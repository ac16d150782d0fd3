"""Box_LS: the paper's n-observation least-squares depth from optical expansion.

For every observation ``k`` of an example the pinhole box model gives one width and one
height equation (paper, equation ``axb``, with ``i = n`` the last observation)::

    w_k Z + a = w_k d_k        h_k Z + b = h_k d_k        d_k = C_Zk - C_Zn

with unknowns ``Z`` (the depth at the last observation), ``a = -fx W`` and
``b = -fy H``. The least-squares solution eliminates ``a`` and ``b`` in closed form
(each is the mean residual of its own rows), which leaves, with box sizes centred per
example (``w'_k = w_k - mean(w)``, likewise ``h'``)::

    Z = sum_k (w'_k w_k d_k + h'_k h_k d_k) / sum_k (w'_k^2 + h'_k^2)

This is the exact least-squares solution of the paper's ``A x = b`` (the normal
equations after block elimination), computed for all examples at once (vectorised, in
cache-sized blocks, no loop over examples) with centred sums, which avoids the
cancellation of the raw normal equations. It agrees with a per-example
:func:`numpy.linalg.lstsq` solve to about 1e-12 relative, and solves several million
examples per second on one core (``benchmarks/bench_box_ls.py``).

Missing detections: a missing box is replaced by the box of the nearest observation
that has one, the earlier on a tie (:func:`odmd_bench.fill_missing` over all
observations), as in the paper.

Fallbacks (each example counted once, in this order of precedence; the depth given is
``fallback_depth``, 0 by default, which is how the paper's published numbers score these
examples: four robot test examples have one detection only, and with 0 they give the
published 21.23):

``no_detection``
    No observation has a detection: there is nothing to solve.
``single_detection``
    Exactly one observation has a detection: it is copied to every observation, the
    box size is constant and ``A`` is rank deficient.
``no_z_motion``
    The camera has the same ``z`` at every observation: depth is not observable from
    optical expansion (with exact boxes the system is singular; with noisy boxes the
    least-squares answer would be a meaningless 0).
``rank_deficient``
    Several detections but box widths and heights constant to rounding
    (``sum w'^2 + h'^2 <= (2 n eps)^2 sum w^2 + h^2``): ``A`` is singular.
``non_finite``
    The solution is not finite (non-finite numbers in the inputs).

Error bars: ``predict_spread`` is the box-size posterior's spread of
:mod:`odmd_bench_baselines.robust.spread` (the information Box_LS uses: box sizes and
camera ``z``), which ``odmd-bench baseline box-ls --interval 0.9`` turns into intervals
calibrated on val (:mod:`odmd_bench.predict.intervals`).

The output never holds NaN or infinity. Negative depths are legal least-squares answers
on noisy data and are returned as they are (the paper's numbers include them).
"""

from __future__ import annotations

import numpy as np
from odmd_bench_baselines.robust.spread import box_ls_spread

import odmd_bench

#: The optional third function of a method (:mod:`odmd_bench.methods`): each estimate's spread.
predict_spread = box_ls_spread

#: Depth (metres) given to examples whose system cannot be solved, as the paper scores them.
DEFAULT_FALLBACK_DEPTH = 0.0

#: The method reads depth from the boxes' growth as the camera moves along its optical axis:
#: ``odmd-bench predict`` gives no depth where it moved too little (``odmd_bench.predict``).
NEEDS_FORWARD_MOTION = True

#: Fallback reasons, in order of precedence.
FALLBACKS: tuple[str, ...] = (
    "no_detection",
    "single_detection",
    "no_z_motion",
    "rank_deficient",
    "non_finite",
)


#: Examples solved per block: small enough for the temporaries to stay in cache.
_BLOCK = 1024


def solve(width: np.ndarray, height: np.ndarray, camera_z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares depth at the last observation from box sizes and camera ``z``.

    No missing-detection handling: every observation must hold a box (see
    :func:`predict_report`). Inputs may be strided views (``boxes[:, :, 2]``); they are
    copied block by block, so memory stays bounded and the temporaries stay in cache.

    With ``w'`` the centred widths (``w - mean(w)``, likewise ``h'``) and
    ``u = w' w + h' h``, ``Z = sum(u C_Z) / sum(w'^2 + h'^2) - C_Zn``, using
    ``sum(u) = sum(w'^2 + h'^2)`` so that the camera positions need no shift.

    Args:
        width: (N, n_obs) box width per observation (normalised; any common unit works).
        height: (N, n_obs) box height per observation, in the same unit.
        camera_z: (N, n_obs) camera ``z`` position per observation, metres; only
            differences to the last observation matter.

    Returns:
        ``(depth, singular)``: ``depth`` (N,) is the least-squares ``Z_n``, undefined
        (any value, possibly NaN) where ``singular`` is True; ``singular`` (N,) bool is
        True where the box sizes are constant to rounding, so that ``A`` is rank
        deficient: ``sum(w'^2 + h'^2) <= (2 n_obs eps)^2 sum(w^2 + h^2)``.

    Example:
        >>> import numpy as np
        >>> cz = np.array([[0.5, 0.2, 0.0]])  # camera z per observation, the last at 0
        >>> w = 0.1 / (1.0 - cz)  # w_k = fx W / Z_k with Z_k = Z_n - C_Zk, Z_n = 1
        >>> depth, singular = solve(w, 2 * w, cz)
        >>> round(float(depth[0]), 12), bool(singular[0])
        (1.0, False)
    """
    width = np.asarray(width, dtype=np.float64)
    height = np.asarray(height, dtype=np.float64)
    camera_z = np.asarray(camera_z, dtype=np.float64)
    n, n_obs = width.shape
    depth = np.empty(n)
    singular = np.empty(n, dtype=bool)
    mean_weights = np.full(n_obs, 1.0 / n_obs)
    tol = (2 * n_obs * np.finfo(np.float64).eps) ** 2
    block = max(1, min(_BLOCK, n))
    w, h, cw, ch = (np.empty((block, n_obs)) for _ in range(4))
    # Rows whose unused boxes hold NaN or infinity are solved too (and replaced by the
    # caller), so floating-point warnings are silenced for the whole loop.
    with np.errstate(all="ignore"):
        for start in range(0, n, block):
            stop = min(start + block, n)
            k = stop - start
            wk, hk, cwk, chk = w[:k], h[:k], cw[:k], ch[:k]
            np.copyto(wk, width[start:stop])
            np.copyto(hk, height[start:stop])
            mean_w, mean_h = wk @ mean_weights, hk @ mean_weights
            np.subtract(wk, mean_w[:, None], out=cwk)
            np.subtract(hk, mean_h[:, None], out=chk)
            den = np.einsum("ij,ij->i", cwk, cwk) + np.einsum("ij,ij->i", chk, chk)
            cwk *= wk
            chk *= hk
            cwk += chk
            cz = camera_z[start:stop]
            depth[start:stop] = np.einsum("ij,ij->i", cwk, cz) / den - cz[:, -1]
            singular[start:stop] = den <= tol * (n_obs * (mean_w * mean_w + mean_h * mean_h) + den)
    return depth, singular


def predict_report(
    examples: odmd_bench.Examples, fallback_depth: float = DEFAULT_FALLBACK_DEPTH
) -> tuple[np.ndarray, dict[str, int]]:
    """Box_LS depths and how many examples used each fallback.

    Args:
        examples: ``N`` examples.
        fallback_depth: Depth (metres) for examples whose system cannot be solved
            (module docstring).

    Returns:
        ``(depths, fallbacks)``: ``depths`` (N,) finite depth estimates at the last
        observation, metres; ``fallbacks`` ``{reason: count}`` for every reason in
        :data:`FALLBACKS` (zeros included).

    Raises:
        odmd_bench.UsageError: If ``fallback_depth`` is not finite.
    """
    fallback_depth = float(fallback_depth)
    if not np.isfinite(fallback_depth):
        raise odmd_bench.UsageError(f"fallback_depth must be finite, got {fallback_depth}")
    boxes, detected = examples.boxes, examples.detected
    camera_z = examples.camera[:, :, 2]
    depth, singular = solve(boxes[:, :, 2], boxes[:, :, 3], camera_z)
    no_detection = np.zeros(len(examples), dtype=bool)
    single_detection = np.zeros(len(examples), dtype=bool)
    # Only examples with a missing box need filling (and a second solve).
    gaps = np.flatnonzero(~detected.all(axis=1))
    if gaps.size:
        filled = odmd_bench.fill_missing(boxes[gaps], detected[gaps])
        depth[gaps], singular[gaps] = solve(filled[:, :, 2], filled[:, :, 3], camera_z[gaps])
        n_detected = detected[gaps].sum(axis=1)
        no_detection[gaps] = n_detected == 0
        single_detection[gaps] = n_detected == 1

    reasons = {
        "no_detection": no_detection,
        "single_detection": single_detection,
        "no_z_motion": (camera_z == camera_z[:, -1:]).all(axis=1),
        "rank_deficient": singular,
        "non_finite": ~np.isfinite(depth),
    }
    counts: dict[str, int] = {}
    taken = np.zeros(len(examples), dtype=bool)
    for name in FALLBACKS:
        hit = reasons[name] & ~taken
        counts[name] = int(hit.sum())
        taken |= hit
    return np.where(taken, fallback_depth, depth), counts


def predict(examples: odmd_bench.Examples, fallback_depth: float = DEFAULT_FALLBACK_DEPTH) -> np.ndarray:
    """Box_LS depth at the last observation for every example.

    Args:
        examples: ``N`` examples.
        fallback_depth: Depth for examples whose system cannot be solved (see the module
            docstring).

    Returns:
        (N,) finite depths in metres.

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(4, perturbation="normal", rng=0)
        >>> bool(abs(predict(ex) - ex.depth).max() < 1e-9)
        True
    """
    return predict_report(examples, fallback_depth)[0]
