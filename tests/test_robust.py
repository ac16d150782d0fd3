"""The robust reprojection method (baselines/robust/): exactness, robustness, contract."""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from odmd_bench_baselines import robust
from odmd_bench_baselines.robust import DEFAULT_PARAMS, NoiseModel, RobustParams

import odmd_bench
from odmd_bench import CameraConfig, DataError, Examples, GeneratorConfig, UsageError


def _percent_error(depth: np.ndarray, ex: Examples) -> np.ndarray:
    return odmd_bench.percent_error(ex.depth, depth)


def _without(ex: Examples, *keys: str) -> Examples:
    """A copy of ``ex`` whose attrs lack ``keys`` (e.g. the intrinsics)."""
    attrs = {k: v for k, v in ex.attrs.items() if k not in keys}
    return Examples(ex.boxes, ex.detected, ex.camera, ex.depth, ex.observation_depth, ex.extras, attrs)


def _with(ex: Examples, **arrays: np.ndarray) -> Examples:
    """A copy of ``ex`` with some core arrays replaced."""
    fields = {"boxes": ex.boxes, "detected": ex.detected, "camera": ex.camera, "depth": ex.depth} | arrays
    return Examples(**fields, observation_depth=ex.observation_depth, extras=ex.extras, attrs=ex.attrs)


INTRINSICS = ("fx", "fy", "cx", "cy", "image_width", "image_height")


# --- exact on noise-free data ---------------------------------------------------------


def test_exact_on_noise_free_odmd_data() -> None:
    ex = odmd_bench.generate(500, preset="odmd", perturbation="normal", rng=1)
    depth, counts = robust.predict_report(ex)
    assert np.max(_percent_error(depth, ex)) < 1e-7
    assert counts["fit_failed"] == 0 and counts["too_few_detections"] == 0


def test_exact_with_missing_detections_left_out() -> None:
    ex = odmd_bench.generate(300, perturbation="normal", rng=2)
    rng = np.random.default_rng(0)
    detected = rng.random(ex.detected.shape) > 0.3
    detected[:, :2] = True  # at least two observations each
    boxes = np.where(detected[:, :, None], ex.boxes, 0.0)  # as the original files store them
    missing = _with(ex, boxes=boxes, detected=detected)
    depth = robust.predict(missing)
    assert np.max(_percent_error(depth, ex)) < 1e-7


def _scale_bound(ex: Examples, params: RobustParams = DEFAULT_PARAMS) -> np.ndarray:
    """The largest depth scale mode may give: ``z_low + ratio * z travel`` (used boxes)."""
    cz = ex.camera[:, :, 2]
    nearest = np.max(np.where(ex.detected, cz, -np.inf), axis=1)
    spread = nearest - np.min(np.where(ex.detected, cz, np.inf), axis=1)
    return np.maximum(nearest, 0.0) + params.min_depth + params.scale_max_depth_ratio * spread


def test_scale_mode_is_exact_without_intrinsics_on_z_only_motion() -> None:
    ex = odmd_bench.generate(300, preset="odms", perturbation="normal", rng=3)
    bare = _without(ex, *INTRINSICS)
    # The odms preset reaches depth / travel of about 20: widen the prior to cover it.
    wide = replace(DEFAULT_PARAMS, scale_max_depth_ratio=30.0)
    assert np.max(_percent_error(robust.predict(bare, wide, mode="scale"), ex)) < 1e-7
    # With the default prior, exact wherever the true depth is inside it, and never above it.
    depth = robust.predict(bare, mode="scale")
    bound = _scale_bound(ex)
    inside = ex.depth <= bound
    assert 0 < inside.sum() < len(ex)
    assert np.max(_percent_error(depth[inside], ex.subset(inside))) < 1e-7
    assert np.all(depth <= bound * (1 + 1e-12))
    assert np.all(depth[~inside] > 0.8 * bound[~inside])


