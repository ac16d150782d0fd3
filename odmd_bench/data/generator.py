"""The versioned ODMD generator (paper section 3.3 and supplementary material).

Generator version 1. Everything random comes from the ``numpy.random.Generator``
passed in, in a fixed order, so a set is a pure function of
(generator version, config, perturbation, seed). Any change that alters a generated
number must bump :data:`GENERATOR_VERSION` and keep version 1 reproducible.

Order of draws for ``N`` examples of ``n`` observations (version 1):

1. one uniform block ``U`` of shape (N, 12 + 3 (n - 2)), float64, columns:
   total move magnitude (3), move sign (3), object W and H (2), Z1 (1), X1 and Y1
   (2), reversal (1), intermediate positions (3 x (n - 2), axis-major; each axis's
   n - 2 values are sorted);
2. if camera noise is on: standard normals (N, n - 1, 3);
3. if box noise is on: standard normals (N, n, 4);
4. if replacement is on: uniforms (N,) (replace or not), integers (N,) in [0, n)
   (which observation) and integers (N,) in [1, N) (donor offset; the donor is
   example ``(i + offset) mod N``). With N = 1 there is no other example and
   nothing is replaced.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from odmd_bench.data.config import GeneratorConfig, check_perturbation, get_preset
from odmd_bench.data.examples import Examples

GENERATOR_VERSION = 1


def as_rng(rng: int | np.random.Generator | None) -> np.random.Generator:
    """A ``numpy.random.Generator`` from a seed (SFC64) or the generator itself."""
    if isinstance(rng, np.random.Generator):
        return rng
    # Generator version 1 turns a seed into SFC64: as portable and well tested as
    # numpy's default PCG64, and its normal draws (most of the generator's time) are
    # markedly faster here.
    if rng is None or isinstance(rng, bool) or not isinstance(rng, int | np.integer) or rng < 0:
        from odmd_bench.errors import UsageError

        raise UsageError(f"rng must be a non-negative integer seed or a numpy Generator, got {rng!r}")
    return np.random.Generator(np.random.SFC64(int(rng)))


def generate(
    n: int,
    preset: str | GeneratorConfig = "odmd",
    perturbation: str = "normal",
    rng: int | np.random.Generator = 0,
) -> Examples:
    """``n`` fresh examples from generator version 1.

    Args:
        n: number of examples (>= 1).
        preset: ``"odmd"``, ``"odms"`` or a :class:`GeneratorConfig`.
        perturbation: ``"normal"`` (none), ``"camera"`` (camera-position noise),
            ``"object"`` (box noise and box replacement) or ``"both"``.
        rng: a seed or a ``numpy.random.Generator`` (advanced in place).

    Returns:
        :class:`Examples` with ``boxes`` (n, n_obs, 4), ``detected`` all True,
        ``camera`` (n, n_obs, 3), ``depth`` (n,), ``observation_depth`` (n, n_obs),
        and extras ``positions`` (n, n_obs, 3), ``size`` (n, 2), ``camera_clean``
        (n, n_obs, 3) and ``replaced`` (n, n_obs) bool.

    Example:
        >>> ex = generate(4, rng=0)
        >>> ex.boxes.shape, ex.camera[:, -1].tolist() == [[0.0, 0.0, 0.0]] * 4
        ((4, 10, 4), True)
    """
    n = _count(n, "n")
    config = get_preset(preset)
    check_perturbation(perturbation)
    try:
        return _examples(_generate_arrays(n, config, perturbation, as_rng(rng)), config, perturbation)
    except MemoryError:
        from odmd_bench.errors import UsageError

        raise UsageError(
            f"{n:,} examples of {config.n_obs} observations do not fit in memory; "
            "generate fewer at a time (odmd_bench.stream gives batches)"
        ) from None


def _count(value: object, name: str) -> int:
    """``value`` as an int if it is a positive integer (not a bool), else a UsageError."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        from odmd_bench.errors import UsageError

        raise UsageError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _examples(arrays: dict[str, np.ndarray], config: GeneratorConfig, perturbation: str) -> Examples:
    cam = config.camera
    attrs = {
        "generator_version": GENERATOR_VERSION,
        "perturbation": perturbation,
        "config": config.to_json(),
        "fx": cam.fx,
        "fy": cam.fy,
        "cx": cam.cx,
        "cy": cam.cy,
        "image_width": cam.image_width,
        "image_height": cam.image_height,
    }
    return Examples(
        boxes=arrays["boxes"],
        detected=np.ones(arrays["boxes"].shape[:2], dtype=bool),
        camera=arrays["camera"],
        depth=arrays["depth"],
        observation_depth=arrays["observation_depth"],
        extras={k: arrays[k] for k in ("positions", "size", "camera_clean", "replaced")},
        attrs=attrs,
    )


