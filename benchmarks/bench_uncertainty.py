"""The cost of the uncertainty columns: ``evaluate`` of a 12,000-row file with and without them.

Run: pytest benchmarks/bench_uncertainty.py --benchmark-only -p no:randomly -s

The issue's target: scoring the extra columns (``depth_lo``, ``depth_hi``, ``level``,
``depth_std``) adds at most 20 % to ``evaluate`` on a 12,000-row file (odmd-v1 test).
Before: the file without the columns; after: the same depths with them. Both are
measured in the same run, interleaved round by round, two ways:

- ``evaluate()`` in process (parse, the sets loaded and verified, coverage, score), as
  ``odmd_bench.evaluate`` runs;
- ``odmd-bench evaluate FILE`` as a user runs it, each a fresh process.

The medians and their ratio are printed and kept in ``benchmark.extra_info``; the
in-process ratio is asserted (at most 1.2). The predictions are seeded; the data folder
is generated once into a temporary folder (not timed).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import odmd_bench
from odmd_bench.data.store import ensure_generated
from odmd_bench.evaluation.predictions import write_predictions
from odmd_bench.evaluation.scoring import evaluate

ROUNDS = 15
CLI_ROUNDS = 7


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    data = tmp_path_factory.mktemp("bench-data")
    ensure_generated("odmd-v1", ["test"], data)
    sets = odmd_bench.load_split("test", "odmd-v1", data)
    rng = np.random.default_rng(0)
    depths = {s: ex.depth * (1 + rng.normal(0, 0.05, len(ex))) for s, ex in sets.items()}
    unc = {s: {"depth_lo": 0.9 * d, "depth_hi": 1.1 * d, "depth_std": 0.06 * d} for s, d in depths.items()}
    before, after = data / "before.csv", data / "after.csv"
    write_predictions(before, "test", depths, "odmd-v1")
    write_predictions(after, "test", depths, "odmd-v1", uncertainty=unc, level=0.9)
    assert sum(len(ex) for ex in sets.values()) == 12_000
    return data, before, after


def _interleaved(run_before, run_after, rounds: int) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    b, a = [], []
    for _ in range(rounds):
        for run, out in ((run_before, b), (run_after, a)):
            t = time.perf_counter()
            run()
            out.append(time.perf_counter() - t)
    return statistics.median(b), statistics.median(a)


def test_evaluate_in_process(benchmark, files: tuple[Path, Path, Path]) -> None:  # type: ignore[no-untyped-def]
    data, before, after = files
    assert not evaluate(before, data_dir=data).uncertainty
    assert evaluate(after, data_dir=data).all_uncertainty["coverage"] > 0

    def both() -> tuple[float, float]:
        return _interleaved(
            lambda: evaluate(before, data_dir=data), lambda: evaluate(after, data_dir=data), ROUNDS
        )

    t_before, t_after = benchmark.pedantic(both, rounds=1, iterations=1, warmup_rounds=0)
    ratio = t_after / t_before
    benchmark.extra_info.update({"before_s": t_before, "after_s": t_after, "ratio": ratio})
    print(
        f"\nevaluate() of 12,000 rows in process, median of {ROUNDS} interleaved rounds: without the columns "
        f"{t_before * 1e3:.1f} ms, with them {t_after * 1e3:.1f} ms: x{ratio:.3f}"
    )
    assert ratio <= 1.2


def test_evaluate_cli(benchmark, files: tuple[Path, Path, Path]) -> None:  # type: ignore[no-untyped-def]
    data, before, after = files
    env = {**os.environ, "ODMD_BENCH_DATA": str(data)}
    script = Path(sys.executable).parent / "odmd-bench"

    def cli(path: Path) -> None:
        subprocess.run([str(script), "evaluate", str(path)], check=True, stdout=subprocess.DEVNULL, env=env)

    def both() -> tuple[float, float]:
        return _interleaved(lambda: cli(before), lambda: cli(after), CLI_ROUNDS)

    t_before, t_after = benchmark.pedantic(both, rounds=1, iterations=1, warmup_rounds=0)
    ratio = t_after / t_before
    benchmark.extra_info.update({"before_s": t_before, "after_s": t_after, "ratio": ratio})
    print(
        f"\nodmd-bench evaluate of 12,000 rows, a fresh process each, median of {CLI_ROUNDS} interleaved rounds: "
        f"without the columns {t_before * 1e3:.0f} ms, with them {t_after * 1e3:.0f} ms: x{ratio:.3f}"
    )