def test_scale_mode_is_the_posterior_median_it_states() -> None:
    """Independent check of scale mode's median by dense quadrature.

    A dense quadrature of the stated integrand (per unit log Z,
    RSS(Z)^-(k-1) / Z^2 on the prior's range) has its median where scale mode says.
    """
    ex = odmd_bench.generate(6, preset="odms", perturbation="object", rng=21)
    depth = robust.predict(ex, mode="scale")
    bound = _scale_bound(ex)
    low = np.maximum(ex.camera[:, :, 2].max(axis=1), 0.0) + DEFAULT_PARAMS.min_depth
    for i in range(len(ex)):
        x = np.linspace(np.log(low[i]), np.log(bound[i]), 400_001)
        zi = np.exp(x)[:, None] - ex.camera[i, :, 2][None]
        v = np.log(ex.boxes[i, :, 2:4])[None] + np.log(zi)[:, :, None]
        rss = ((v - v.mean(axis=1, keepdims=True)) ** 2).sum(axis=(1, 2))
        logp = -(ex.n_obs - 1) * np.log(rss) - 2 * x
        cdf = np.cumsum(np.exp(logp - logp.max()))
        median = np.exp(x[np.searchsorted(cdf, 0.5 * cdf[-1])])
        assert abs(depth[i] / median - 1) < 1e-3, i


def test_scale_mode_unresolvable_examples_stay_bounded_and_are_counted() -> None:
    ex = odmd_bench.generate(40, preset="odms", perturbation="normal", rng=22)
    frozen = np.repeat(ex.boxes[:, -1:, :], ex.n_obs, axis=1)  # no expansion at all
    depth, counts = robust.predict_report(_with(ex, boxes=frozen), mode="scale")
    assert np.all(np.isfinite(depth)) and np.all(depth > 0)
    assert np.all(depth <= _scale_bound(ex) * (1 + 1e-12))
    assert counts["fit_failed"] == 0
    still = np.zeros_like(ex.camera)  # the camera never moves: nothing to resolve
    depth, counts = robust.predict_report(_with(ex, camera=still), mode="scale")
    assert counts["fit_failed"] == len(ex) and np.all(depth == 0.0)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    fx=st.floats(150.0, 600.0),
    aspect=st.floats(0.8, 1.25),
    cx_frac=st.floats(0.4, 0.6),
    cy_frac=st.floats(0.4, 0.6),
    seed=st.integers(0, 2**31 - 1),
)
def test_exact_for_other_cameras(fx: float, aspect: float, cx_frac: float, cy_frac: float, seed: int) -> None:
    camera = CameraConfig(
        image_width=640, image_height=480, fx=fx, fy=fx * aspect, cx=640 * cx_frac, cy=480 * cy_frac
    )
    # Far enough for any of these cameras to keep the object in view, and a camera
    # travel of at least 0.1 m so that depth / travel stays below max_depth_ratio.
    config = GeneratorConfig(camera=camera, initial_depth=(1.2, 1.5), move_min=(0.05, 0.05, 0.1))
    ex = odmd_bench.generate(64, preset=config, perturbation="normal", rng=seed)
    assert np.max(_percent_error(robust.predict(ex), ex)) < 1e-6


def test_intrinsics_argument_overrides_the_sets() -> None:
    ex = odmd_bench.generate(200, perturbation="normal", rng=4)
    right = tuple(float(ex.attrs[k]) for k in INTRINSICS)
    depth = robust.predict(_without(ex, *INTRINSICS), intrinsics=right)  # type: ignore[arg-type]
    assert np.max(_percent_error(depth, ex)) < 1e-7
    wrong = (right[0] * 1.5,) + right[1:]
    assert np.mean(_percent_error(robust.predict(ex, intrinsics=wrong), ex)) > 1.0  # type: ignore[arg-type]


# --- robustness -------------------------------------------------------------------------