#: Examples per chunk of arithmetic: the random draws are made for the whole batch
#: (their order defines the data), the geometry is computed chunk by chunk so that the
#: temporaries stay in cache. Any chunk size gives the same numbers.
_CHUNK = 1024


def _scratch(work: dict[str, np.ndarray] | None, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """A float64 array for temporaries: reused from ``work`` when it has one of this shape.

    Fresh memory costs page faults that take as long as the draws themselves here, so
    :func:`stream` keeps its temporaries from batch to batch. Nothing returned to the
    caller lives in ``work``.
    """
    if work is None:
        return np.empty(shape)
    a = work.get(name)
    if a is None or a.shape != shape:
        a = work[name] = np.empty(shape)
    return a


def _generate_arrays(
    n: int,
    config: GeneratorConfig,
    perturbation: str,
    rng: np.random.Generator,
    work: dict[str, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    n_obs = config.n_obs
    cam = config.camera
    u = rng.random(out=_scratch(work, "u", (n, 12 + 3 * (n_obs - 2))))
    cam_noise = None
    if perturbation in ("camera", "both") and config.camera_sigma > 0:
        cam_noise = rng.standard_normal(out=_scratch(work, "camera_noise", (n, n_obs - 1, 3)))
    boxes = np.empty((n, n_obs, 4))
    box_noise = False
    replacement = None
    if perturbation in ("object", "both"):
        if config.box_sigma > 0:
            # Drawn straight into the output; the projection is added below
            # (sigma * noise + projection: the same sum, bit for bit).
            rng.standard_normal(out=boxes)
            box_noise = True
        if config.replace_prob > 0 and n > 1:
            hit = rng.random(n) < config.replace_prob
            obs = rng.integers(0, n_obs, n)
            offset = rng.integers(1, n, n)
            replacement = (hit, obs, offset)

    move_min = np.asarray(config.move_min)
    move_max = np.asarray(config.move_max)
    s_lo, s_hi = config.object_size
    z_lo, z_hi = config.initial_depth
    half = s_hi / 2
    fxn = cam.fx / cam.image_width
    fyn = cam.fy / cam.image_height
    cxn = cam.cx / cam.image_width
    cyn = cam.cy / cam.image_height

    size = s_lo + u[:, 6:8] * (s_hi - s_lo)  # object W, H
    positions = np.empty((n, n_obs, 3))
    camera_clean = np.empty((n, n_obs, 3))
    camera = camera_clean if cam_noise is None else np.empty((n, n_obs, 3))

    for a in range(0, n, _CHUNK):
        b = min(n, a + _CHUNK)
        uc = u[a:b]
        m = b - a
        # Total camera move delta = p_n - p_1: uniform magnitude per axis, random sign.
        delta = move_min + uc[:, 0:3] * (move_max - move_min)
        np.negative(delta, out=delta, where=uc[:, 3:6] < 0.5)
        z1 = z_lo + uc[:, 8] * (z_hi - z_lo)
        # X1, Y1 within the view bounds for Z1 (supplementary, eq. X1min).
        room = z1 - move_max[2]
        x_lo = (cam.cx / cam.fx) * -room + move_max[0] + half
        x_hi = ((cam.image_width - cam.cx) / cam.fx) * room - move_max[0] - half
        y_lo = (cam.cy / cam.fy) * -room + move_max[1] + half
        y_hi = ((cam.image_height - cam.cy) / cam.fy) * room - move_max[1] - half
        reverse = uc[:, 11] < config.reverse_prob
        keep = ~reverse

        # Camera path in generation order: p_i = p_1 + t_i (p_n - p_1), t_1 = 0, t_n = 1,
        # the intermediate t_i uniform and sorted (monotonic motion on every axis).
        # Relative to the last observation of the *output* order, the camera is
        #   (t_i - 1) delta      when the sequence is kept,
        #   t_(n+1-i) delta      when it is reversed (the first generated position is last),
        # so the reversal is a choice of coefficients, not a copy of every array.
        t = np.sort(uc[:, 12:].reshape(m, 3, n_obs - 2), axis=2).transpose(0, 2, 1)
        coef = camera_clean[a:b]
        coef[:, 0] = np.where(keep, -1.0, 1.0)[:, None]
        coef[:, -1] = 0.0
        coef[:, 1:-1] = t
        coef[keep, 1:-1] -= 1.0
        coef[reverse, 1:-1] = coef[reverse, -2:0:-1]
        coef[:, :-1] *= delta[:, None, :]  # the last row stays +0.0

        # The object is static: at each observation it sits at P_last - camera_i, where
        # P_last is P_1 - delta (kept) or P_1 itself (reversed).
        last = np.empty((m, 3))
        last[:, 0] = x_lo + uc[:, 9] * (x_hi - x_lo)
        last[:, 1] = y_lo + uc[:, 10] * (y_hi - y_lo)
        last[:, 2] = z1
        last[keep] -= delta[keep]
        pos = positions[a:b]
        np.subtract(last[:, None, :], coef, out=pos)

        # Pinhole projection, normalised by the image size, plus (object perturbation)
        # box noise on every coordinate, already drawn into ``boxes``.
        inv_z = 1.0 / pos[:, :, 2]
        bx = boxes[a:b]
        proj = (
            pos[:, :, 0] * inv_z * fxn + cxn,
            pos[:, :, 1] * inv_z * fyn + cyn,
            inv_z * (size[a:b, 0:1] * fxn),
            inv_z * (size[a:b, 1:2] * fyn),
        )
        if box_noise:
            bx *= config.box_sigma
            for k in range(4):
                bx[:, :, k] += proj[k]
        else:
            for k in range(4):
                bx[:, :, k] = proj[k]

        # Camera noise on every position but the last.
        if cam_noise is not None:
            noise = cam_noise[a:b]
            noise *= config.camera_sigma
            np.add(coef[:, :-1], noise, out=camera[a:b, :-1])
            camera[a:b, -1] = 0.0

    # Replacement of one box by the box another example has at the same observation
    # (after the noise, so the donor box is a noisy detection too).
    replaced = np.zeros((n, n_obs), dtype=bool)
    if replacement is not None:
        hit, obs, offset = replacement
        donor = (np.arange(n) + offset) % n
        rows = np.flatnonzero(hit)
        boxes[rows, obs[rows]] = boxes[donor[rows], obs[rows]]
        replaced[rows, obs[rows]] = True

    observation_depth = positions[:, :, 2]
    return {
        "boxes": boxes,
        "camera": camera,
        "depth": observation_depth[:, -1].copy(),
        "observation_depth": observation_depth,
        "positions": positions,
        "size": size,
        "camera_clean": camera_clean,
        "replaced": replaced,
    }


def stream(
    batch_size: int,
    preset: str | GeneratorConfig = "odmd",
    perturbation: str = "both",
    rng: int | np.random.Generator = 0,
) -> Iterator[Examples]:
    """An endless stream of fresh training batches from one random generator.

    Batch ``k`` of ``stream(b, ..., rng=seed)`` is a pure function of the seed and ``k``
    (each batch advances the same generator), so a training run can be replayed.

    Example:
        >>> batches = stream(512, perturbation="both", rng=0)
        >>> next(batches).boxes.shape
        (512, 10, 4)
    """
    batch_size = _count(batch_size, "batch_size")
    gen = as_rng(rng)
    config = get_preset(preset)
    check_perturbation(perturbation)
    work: dict[str, np.ndarray] = {}  # temporaries kept between batches (see _scratch)
    while True:
        yield _examples(_generate_arrays(batch_size, config, perturbation, gen, work), config, perturbation)
