"""DBox training batches generated on the training device (``train-dbox --data device``).

The generator of :mod:`odmd_bench.data.generator` (version 1) written in torch, so that
a GPU run draws, projects and normalises its batches where the network runs, with no
copy from the host per step. The arithmetic is the numpy generator's, operation for
operation: fed the same random draws it gives the same examples bit for bit in float64
(a test checks it). The draws themselves come from torch's generator on the device, a
different random stream from numpy's, so ``--data device`` is another stream of the
same distribution than ``--data host``, not the same examples.

Random draws per step: the step's generator is seeded from (run seed, step) through
``numpy.random.SeedSequence``, so the examples of a step depend on the seed and the step
alone: a resumed run, or a run on another number of processes, continues the same stream,
and nothing about the stream is kept in the training state. On CUDA the draws come from
Philox (counter-based: the same on every CUDA device), on the CPU from torch's Mersenne
Twister.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from odmd_bench import PRESETS, GeneratorConfig, UsageError

#: Where ``train-dbox`` generates its batches: ``host`` (numpy on the CPU, the stream the
#: shipped weights were trained on) or ``device`` (this module, on the training device).
DATA_SOURCES = ("host", "device")


@dataclass(frozen=True)
class Draws:
    """The random draws of one batch, in the numpy generator's layout (its docstring).

    Attributes:
        u: (N, 12 + 3 (n - 2)) uniforms.
        camera_noise: (N, n - 1, 3) standard normals, or None (no camera noise).
        box_noise: (N, n, 4) standard normals, or None (no box noise).
        replace: (hit (N,) bool, obs (N,) int64, offset (N,) int64), or None.
    """

    u: torch.Tensor
    camera_noise: torch.Tensor | None
    box_noise: torch.Tensor | None
    replace: tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None


def step_seed(seed: int, step: int) -> int:
    """The seed of step ``step``'s generator: a 63-bit hash of (seed, step)."""
    state = np.random.SeedSequence([int(seed), int(step)]).generate_state(2, np.uint32)
    return (int(state[0]) << 31) ^ int(state[1])


def draw(
    n: int, config: GeneratorConfig, perturbation: str, generator: torch.Generator, device: torch.device
) -> Draws:
    """A batch's random draws, in the numpy generator's order, from ``generator``."""
    n_obs = config.n_obs
    f64 = torch.float64
    u = torch.rand((n, 12 + 3 * (n_obs - 2)), generator=generator, device=device, dtype=f64)
    cam = box = replace = None
    if perturbation in ("camera", "both") and config.camera_sigma > 0:
        cam = torch.randn((n, n_obs - 1, 3), generator=generator, device=device, dtype=f64)
    if perturbation in ("object", "both"):
        if config.box_sigma > 0:
            box = torch.randn((n, n_obs, 4), generator=generator, device=device, dtype=f64)
        if config.replace_prob > 0 and n > 1:
            hit = torch.rand((n,), generator=generator, device=device, dtype=f64) < config.replace_prob
            obs = torch.randint(0, n_obs, (n,), generator=generator, device=device)
            offset = torch.randint(1, n, (n,), generator=generator, device=device)
            replace = (hit, obs, offset)
    return Draws(u, cam, box, replace)


def numpy_draws(n: int, config: GeneratorConfig, perturbation: str, rng: np.random.Generator) -> Draws:
    """The draws numpy's generator version 1 makes from ``rng`` (for tests of :func:`geometry`)."""
    n_obs = config.n_obs
    u = rng.random((n, 12 + 3 * (n_obs - 2)))
    cam = box = None
    replace = None
    if perturbation in ("camera", "both") and config.camera_sigma > 0:
        cam = torch.from_numpy(rng.standard_normal((n, n_obs - 1, 3)))
    if perturbation in ("object", "both"):
        if config.box_sigma > 0:
            box = torch.from_numpy(rng.standard_normal((n, n_obs, 4)))
        if config.replace_prob > 0 and n > 1:
            hit = rng.random(n) < config.replace_prob
            obs = rng.integers(0, n_obs, n)
            offset = rng.integers(1, n, n)
            replace = (torch.from_numpy(hit), torch.from_numpy(obs), torch.from_numpy(offset))
    return Draws(torch.from_numpy(u), cam, box, replace)


