r"""Throughput of the robust reprojection method (target: >= 20,000 examples/s, one core).

Run (one core; the method uses no BLAS, but keep OpenBLAS to one thread all the same):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 .venv/bin/pytest benchmarks/bench_robust.py \
        --benchmark-only -p no:randomly --benchmark-columns=min,median,ops -s

Data: 12,000 generated ODMD examples, 3,000 each of the perturbations normal, camera,
object and both (preset odmd, seeds 0-3), with 2% of the examples missing one box, in
one batch; and, when the original release is present, the four ``odmd-paper`` test
sets (12,000 examples with the real robot set) as scored in the README. Throughput is
examples per second = batch / best time (``examples_per_s`` in ``extra_info``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from odmd_bench_baselines import robust

import odmd_bench

PER_SET = 3_000
ORIGINAL = Path(__file__).resolve().parents[2] / "shared" / "odmd-original"


def _concat(parts: list[odmd_bench.Examples]) -> odmd_bench.Examples:
    return odmd_bench.Examples(
        boxes=np.concatenate([p.boxes for p in parts]),
        detected=np.concatenate([p.detected for p in parts]),
        camera=np.concatenate([p.camera for p in parts]),
        depth=np.concatenate([p.depth for p in parts]),
        attrs=dict(parts[0].attrs),
    )


@pytest.fixture(scope="module")
def generated() -> odmd_bench.Examples:
    parts = [
        odmd_bench.generate(PER_SET, preset="odmd", perturbation=p, rng=seed)
        for seed, p in enumerate(("normal", "camera", "object", "both"))
    ]
    ex = _concat(parts)
    rng = np.random.default_rng(0)
    detected = ex.detected.copy()
    gaps = np.flatnonzero(rng.random(len(ex)) < 0.02)
    detected[gaps, rng.integers(0, ex.n_obs, len(gaps))] = False
    return odmd_bench.Examples(ex.boxes, detected, ex.camera, ex.depth, attrs=ex.attrs)


@pytest.fixture(scope="module")
def paper_test(tmp_path_factory: pytest.TempPathFactory) -> odmd_bench.Examples:
    src = Path(os.environ.get("ODMD_ORIGINAL", ORIGINAL))
    if not (src / "odmd").is_dir():
        pytest.skip(f"the original release is not at {src}")
    from odmd_bench.data.importer import import_release

    data = tmp_path_factory.mktemp("paper")
    import_release(src, data)
    sets = odmd_bench.load_split("test", "odmd-paper", data)
    return _concat(list(sets.values()))


def _measure(benchmark, ex: odmd_bench.Examples) -> None:
    depth = benchmark.pedantic(robust.predict, args=(ex,), rounds=5, iterations=1, warmup_rounds=1)
    assert depth.shape == (len(ex),) and np.all(np.isfinite(depth))
    rate = len(ex) / benchmark.stats.stats.min
    benchmark.extra_info["examples"] = len(ex)
    benchmark.extra_info["examples_per_s"] = round(rate)
    print(f"\nrobust: {len(ex)} examples, best {benchmark.stats.stats.min:.3f} s, {rate:,.0f} examples/s")


def test_generated_mix(benchmark, generated: odmd_bench.Examples) -> None:
    _measure(benchmark, generated)


def test_paper_test_sets(benchmark, paper_test: odmd_bench.Examples) -> None:
    _measure(benchmark, paper_test)
