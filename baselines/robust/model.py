"""The robust method's noise model and hyperparameters (see the package docstring)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from odmd_bench import UsageError

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


def chunked(
    fit_slice: Callable[[slice], tuple[np.ndarray, np.ndarray, dict[str, int]]], n: int
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """A fit of ``n`` examples run ``CHUNK`` at a time, joined (examples are independent).

    Chunks keep the working arrays in cache.
    """
    parts = [fit_slice(slice(s, s + CHUNK)) for s in range(0, n, CHUNK)]
    counts = {k: sum(part[2][k] for part in parts) for k in parts[0][2]}
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]), counts
