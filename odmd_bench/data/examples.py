"""The in-memory form of a set of examples, and the shared missing-detection rule."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odmd_bench.data.pixels import pixel_fields
from odmd_bench.errors import DataError

#: Arrays every set has, with their dtype and the shape after the example axis.
CORE_ARRAYS: dict[str, str] = {
    "boxes": "float64",
    "detected": "bool",
    "camera": "float64",
    "depth": "float64",
}


@dataclass(frozen=True, eq=False)
class Examples:
    """``N`` examples of ``n_obs`` observations each.

    Attributes:
        boxes: (N, n_obs, 4) float64, ``x, y, w, h`` divided by the image width (x, w)
            or height (y, h). Where ``detected`` is False the numbers are whatever the
            source stored (0 for the original release) and carry no information.
        detected: (N, n_obs) bool, False where the detector found nothing.
        camera: (N, n_obs, 3) float64, camera position relative to the last
            observation in metres (camera axes); the last row is zero.
        depth: (N,) float64, depth Z_n of the object at the last observation, metres;
            NaN where unknown (``depth=None`` on creation: unknown for every example).
        observation_depth: (N, n_obs) float64 or None, depth at each observation
            (NaN where unknown).
        extras: further per-example arrays the source knew (for generated sets:
            ``positions`` (N, n_obs, 3), ``size`` (N, 2), ``camera_clean``
            (N, n_obs, 3), ``replaced`` (N, n_obs)).
        attrs: metadata: ``benchmark``, ``split``, ``set``, ``content_sha256`` and,
            where known, the intrinsics ``fx``, ``fy``, ``cx``, ``cy`` (pixels) and
            ``image_width``, ``image_height``.
    """

    boxes: np.ndarray
    detected: np.ndarray
    camera: np.ndarray
    depth: np.ndarray = None  # type: ignore[assignment]  # None -> all NaN in __post_init__
    observation_depth: np.ndarray | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    attrs: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.depth is None and self.boxes.ndim >= 1:
            object.__setattr__(self, "depth", np.full(self.boxes.shape[0], np.nan))
        problems = []
        if self.boxes.ndim != 3 or self.boxes.shape[2] != 4:
            problems.append(f"boxes must be (N, n_obs, 4), got {self.boxes.shape}")
        else:
            n, n_obs = self.boxes.shape[:2]
            expect = {
                "detected": (n, n_obs),
                "camera": (n, n_obs, 3),
                "depth": (n,),
            }
            for name, shape in expect.items():
                got = getattr(self, name).shape
                if got != shape:
                    problems.append(f"{name} must be {shape}, got {got}")
            if self.observation_depth is not None and self.observation_depth.shape != (n, n_obs):
                problems.append(f"observation_depth must be {(n, n_obs)}, got {self.observation_depth.shape}")
            if not problems and n_obs:
                last = np.asarray(self.camera[:, -1, :])
                moved = np.flatnonzero((np.isfinite(last) & (last != 0)).any(axis=1))
                if moved.size:
                    problems.append(
                        "camera must be relative to the last observation (its last row "
                        f"zero), but {moved.size} example(s) have a nonzero last row "
                        f"(first: {moved[:5].tolist()}); subtract camera[:, -1:] or build "
                        "them with Examples.from_pixels, which takes any origin"
                    )
        if problems:
            raise DataError("inconsistent example arrays", problems)

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    @classmethod
    def from_pixels(
        cls,
        corners: Any,
        camera: Any,
        image_size: tuple[float, float],
        depth: Any = None,
        **kwargs: Any,
    ) -> Examples:
        """Examples from pixel box corners and camera positions in a fixed frame.

        The conversion and its checks: :func:`odmd_bench.data.pixels.pixel_fields`.

        Args:
            corners: (N, n_obs, 4) ``x1, y1, x2, y2`` in pixels, NaN in all four where
                the detector found nothing.
            camera: (N, n_obs, 3) camera positions, metres, camera axes, any origin.
            image_size: ``(width, height)`` in pixels.
            depth: (N,) true depth at the last observation, or None (unknown).
            **kwargs: ``intrinsics``, ``observation_depth``, ``attrs``.

        Returns:
            The examples in the package's convention.

        Raises:
            DataError: wrong shapes, a box partly NaN, with ``x2 <= x1`` or ``y2 <= y1``,
                non-finite numbers, or a known depth that is not > 0 (every problem named).

        Example:
            >>> import numpy as np
            >>> corners = np.array([[[280.0, 200.0, 360.0, 280.0], [270.0, 190.0, 370.0, 290.0]]])
            >>> camera = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.2]]])
            >>> ex = Examples.from_pixels(corners, camera, (640, 480))
            >>> ex.boxes[0, 1].tolist(), ex.camera[0, 0].tolist(), bool(np.isnan(ex.depth[0]))
            ([0.5, 0.5, 0.15625, 0.20833333333333334], [0.0, 0.0, -0.2], True)
        """
        return cls(**pixel_fields(corners, camera, image_size, depth, **kwargs))

    @property
    def n_obs(self) -> int:
        """Number of observations per example."""
        return int(self.boxes.shape[1])

    def intrinsics(self) -> tuple[float, float, float, float, float, float]:
        """``(fx, fy, cx, cy, image_width, image_height)`` in pixels.

        Raises :class:`DataError` naming the set when it does not carry them (the
        original robot and ODMS files, for instance, say nothing about the camera).
        """
        keys = ("fx", "fy", "cx", "cy", "image_width", "image_height")
        missing = [k for k in keys if self.attrs.get(k) is None]
        if missing:
            where = "/".join(str(self.attrs[k]) for k in ("benchmark", "split", "set") if k in self.attrs)
            raise DataError(
                f"set {where or '(unnamed)'} carries no camera intrinsics "
                f"(missing: {', '.join(missing)}); this method needs a calibrated camera"
            )
        return tuple(float(self.attrs[k]) for k in keys)  # type: ignore[return-value]

    def without_truth(self) -> Examples:
        """The same examples as a method may see them, without the answer.

        No depth, no per-observation depth and none of the source's ``extras`` (the
        generator's object positions, clean camera and replaced boxes). Each call gives
        its own copies of ``boxes``, ``detected`` and ``camera``, marked read-only (a
        write raises ``ValueError: assignment destination is read-only`` where the
        method writes), and a copy of ``attrs``: a method that writes into its input,
        even after marking a copy writable again, changes nothing another method or the
        scorer sees.

        Every registered method is run on this view (:meth:`odmd_bench.methods.Method.run`),
        so that a score can never come from the answer, and one method cannot change the
        input of the next (an audit runs every entry on the same fresh sets).
        """
        return Examples(
            boxes=_read_only(self.boxes),
            detected=_read_only(self.detected),
            camera=_read_only(self.camera),
            attrs=dict(self.attrs),
        )

    def subset(self, index: np.ndarray | slice) -> Examples:
        """The examples selected by ``index`` (a new object; arrays are copies)."""
        return Examples(
            boxes=self.boxes[index].copy(),
            detected=self.detected[index].copy(),
            camera=self.camera[index].copy(),
            depth=self.depth[index].copy(),
            observation_depth=None
            if self.observation_depth is None
            else self.observation_depth[index].copy(),
            extras={k: v[index].copy() for k, v in self.extras.items()},
            attrs=dict(self.attrs),
        )


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only copy of ``array`` (its own memory: making it writable again reaches nothing else)."""
    out = np.array(array, copy=True)
    out.flags.writeable = False
    return out