def _one_wrong_box(n: int, seed: int) -> tuple[Examples, np.ndarray]:
    """Noise-free examples, each with one box swapped for another example's box."""
    ex = odmd_bench.generate(n, perturbation="normal", rng=seed)
    rng = np.random.default_rng(seed)
    obs = rng.integers(0, ex.n_obs, n)
    donor = (np.arange(n) + rng.integers(1, n, n)) % n
    boxes = ex.boxes.copy()
    boxes[np.arange(n), obs] = ex.boxes[donor, obs]
    return _with(ex, boxes=boxes), obs


def test_a_wrong_detection_is_down_weighted() -> None:
    ex, _ = _one_wrong_box(400, seed=5)
    robust_err = _percent_error(robust.predict(ex), ex)
    least_squares = replace(DEFAULT_PARAMS, loss="linear")
    ls_err = _percent_error(robust.predict(ex, least_squares), ex)
    assert np.median(robust_err) < 0.1
    assert np.mean(robust_err) < 0.25 * np.mean(ls_err)


def test_noise_model_follows_the_perturbation() -> None:
    camera = odmd_bench.generate(600, perturbation="camera", rng=6)
    boxes = odmd_bench.generate(600, perturbation="object", rng=6)
    _, c_model, _ = robust.predict_details(camera)
    _, b_model, _ = robust.predict_details(boxes)
    # Model 0 doubts the camera positions, model 1 the boxes.
    assert np.mean(c_model == 0) > 0.9
    assert np.mean(b_model == 1) > 0.9


def test_camera_corrections_help_under_camera_noise() -> None:
    ex = odmd_bench.generate(600, perturbation="camera", rng=7)
    with_prior = np.mean(_percent_error(robust.predict(ex), ex))
    no_prior = replace(DEFAULT_PARAMS, noise_models=(NoiseModel(2e-4, 0.0),))
    without = np.mean(_percent_error(robust.predict(ex, no_prior), ex))
    assert with_prior < 0.7 * without


def test_depth_keeps_the_object_in_front_of_every_camera() -> None:
    ex = odmd_bench.generate(800, perturbation="both", rng=8)
    depth = robust.predict(ex)
    nearest = np.max(np.where(ex.detected, ex.camera[:, :, 2], -np.inf), axis=1)
    assert np.all(depth > nearest)


def test_boxes_that_never_change_do_not_run_away() -> None:
    ex = odmd_bench.generate(50, perturbation="normal", rng=16)
    frozen = np.repeat(ex.boxes[:, -1:, :], ex.n_obs, axis=1)  # no expansion, no parallax
    travel = np.max(np.linalg.norm(ex.camera, axis=2), axis=1)
    depth = robust.predict(_with(ex, boxes=frozen))
    assert np.all(np.isfinite(depth))
    assert np.all(depth <= DEFAULT_PARAMS.max_depth_ratio * travel * (1 + 1e-12))
    # Run to the end, every fit reaches the far bound: no depth resolved, all counted.
    long_run = replace(DEFAULT_PARAMS, iterations=200)
    depth, counts = robust.predict_report(_with(ex, boxes=frozen), long_run)
    assert counts["fit_failed"] == len(ex)
    assert np.all(depth <= DEFAULT_PARAMS.max_depth_ratio * travel * (1 + 1e-12))


# --- behaviour of the function ----------------------------------------------------------


def test_examples_are_independent_of_their_batch() -> None:
    ex = odmd_bench.generate(300, perturbation="both", rng=9)
    full = robust.predict(ex)
    perm = np.random.default_rng(1).permutation(len(ex))
    np.testing.assert_allclose(robust.predict(ex.subset(perm)), full[perm], rtol=1e-12)
    np.testing.assert_allclose(robust.predict(ex.subset(slice(17, 18))), full[17:18], rtol=1e-12)


def test_chunking_does_not_change_results(monkeypatch: pytest.MonkeyPatch) -> None:
    ex = odmd_bench.generate(100, perturbation="both", rng=15)
    whole, whole_counts = robust.predict_report(ex)
    monkeypatch.setattr(robust.model, "CHUNK", 7)
    chunked, chunked_counts = robust.predict_report(ex)
    np.testing.assert_array_equal(chunked, whole)
    assert chunked_counts == whole_counts


