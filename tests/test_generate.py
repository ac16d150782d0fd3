"""Generator version 1: shapes, the pinhole model, determinism, perturbations, fidelity."""

from __future__ import annotations

import numpy as np
import pytest

import odmd_bench
from odmd_bench import generate
from odmd_bench.data.config import PRESETS, GeneratorConfig
from odmd_bench.data.hashing import content_sha256, set_arrays


@pytest.mark.parametrize("preset", ["odmd", "odms"])
def test_noise_free_examples_satisfy_the_pinhole_model(preset: str) -> None:
    cfg = PRESETS[preset]
    ex = generate(3000, preset, "normal", rng=7)
    cam = cfg.camera
    z = ex.observation_depth
    assert z is not None
    size = ex.extras["size"]
    # w_i Z_i = fx W (normalised by the image width), to rounding.
    np.testing.assert_allclose(
        ex.boxes[:, :, 2] * z, np.broadcast_to((cam.fx / cam.image_width) * size[:, :1], z.shape), rtol=1e-13
    )
    np.testing.assert_allclose(
        ex.boxes[:, :, 3] * z, np.broadcast_to((cam.fy / cam.image_height) * size[:, 1:], z.shape), rtol=1e-13
    )
    # Depths follow the camera: Z_j + C_Zj = Z_n, and the object stays in front.
    np.testing.assert_allclose(
        z + ex.camera[:, :, 2], np.broadcast_to(ex.depth[:, None], z.shape), atol=1e-14
    )
    assert (z > 0).all()
    # Every box, not just its centre, is inside the image at every observation.
    x, y, w, h = np.moveaxis(ex.boxes, 2, 0)
    assert (x - w / 2 >= 0).all() and (x + w / 2 <= 1).all()
    assert (y - h / 2 >= 0).all() and (y + h / 2 <= 1).all()
    assert ex.detected.all()


def test_camera_motion_is_monotonic_and_within_bounds() -> None:
    cfg = PRESETS["odmd"]
    ex = generate(5000, rng=3)
    assert (ex.camera[:, -1] == 0).all() and not np.signbit(ex.camera[:, -1]).any()
    d = np.diff(ex.camera, axis=1)
    assert ((d >= 0).all(axis=1) | (d <= 0).all(axis=1)).all()
    total = np.abs(ex.camera[:, 0])
    assert (total >= np.array(cfg.move_min) - 1e-15).all() and (total <= np.array(cfg.move_max) + 1e-15).all()
    # Both directions on every axis, and both orders (reversal) occur.
    for axis in range(3):
        share = (ex.camera[:, 0, axis] > 0).mean()
        assert 0.45 < share < 0.55
    z_closer = ex.observation_depth[:, -1] < ex.observation_depth[:, 0]
    assert 0.45 < z_closer.mean() < 0.55


def test_seeds_are_deterministic_and_distinct() -> None:
    a = content_sha256(set_arrays(generate(500, perturbation="both", rng=11)))
    b = content_sha256(
        set_arrays(generate(500, perturbation="both", rng=np.random.Generator(np.random.SFC64(11))))
    )
    c = content_sha256(set_arrays(generate(500, perturbation="both", rng=12)))
    assert a == b != c


def test_generate_does_not_share_memory_between_calls() -> None:
    a = generate(10, rng=1)
    b = generate(10, rng=1)
    a.boxes[:] = 0
    assert (b.boxes != 0).all()


def test_camera_perturbation_spares_the_last_position() -> None:
    ex = generate(4000, perturbation="camera", rng=5)
    noise = ex.camera - ex.extras["camera_clean"]
    assert (noise[:, -1] == 0).all()
    assert noise[:, :-1].std() == pytest.approx(0.01, rel=0.03)
    assert abs(noise[:, :-1].mean()) < 3e-4
    assert not ex.extras["replaced"].any()


