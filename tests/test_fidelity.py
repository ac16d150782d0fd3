"""odmd-v1 against the original release: same distribution, by two-sample KS tests.

The generated sets are pinned, so these tests are deterministic: they pass or fail the
same way on every machine. The negative controls show that the same test catches a
wrong bound, a swapped axis and a wrong sign.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import odmd_bench
from odmd_bench import Examples, generate
from odmd_bench.data.config import PRESETS

ALPHA = 1e-3


def ks_pvalue(a: np.ndarray, b: np.ndarray) -> float:
    """Asymptotic two-sample Kolmogorov-Smirnov p-value (Stephens' correction)."""
    a, b = np.sort(a), np.sort(b)
    x = np.concatenate([a, b])
    d = np.abs(np.searchsorted(a, x, "right") / a.size - np.searchsorted(b, x, "right") / b.size).max()
    if d == 0:
        return 1.0
    n = a.size * b.size / (a.size + b.size)
    lam = (np.sqrt(n) + 0.12 + 0.11 / np.sqrt(n)) * d
    k = np.arange(1, 101)
    return float(np.clip(2 * np.sum((-1.0) ** (k - 1) * np.exp(-2 * k**2 * lam**2)), 0, 1))


def features(ex: Examples) -> dict[str, np.ndarray]:
    """Quantities whose distribution a wrong bound, axis or sign would change."""
    f = {
        "depth": ex.depth,
        "first depth": ex.observation_depth[:, 0],
        "w last": ex.boxes[:, -1, 2],
        "h last": ex.boxes[:, -1, 3],
        "x last": ex.boxes[:, -1, 0],
        "y last": ex.boxes[:, -1, 1],
        "x first": ex.boxes[:, 0, 0],
        "y first": ex.boxes[:, 0, 1],
        "object W": ex.extras["size"][:, 0],
        "object H": ex.extras["size"][:, 1],
        "mid camera x": ex.camera[:, 4, 0],
    }
    for i, axis in enumerate("xyz"):
        f[f"move {axis}"] = ex.camera[:, 0, i]
        f[f"|move {axis}|"] = np.abs(ex.camera[:, 0, i])
    pos = ex.extras["positions"]
    if ex.attrs.get("set") == "camera":
        clean_camera = pos[:, -1:, :] - pos
        f["camera noise"] = (ex.camera - clean_camera)[:, :-1].ravel()
    if ex.attrs.get("set") == "object":
        fx, fy, cx, cy, width, height = ex.intrinsics()
        z = pos[:, :, 2]
        clean = np.stack(
            [
                (fx * pos[:, :, 0] / z + cx) / width,
                (fy * pos[:, :, 1] / z + cy) / height,
                fx * ex.extras["size"][:, None, 0] / z / width,
                fy * ex.extras["size"][:, None, 1] / z / height,
            ],
            axis=2,
        )
        residual = ex.boxes - clean
        outlier = (np.abs(residual) > 0.006).any(axis=2)  # replaced boxes (6 sigma)
        f["box noise"] = residual[~outlier].ravel()
        f["replaced per example"] = outlier.sum(axis=1).astype(float)
    return f


def rejected(a: Examples, b: Examples) -> list[str]:
    fa, fb = features(a), features(b)
    return [k for k in fa if ks_pvalue(fa[k], fb[k]) < ALPHA]


@pytest.mark.parametrize("split", ["val", "test"])
@pytest.mark.parametrize("set_name", ["normal", "camera", "object"])
def test_v1_matches_the_original_distribution(split, set_name, v1_data_dir, paper_data_dir) -> None:
    ours = odmd_bench.load(split, set_name, "odmd-v1", v1_data_dir)
    theirs = odmd_bench.load(split, set_name, "odmd-paper", paper_data_dir)
    assert len(ours) == len(theirs)
    assert rejected(ours, theirs) == []


@pytest.mark.parametrize(
    "wrong",
    [
        {"move_max": (0.25, 0.175, 0.3)},  # wrong bound
        {"object_size": (0.02, 0.175)},  # wrong bound
        {"initial_depth": (0.6, 1.0)},  # wrong bound
    ],
)
def test_the_fidelity_test_catches_wrong_configs(wrong, paper_data_dir) -> None:
    theirs = odmd_bench.load("test", "normal", "odmd-paper", paper_data_dir)
    cfg = replace(PRESETS["odmd"], **wrong)
    assert rejected(generate(3000, cfg, "normal", rng=1), theirs) != []


def _with_camera(ex: Examples, camera: np.ndarray) -> Examples:
    return Examples(
        boxes=ex.boxes,
        detected=ex.detected,
        camera=camera,
        depth=ex.depth,
        observation_depth=ex.observation_depth,
        extras=ex.extras,
        attrs=ex.attrs,
    )


def test_the_fidelity_test_catches_a_swapped_axis(paper_data_dir) -> None:
    theirs = odmd_bench.load("test", "normal", "odmd-paper", paper_data_dir)
    ours = generate(3000, "odmd", "normal", rng=1)
    assert {"move x", "move y"} <= set(rejected(_with_camera(ours, ours.camera[:, :, [1, 0, 2]]), theirs))


def test_the_fidelity_test_catches_a_wrong_sign(paper_data_dir) -> None:
    theirs = odmd_bench.load("test", "normal", "odmd-paper", paper_data_dir)
    ours = generate(3000, "odmd", "normal", rng=1)
    # Camera z with the wrong sign: depths no longer follow the camera the same way.
    flipped = _with_camera(ours, ours.camera * np.array([1.0, 1.0, -1.0]))
    flipped_depth = Examples(
        boxes=ours.boxes,
        detected=ours.detected,
        camera=flipped.camera,
        depth=ours.depth,
        observation_depth=ours.depth[:, None] - flipped.camera[:, :, 2],
        extras=ours.extras,
        attrs=ours.attrs,
    )
    assert "first depth" in rejected(flipped_depth, theirs)


def test_the_fidelity_test_catches_wrong_noise(paper_data_dir) -> None:
    theirs = odmd_bench.load("test", "camera", "odmd-paper", paper_data_dir)
    cfg = replace(PRESETS["odmd"], camera_sigma=0.012)
    ours = generate(3000, cfg, "camera", rng=1)
    ours.attrs["set"] = "camera"
    assert "camera noise" in rejected(ours, theirs)
    theirs = odmd_bench.load("test", "object", "odmd-paper", paper_data_dir)
    cfg = replace(PRESETS["odmd"], box_sigma=0.0012)
    ours = generate(3000, cfg, "object", rng=1)
    ours.attrs["set"] = "object"
    assert "box noise" in rejected(ours, theirs)