def test_inputs_are_not_modified() -> None:
    ex = odmd_bench.generate(100, perturbation="both", rng=10)
    before = {k: getattr(ex, k).copy() for k in ("boxes", "detected", "camera", "depth")}
    robust.predict(ex)
    robust.predict(ex, missing="fill")
    for k, v in before.items():
        np.testing.assert_array_equal(getattr(ex, k), v)


def test_too_few_detections_give_zero_and_are_counted() -> None:
    ex = odmd_bench.generate(5, perturbation="normal", rng=11)
    detected = ex.detected.copy()
    detected[0] = False
    detected[1] = False
    detected[1, 4] = True
    depth, counts = robust.predict_report(_with(ex, detected=detected))
    assert depth[0] == 0.0 and depth[1] == 0.0
    assert counts["too_few_detections"] == 2
    assert np.max(_percent_error(depth[2:], ex.subset(slice(2, None)))) < 1e-7


def test_fill_rule_equals_omit_when_nothing_is_missing_and_differs_otherwise() -> None:
    ex = odmd_bench.generate(200, perturbation="object", rng=12)
    np.testing.assert_allclose(robust.predict(ex, missing="fill"), robust.predict(ex), rtol=1e-12)
    detected = ex.detected.copy()
    detected[:, 3] = False
    gappy = _with(ex, detected=detected, boxes=np.where(detected[:, :, None], ex.boxes, 0.0))
    assert not np.allclose(robust.predict(gappy, missing="fill"), robust.predict(gappy))


def test_no_intrinsics_is_a_clear_error() -> None:
    ex = _without(odmd_bench.generate(10, rng=13), "fx")
    with pytest.raises(DataError, match="calibrated.*--mode scale; mode='scale'"):
        robust.predict(ex)


def test_bad_arguments_are_usage_errors() -> None:
    ex = odmd_bench.generate(10, rng=14)
    with pytest.raises(UsageError, match="mode"):
        robust.predict(ex, mode="fast")  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="missing"):
        robust.predict(ex, missing="drop")  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="intrinsics"):
        robust.predict(ex, intrinsics=(0.0, 1.0, 1.0, 1.0, 640.0, 480.0))
    with pytest.raises(UsageError) as info:
        RobustParams(loss="l2", loss_scale=-1.0, noise_models=())
    assert len(info.value.problems) == 3
    with pytest.raises(UsageError) as info:
        RobustParams(scale_max_depth_ratio=0.0, scale_grid=4, scale_refinements=-1)
    assert len(info.value.problems) == 3


# --- hyperparameters were chosen on val, and the numbers on the original sets ----------

RESULTS = Path(robust.__file__).parent.with_name("robust_search_results.csv")


def test_defaults_are_the_best_row_of_the_val_search() -> None:
    from odmd_bench_baselines.robust_search import Trial, describe

    with RESULTS.open(newline="") as fh:
        best = next(csv.DictReader(fh))
    expected = describe(Trial("", DEFAULT_PARAMS))
    for key in expected:
        if key != "stage":
            assert best[key] == expected[key], key
    assert not any("test" in key for key in best)


def test_paper_test_sets_beat_dbox(paper_data_dir: Path) -> None:
    sets = odmd_bench.load_split("test", "odmd-paper", paper_data_dir)
    errors = {name: float(np.mean(_percent_error(robust.predict(ex), ex))) for name, ex in sets.items()}
    assert errors["normal"] < 1e-6
    assert errors["object"] < 3.0
    assert np.mean(list(errors.values())) < 4.47  # DBox_p, the paper's best