def set_problems(ex: Examples) -> list[str]:
    """What makes ``ex`` unusable as a benchmark set, one line per kind (empty when usable).

    A set is scored as ``|Z - Z_hat| / Z``, so every true depth must be known, finite
    and positive; the camera positions must be finite; a detected box must be finite
    (its size may be zero: the original release has such detections); every example
    needs two observations and a detection; an observation's depth is positive or unknown (NaN). The sets
    odmd-bench generates or imports from the pinned original files all pass; a file
    imported with ``--allow-unknown`` may not.
    """
    if len(ex) == 0:
        return ["the set has no examples"]
    if ex.n_obs < 2:
        return [f"every example needs at least two observations, these have {ex.n_obs}"]

    def where(bad: Any, what: str) -> list[str]:
        rows = np.flatnonzero(bad)
        if not rows.size:
            return []
        return [f"{rows.size} example(s) {what} (first: {rows[:5].tolist()})"]

    depth = np.asarray(ex.depth, dtype=np.float64)
    boxes_ok = np.isfinite(ex.boxes).all(axis=2) | ~ex.detected
    problems = where(~(np.isfinite(depth) & (depth > 0)), "with a true depth that is not finite and > 0")
    problems += where(~np.isfinite(ex.camera).all(axis=(1, 2)), "with a camera position that is not finite")
    problems += where(~boxes_ok.all(axis=1), "with a detected box that is not finite")
    problems += where(~ex.detected.any(axis=1), "with no detection at any observation")
    if ex.observation_depth is not None:
        od = ex.observation_depth
        problems += where(
            ~((od > 0) & np.isfinite(od) | np.isnan(od)).all(axis=1),
            "with an observation depth that is not positive, finite or unknown (NaN)",
        )
    return problems


