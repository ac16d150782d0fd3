r"""Box_LS throughput: the batched closed-form solve against a per-example lstsq loop.

Run (one core: keep OpenBLAS to one thread):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 .venv/bin/pytest benchmarks/bench_box_ls.py \
        --benchmark-only -p no:randomly --benchmark-columns=min,median,ops -s

The reference is what the original release does: build the paper's ``A`` (2 n x 3) and
``b`` for one example at a time and solve with ``numpy.linalg`` in a Python loop.
Throughput is examples per second = batch / best time; ``test_ratio`` measures both in
the same run and prints the ratio. The data are ODMD-like examples (preset odmd,
perturbation both, seed 0) with 2% of the examples missing one box, so that
``predict_report`` also fills and re-solves.
"""

from __future__ import annotations

import numpy as np
import pytest
from odmd_bench_baselines import box_ls

import odmd_bench

BATCH = 1_000_000
REFERENCE_BATCH = 5_000


@pytest.fixture(scope="module")
def examples() -> odmd_bench.Examples:
    base = odmd_bench.generate(20_000, preset="odmd", perturbation="both", rng=0)
    rng = np.random.default_rng(0)
    pick = rng.integers(0, len(base), BATCH)
    detected = base.detected[pick].copy()
    gaps = rng.random(BATCH) < 0.02
    detected[gaps, rng.integers(0, base.n_obs, int(gaps.sum()))] = False
    return odmd_bench.Examples(
        boxes=base.boxes[pick], detected=detected, camera=base.camera[pick], depth=base.depth[pick]
    )


def reference_box_ls(ex: odmd_bench.Examples) -> np.ndarray:
    """The paper's A x = b, one ``numpy.linalg.lstsq`` solve per example (boxes filled)."""
    boxes = odmd_bench.fill_missing(ex.boxes, ex.detected)
    n_obs = ex.n_obs
    out = np.empty(len(ex))
    a = np.zeros((2 * n_obs, 3))
    a[:n_obs, 1] = 1.0
    a[n_obs:, 2] = 1.0
    for i in range(len(ex)):
        w, h, cz = boxes[i, :, 2], boxes[i, :, 3], ex.camera[i, :, 2]
        a[:n_obs, 0], a[n_obs:, 0] = w, h
        out[i] = np.linalg.lstsq(a, np.concatenate((w * cz, h * cz)), rcond=None)[0][0]
    return out


def test_solve(benchmark, examples: odmd_bench.Examples) -> None:
    """The closed-form solve alone (boxes complete)."""
    b, cz = examples.boxes, examples.camera[:, :, 2]
    depth, _ = benchmark.pedantic(box_ls.solve, args=(b[:, :, 2], b[:, :, 3], cz), rounds=10, iterations=1)
    assert depth.shape == (BATCH,)
    benchmark.extra_info["examples_per_second"] = BATCH / benchmark.stats.stats.min


def test_predict_report(benchmark, examples: odmd_bench.Examples) -> None:
    """The whole method: solve, fill and re-solve the 2% with a gap, count fallbacks."""
    depth, counts = benchmark.pedantic(box_ls.predict_report, args=(examples,), rounds=10, iterations=1)
    assert np.isfinite(depth).all()
    benchmark.extra_info["examples_per_second"] = BATCH / benchmark.stats.stats.min


def test_reference_lstsq_loop(benchmark, examples: odmd_bench.Examples) -> None:
    part = examples.subset(slice(0, REFERENCE_BATCH))
    depth = benchmark.pedantic(reference_box_ls, args=(part,), rounds=3, iterations=1)
    np.testing.assert_allclose(depth, box_ls.predict(part), rtol=1e-9, atol=1e-12)
    benchmark.extra_info["examples_per_second"] = REFERENCE_BATCH / benchmark.stats.stats.min


@pytest.mark.benchmark(disable_gc=True)
def test_ratio(benchmark, examples: odmd_bench.Examples, best_of) -> None:
    """Both in one run: batched examples/s divided by reference examples/s (best of rounds)."""
    b, cz = examples.boxes, examples.camera[:, :, 2]
    part = examples.subset(slice(0, REFERENCE_BATCH))
    solve = BATCH / best_of(lambda: box_ls.solve(b[:, :, 2], b[:, :, 3], cz), 10)
    whole = BATCH / best_of(lambda: box_ls.predict_report(examples), 10)
    slow = REFERENCE_BATCH / best_of(lambda: reference_box_ls(part), 3)
    benchmark.extra_info.update(
        solve_per_s=solve,
        predict_report_per_s=whole,
        reference_per_s=slow,
        ratio_solve=solve / slow,
        ratio_predict_report=whole / slow,
    )
    print(
        f"\nBox_LS solve {solve:,.0f}/s  predict_report {whole:,.0f}/s  "
        f"lstsq loop {slow:,.0f}/s  ratio {solve / slow:,.0f}x (solve), {whole / slow:,.0f}x (predict_report)"
    )
    benchmark.pedantic(lambda: None, rounds=1)