def test_odms_detection_sets_need_scale_mode(paper_data_dir: Path) -> None:
    ex = odmd_bench.load("val", "normal", benchmark="odms-detection", data_dir=paper_data_dir)
    with pytest.raises(DataError, match="odms-detection"):
        robust.predict(ex)
    depth, counts = robust.predict_report(ex, mode="scale")
    assert depth.shape == (len(ex),) and np.all(np.isfinite(depth))
    assert counts["fit_failed"] == 0


def test_scale_mode_on_odms_val_is_bounded_and_no_worse_than_box_ls(paper_data_dir: Path) -> None:
    """The acceptance criterion of scale mode, on the val sets it was designed on.

    Every depth inside the prior (at most 6 times the camera travel beyond the nearest camera,
    so no runaway), and a mean percent error no worse than Box_LS on each set.
    """
    from odmd_bench_baselines import box_ls

    sets = odmd_bench.load_split("val", "odms-detection", paper_data_dir)
    for name, ex in sets.items():
        depth, counts = robust.predict_report(ex, mode="scale")
        assert counts["fit_failed"] == 0 and counts["too_few_detections"] == 0, name
        assert np.all(depth > 0) and np.all(depth <= _scale_bound(ex) * (1 + 1e-12)), name
        ours = float(np.mean(_percent_error(depth, ex)))
        theirs = float(np.mean(_percent_error(box_ls.predict(ex), ex)))
        assert ours <= theirs, (name, ours, theirs)


def test_fit_minimises_the_stated_objective() -> None:
    """Independent check with torch autograd of the full-mode optimum.

    The depth found minimises the profile of
    sum_i rho(|r_i|^2 / sigma_box^2) + |delta|^2 / sigma_camera^2 (other unknowns optimised).
    """
    torch = pytest.importorskip("torch")
    torch.set_num_threads(1)
    ex = odmd_bench.generate(3, perturbation="both", rng=3)
    nm = DEFAULT_PARAMS.noise_models[0]
    params = replace(DEFAULT_PARAMS, noise_models=(nm,), iterations=200, tolerance=1e-13)
    zhat = robust.predict(ex, params)
    fx, fy, cx, cy, width, height = ex.intrinsics()
    a, b, u0, v0 = fx / width, fy / height, cx / width, cy / height
    c2, var_box, var_cam = params.loss_scale**2, nm.sigma_box**2, nm.sigma_camera**2

    def profile(i: int, z: float) -> float:
        g, cam = torch.tensor(ex.boxes[i]), torch.tensor(ex.camera[i])
        zi0 = z - cam[:, 2]
        t = torch.stack(
            [
                ((g[:, 0] - u0) * zi0 + a * cam[:, 0]).mean(),
                ((g[:, 1] - v0) * zi0 + b * cam[:, 1]).mean(),
                (g[:, 2] * zi0).mean(),
                (g[:, 3] * zi0).mean(),
            ]
        ).requires_grad_(True)
        d = torch.zeros(ex.n_obs - 1, 3, dtype=torch.float64, requires_grad=True)
        opt = torch.optim.LBFGS(
            [t, d], max_iter=500, tolerance_grad=1e-14, tolerance_change=1e-16, line_search_fn="strong_wolfe"
        )

        def objective() -> Any:
            opt.zero_grad()
            c = cam + torch.cat([d, torch.zeros(1, 3, dtype=torch.float64)])
            zi = z - c[:, 2]
            p = torch.stack(
                [u0 + (t[0] - a * c[:, 0]) / zi, v0 + (t[1] - b * c[:, 1]) / zi, t[2] / zi, t[3] / zi], 1
            )
            s = ((g - p) ** 2).sum(1) / var_box
            loss = (c2 * torch.log1p(s / c2)).sum() + (d**2).sum() / var_cam
            loss.backward()
            return loss

        for _ in range(3):
            opt.step(objective)
        return float(objective().detach())

    for i in range(len(ex)):
        here = profile(i, float(zhat[i]))
        assert profile(i, float(zhat[i]) * 0.999) > here
        assert profile(i, float(zhat[i]) * 1.001) > here