def nearest_detected_index(detected: np.ndarray, use: np.ndarray | None = None) -> np.ndarray:
    """For each observation, the index of the nearest observation with a detection.

    Args:
        detected: (N, n_obs) bool.
        use: optional (n_obs,) bool or index array: only these observations are
            considered as sources and targets (e.g. first and last only).

    Returns:
        (N, n_obs) int: the source index for each observation (itself where detected;
        the earlier of two equally near otherwise). Where an example has no detection
        among the used observations, each observation maps to itself.
    """
    detected = np.asarray(detected, dtype=bool)
    n_obs = detected.shape[1]
    idx = np.arange(n_obs)
    mask = np.ones(n_obs, dtype=bool)
    if use is not None:
        mask = np.zeros(n_obs, dtype=bool)
        mask[np.asarray(use)] = True
    # Cost of taking target t from source s: 2|t - s| plus 1 if s is later, so that
    # the earlier observation wins a tie.
    cost = 2 * np.abs(idx[:, None] - idx[None, :]) + (idx[None, :] > idx[:, None])
    big = 4 * n_obs + 2
    cost_all = np.where((detected & mask[None, :])[:, None, :], cost[None], big)
    src = np.argmin(cost_all, axis=2)
    none = ~(detected & mask[None, :]).any(axis=1)
    src[none] = idx
    return src


def fill_missing(boxes: np.ndarray, detected: np.ndarray, use: np.ndarray | None = None) -> np.ndarray:
    """Replace every missing box by the box of the nearest observation that has one.

    The rule of the paper and of every method here: among the observations a method
    uses (``use``, default all), a missing box takes the box of the nearest detected
    observation, the earlier one on a tie. Examples with no detection at all are
    returned unchanged (callers apply their own documented fallback).

    Args:
        boxes: (N, n_obs, 4).
        detected: (N, n_obs) bool.
        use: optional observations to consider (see :func:`nearest_detected_index`).

    Returns:
        (N, n_obs, 4) new array.

    Example:
        >>> import numpy as np
        >>> b = np.arange(12, dtype=float).reshape(1, 3, 4)
        >>> fill_missing(b, np.array([[True, False, True]]))[0, 1].tolist()
        [0.0, 1.0, 2.0, 3.0]
    """
    src = nearest_detected_index(detected, use)
    return np.take_along_axis(np.asarray(boxes), src[:, :, None], axis=1)
