"""The method interface: ``predict``, ``predict_report``, ``predict_details``.

**A camera that turns** (``rotation=``, given by ``odmd-bench predict`` from the
sequences file's quaternion columns): the object is then modelled as a flat rectangle
facing the last observation, whose box in observation ``k`` (turned by ``R_k``, its axes
in the last observation's) is the bounding box of its four projected corners. Each box
is carried exactly into the last observation's orientation before the fit
(:func:`odmd_bench.carry_boxes`, ``"plane"``: the box whose corners, carried back by the
rotation's homography, have the seen box as their bounding box), and the fit runs
unchanged (positions given in the last observation's axes). Exact on noise-free scenes of
such objects; the box noise is not rescaled (the carry changes sizes by under 8 % for
turns under 15 degrees near the image centre).
"""

from __future__ import annotations

import numpy as np
from odmd_bench_baselines.robust.model import (
    DEFAULT_PARAMS,
    MISSING,
    MODES,
    Intrinsics,
    Missing,
    Mode,
    RobustParams,
)
from odmd_bench_baselines.robust.scale import fit_scale
from odmd_bench_baselines.robust.solver import fit

from odmd_bench import DataError, Examples, UsageError, carry_boxes, fill_missing
from odmd_bench.methods import MethodOption

#: The options ``odmd-bench baseline`` and ``predict`` give it (see odmd_bench.methods).
OPTIONS = (
    MethodOption(
        "mode",
        str,
        "full",
        "full: parallax and scale (needs the camera intrinsics); scale: the box sizes alone "
        "(no intrinsics needed).",
        choices=MODES,
    ),
)

#: The counts of :func:`predict_report` that are fallbacks (``odmd_bench.predict.report``).
FALLBACKS: tuple[str, ...] = ("fit_failed", "too_few_detections")


def predict(
    examples: Examples,
    params: RobustParams = DEFAULT_PARAMS,
    *,
    mode: Mode = "full",
    missing: Missing = "omit",
    intrinsics: Intrinsics | None = None,
    rotation: np.ndarray | None = None,
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
        rotation: (N, n_obs, 3, 3) each observation's camera axes in the last
            observation's (a turning camera, module docstring; ``camera`` then in the
            last observation's axes), or None: the camera does not turn. Needs the
            intrinsics in either mode.

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
    return predict_report(
        examples, params, mode=mode, missing=missing, intrinsics=intrinsics, rotation=rotation
    )[0]


def predict_report(
    examples: Examples,
    params: RobustParams = DEFAULT_PARAMS,
    *,
    mode: Mode = "full",
    missing: Missing = "omit",
    intrinsics: Intrinsics | None = None,
    rotation: np.ndarray | None = None,
) -> tuple[np.ndarray, dict[str, int]]:
    """Like :func:`predict`, also returning the counted fallbacks.

    Returns:
        ``(depths (N,), counts)`` with ``counts`` = ``{"fit_failed": k,
        "too_few_detections": m, "n": N}``.
    """
    depth, _, counts = predict_details(
        examples, params, mode=mode, missing=missing, intrinsics=intrinsics, rotation=rotation
    )
    return depth, counts


def predict_details(
    examples: Examples,
    params: RobustParams = DEFAULT_PARAMS,
    *,
    mode: Mode = "full",
    missing: Missing = "omit",
    intrinsics: Intrinsics | None = None,
    rotation: np.ndarray | None = None,
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
    if mode == "full" or rotation is not None:
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
    if rotation is not None and cam_model is not None:
        boxes = _unturned(boxes, np.asarray(rotation, dtype=np.float64), cam_model)
        if mode == "scale":
            cam_model = None
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


def _unturned(
    boxes: np.ndarray, rotation: np.ndarray, cam_model: tuple[float, float, float, float]
) -> np.ndarray:
    """Boxes (N, n_obs, 4) of a turned camera in the last observation's axes (module docstring).

    Raises:
        UsageError: ``rotation`` not (N, n_obs, 3, 3) or not finite.
    """
    if rotation.shape != boxes.shape[:2] + (3, 3) or not np.isfinite(rotation).all():
        raise UsageError(f"rotation must be finite, {boxes.shape[:2] + (3, 3)}; got {rotation.shape}")
    half = boxes[..., 2:] / 2
    corners = np.concatenate([boxes[..., :2] - half, boxes[..., :2] + half], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        carried = carry_boxes(corners, rotation, cam_model, "plane")
        out = np.concatenate(
            [(carried[..., :2] + carried[..., 2:]) / 2, carried[..., 2:] - carried[..., :2]], axis=-1
        )
    return np.where(np.isfinite(out) & (out[..., 2:3] > 0) & (out[..., 3:4] > 0), out, boxes)