def test_object_perturbation_noise_and_replacement() -> None:
    n = 6000
    ex = generate(n, perturbation="object", rng=9)
    clean = generate(n, perturbation="normal", rng=9)
    replaced = ex.extras["replaced"]
    assert (ex.camera == clean.camera).all()
    per_example = replaced.sum(axis=1)
    assert per_example.max() == 1
    assert per_example.mean() == pytest.approx(0.1, abs=0.015)
    noise = (ex.boxes - clean.boxes)[~replaced]
    assert noise.std() == pytest.approx(0.001, rel=0.03)
    # A replaced box is another example's (noisy) box at the same observation.
    rows, obs = np.nonzero(replaced)
    for r, o in zip(rows[:50], obs[:50], strict=True):
        matches = np.flatnonzero((ex.boxes[:, o] == ex.boxes[r, o]).all(axis=1))
        assert len(matches) >= 2


def test_both_perturbations_together() -> None:
    ex = generate(2000, perturbation="both", rng=4)
    assert (ex.camera != ex.extras["camera_clean"])[:, :-1].all()
    assert ex.extras["replaced"].any()


def test_single_example_batches_work() -> None:
    ex = generate(1, perturbation="both", rng=0)
    assert ex.boxes.shape == (1, 10, 4) and not ex.extras["replaced"].any()


@pytest.mark.parametrize("bad", [0, -1, 2.5, True])
def test_bad_sizes_are_usage_errors(bad) -> None:
    with pytest.raises(odmd_bench.UsageError):
        generate(bad)


def test_bad_perturbation_and_rng() -> None:
    with pytest.raises(odmd_bench.ConfigError, match="normal, camera, object, both"):
        generate(3, perturbation="noisy")
    with pytest.raises(odmd_bench.UsageError, match="seed"):
        generate(3, rng=-5)


def test_custom_config_is_honoured() -> None:
    cfg = GeneratorConfig(n_obs=4, move_min=(0.0, 0.0, 0.1), move_max=(0.0, 0.0, 0.2))
    ex = generate(100, cfg, rng=0)
    assert ex.boxes.shape == (100, 4, 4)
    assert (ex.camera[:, :, :2] == 0).all()
    assert (np.abs(ex.camera[:, 0, 2]) >= 0.1).all()


def _same(a: odmd_bench.Examples, b: odmd_bench.Examples) -> bool:
    return content_sha256(set_arrays(a)) == content_sha256(set_arrays(b))


@pytest.mark.parametrize("perturbation", ["normal", "camera", "object", "both"])
def test_stream_batches_are_successive_generate_calls(perturbation: str) -> None:
    """The stream reuses its temporaries between batches; the numbers must not notice.

    A batch already handed out must not change when the next one is made.
    """
    batches = odmd_bench.stream(300, perturbation=perturbation, rng=11)
    first = next(batches)
    kept = first.boxes.copy(), first.camera.copy(), first.depth.copy()
    rest = [next(batches) for _ in range(3)]
    gen = np.random.Generator(np.random.SFC64(11))
    expected = [generate(300, "odmd", perturbation, gen) for _ in range(4)]
    assert all(_same(x, y) for x, y in zip([first, *rest], expected, strict=True))
    for was, now in zip(kept, (first.boxes, first.camera, first.depth), strict=True):
        np.testing.assert_array_equal(was, now)
    assert first.attrs == expected[0].attrs


def test_box_noise_is_added_to_the_projection() -> None:
    """With box noise, boxes = noise-free projection + sigma * N(0, 1), the same draws."""
    clean = generate(500, "odmd", "normal", rng=5)
    noisy = generate(500, "odmd", "object", rng=5)
    np.testing.assert_array_equal(noisy.camera, clean.camera)
    diff = (noisy.boxes - clean.boxes)[~noisy.extras["replaced"]]
    assert 0.0009 < diff.std() < 0.0011 and abs(diff.mean()) < 1e-4


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "512"])
def test_stream_refuses_a_bad_batch_size(bad: object) -> None:
    with pytest.raises(odmd_bench.OdmdError, match="batch_size"):
        next(odmd_bench.stream(bad))  # type: ignore[arg-type]