def geometry(draws: Draws, config: GeneratorConfig) -> dict[str, torch.Tensor]:
    """Boxes (N, n, 4), camera (N, n, 3) and depth (N,), float64, from the draws.

    The numpy generator's ``_generate_arrays``, operation for operation.
    """
    u = draws.u
    n, n_obs = u.shape[0], config.n_obs
    dev = u.device
    cam = config.camera
    lo, mm = config.move_min, config.move_max  # Python floats: no copy to the device per batch
    s_lo, s_hi = config.object_size
    z_lo, z_hi = config.initial_depth
    half = s_hi / 2
    fxn = cam.fx / cam.image_width
    fyn = cam.fy / cam.image_height
    cxn = cam.cx / cam.image_width
    cyn = cam.cy / cam.image_height

    size = s_lo + u[:, 6:8] * (s_hi - s_lo)
    delta = torch.stack([lo[k] + u[:, k] * (mm[k] - lo[k]) for k in range(3)], dim=1)
    delta = torch.where(u[:, 3:6] < 0.5, -delta, delta)
    z1 = z_lo + u[:, 8] * (z_hi - z_lo)
    room = z1 - mm[2]
    x_lo = (cam.cx / cam.fx) * -room + mm[0] + half
    x_hi = ((cam.image_width - cam.cx) / cam.fx) * room - mm[0] - half
    y_lo = (cam.cy / cam.fy) * -room + mm[1] + half
    y_hi = ((cam.image_height - cam.cy) / cam.fy) * room - mm[1] - half
    keep = ~(u[:, 11] < config.reverse_prob)

    t = torch.sort(u[:, 12:].reshape(n, 3, n_obs - 2), dim=2).values.transpose(1, 2)
    coef = torch.empty((n, n_obs, 3), dtype=torch.float64, device=dev)
    coef[:, 0] = torch.where(keep, -1.0, 1.0)[:, None]
    coef[:, -1] = 0.0
    # kept: t - 1; reversed: t in reverse order (the numpy generator's row copy)
    coef[:, 1:-1] = torch.where(keep[:, None, None], t - 1.0, t.flip(1))
    coef[:, :-1] *= delta[:, None, :]

    last = torch.stack((x_lo + u[:, 9] * (x_hi - x_lo), y_lo + u[:, 10] * (y_hi - y_lo), z1), dim=1)
    last = torch.where(keep[:, None], last - delta, last)
    pos = last[:, None, :] - coef

    inv_z = 1.0 / pos[:, :, 2]
    proj = (
        pos[:, :, 0] * inv_z * fxn + cxn,
        pos[:, :, 1] * inv_z * fyn + cyn,
        inv_z * (size[:, 0:1] * fxn),
        inv_z * (size[:, 1:2] * fyn),
    )
    boxes = torch.stack(proj, dim=2)
    if draws.box_noise is not None:
        boxes = draws.box_noise * config.box_sigma + boxes

    if draws.camera_noise is not None:
        camera = torch.empty_like(coef)
        camera[:, :-1] = coef[:, :-1] + draws.camera_noise * config.camera_sigma
        camera[:, -1] = 0.0
    else:
        camera = coef

    if draws.replace is not None:
        # Every example's box at its drawn observation, the donor's where hit: gathered
        # before any is written, as numpy's fancy assignment does, and with no
        # data-dependent shape (which would wait for the device).
        hit, obs, offset = draws.replace
        index = torch.arange(n, device=dev)
        donor = (index + offset) % n
        boxes[index, obs] = torch.where(hit[:, None], boxes[donor, obs], boxes[index, obs])
    return {"boxes": boxes, "camera": camera, "depth": pos[:, -1, 2].clone()}


def network_batch(
    arrays: dict[str, torch.Tensor], formulation: str, rows: slice = slice(None)
) -> tuple[torch.Tensor, torch.Tensor]:
    """DBox's input (B, n, 7) and target (B,), float32, of ``rows`` of a generated batch.

    :func:`odmd_bench_baselines.dbox.formulations.make_inputs` for generated examples (every
    box detected), in torch.
    """
    boxes = arrays["boxes"][rows].float()
    cam = arrays["camera"][rows].float()
    depth = arrays["depth"][rows].float()
    if formulation == "rel":
        norm = torch.linalg.vector_norm(cam[:, 0], dim=1)
        rel = cam / norm[:, None, None]
        motion = torch.cat((torch.zeros_like(rel[:, :1]), torch.diff(rel, dim=1)), dim=1)
        target = depth / norm
    else:
        motion = cam
        target = depth
    return torch.cat((boxes, motion), dim=2), target


class DeviceBatches:
    """The training batches of one run, drawn on ``device``: step ``t``'s from (seed, t)."""

    def __init__(
        self, preset: str, perturbation: str, formulation: str, seed: int, device: torch.device
    ) -> None:
        if preset not in PRESETS or perturbation not in ("normal", "camera", "object", "both"):
            raise UsageError(f"no generator preset {preset!r} with perturbation {perturbation!r}")
        self.config = PRESETS[preset]
        self.perturbation = perturbation
        self.formulation = formulation
        self.seed = seed
        self.device = device
        self.generator = torch.Generator(device=device)

    def batch(
        self, step: int, batch_size: int, rows: slice = slice(None)
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Input and target of ``rows`` of step ``step``'s global batch of ``batch_size``."""
        self.generator.manual_seed(step_seed(self.seed, step))
        draws = draw(batch_size, self.config, self.perturbation, self.generator, self.device)
        return network_batch(geometry(draws, self.config), self.formulation, rows)


__all__ = [
    "DATA_SOURCES",
    "DeviceBatches",
    "Draws",
    "draw",
    "geometry",
    "network_batch",
    "numpy_draws",
    "step_seed",
]
