"""The kitti-tracking import and the kitti-tracking board's share of ``leaderboard check``.

Run: OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 pytest benchmarks/bench_kitti.py --benchmark-only -p no:randomly -s

Needs the raw files (``../shared/kitti-tracking`` or ``$ODMD_KITTI_TRACKING``), else skips.
Issue 46's targets, each on one core:

- ``test_import_command``: ``odmd-bench import kitti-tracking`` of all 21 sequences, the
  command in a fresh process pinned to one core (``taskset -c 0`` where there is one),
  reading, cutting, carrying, checking the pins and writing both files: at most 10 s.
  Its CPU time is printed beside the wall time (the machine may be shared).
- ``test_build_sets``: the same in process (read and make the sets, no writing), best of
  rounds; and the strict label reader's clean-file path against its line-by-line path
  (the reference, which names problems), in the same run: the labels must be the same.
- ``test_board_scoring``: what the board adds to ``leaderboard check``: its 12 entries
  read, validated, scored against the verified sets and ranked (as ``collect`` does for
  each board): at most 1 s.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from odmd_bench.kitti.readers import labels
from odmd_bench.kitti.sets import build_sets

REPO = Path(__file__).resolve().parents[1]
ROUNDS = 3


@pytest.fixture(scope="module")
def kitti() -> Path:
    path = Path(os.environ.get("ODMD_KITTI_TRACKING", REPO.parent / "shared" / "kitti-tracking"))
    if not (path / "label_02").is_dir():
        pytest.skip(f"the KITTI tracking files are not at {path} (set ODMD_KITTI_TRACKING)")
    return path


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def test_import_command(benchmark, kitti: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    script = Path(sys.executable).parent / "odmd-bench"
    one_core = ["taskset", "-c", "0"] if shutil.which("taskset") else []
    cmd = [*one_core, str(script), "import", "kitti-tracking", str(kitti), "--data-dir", str(tmp_path)]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    cpu: list[float] = []

    def run() -> subprocess.CompletedProcess[str]:
        before = _children_cpu()
        done = subprocess.run(cmd, capture_output=True, text=True, env=env)
        cpu.append(_children_cpu() - before)
        return done

    assert run().returncode == 0  # warms the file cache
    done = benchmark.pedantic(run, rounds=ROUNDS, iterations=1)
    assert done.returncode == 0 and "(the pinned sets;" in done.stdout
    median = benchmark.stats.stats.median
    benchmark.extra_info.update({"median_s": round(median, 3), "cpu_s": round(min(cpu), 3), "target_s": 10.0})
    print(
        f"\nodmd-bench import kitti-tracking (21 sequences, {'one core' if one_core else 'no taskset'}): "
        f"median {median:.2f} s wall, least {min(cpu):.2f} s CPU (target <= 10 s)"
    )


def test_build_sets(benchmark, kitti: Path, best_of) -> None:  # type: ignore[no-untyped-def]
    sets, _ = benchmark.pedantic(lambda: build_sets(kitti), rounds=ROUNDS, iterations=1)
    assert sum(len(ex) for by_set in sets.values() for ex in by_set.values()) == 512
    files = sorted((kitti / "label_02").glob("*.txt"))
    texts = [(f, f.read_text()) for f in files]
    fast = [labels._fast_labels(t) for _, t in texts]
    careful = [labels._careful_label_rows(f, t) for f, t in texts]
    for a, b in zip(fast, careful, strict=True):
        assert a is not None and a.line.tolist() == [r[6] for r in b]
        assert a.type.tolist() == [r[2] for r in b] and a.track.tolist() == [r[1] for r in b]
        numbers = np.array([r[5] for r in b])
        assert np.array_equal(np.hstack([a.corners, a.size, a.bottom]), numbers)
    t_fast = best_of(lambda: [labels._fast_labels(t) for _, t in texts], ROUNDS)
    t_careful = best_of(lambda: [labels._careful_label_rows(f, t) for f, t in texts], ROUNDS)
    median = benchmark.stats.stats.median
    benchmark.extra_info.update(
        {
            "build_median_s": round(median, 3),
            "labels_fast_s": round(t_fast, 3),
            "labels_careful_s": round(t_careful, 3),
        }
    )
    print(
        f"\nbuild_sets (21 sequences, in process): median {median:.2f} s; the label files "
        f"(65,301 lines): clean-file path {t_fast:.2f} s, line by line {t_careful:.2f} s"
    )


def test_board_scoring(benchmark, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    from odmd_bench.evaluation.compare import SharedDraws
    from odmd_bench.leaderboard.board import _score_board, load_board_data
    from odmd_bench.leaderboard.files import discover, read_entry
    from odmd_bench.leaderboard.specs import board_spec

    root = REPO / "leaderboard"
    spec = board_spec("kitti-tracking", "test")
    load_board_data(spec.benchmark, spec.split, tmp_path)  # the data folder made once: not timed
    folders = [f for f in discover(root) if f.name == spec.folder]

    def run():  # type: ignore[no-untyped-def]
        entries = [read_entry(f, root.parent) for f in folders]
        return _score_board(spec, entries, tmp_path, None, None, SharedDraws())

    start = time.process_time()
    board, problems = benchmark.pedantic(run, rounds=5, iterations=1)
    cpu = (time.process_time() - start) / 5
    assert problems == [] and board is not None and len(board.rows) == len(folders) == 12
    median = benchmark.stats.stats.median
    benchmark.extra_info.update({"median_s": round(median, 3), "cpu_s": round(cpu, 3), "target_s": 1.0})
    print(
        f"\nkitti-tracking test board, 12 entries read, scored and ranked: median {median:.2f} s wall, {cpu:.2f} s CPU (target <= 1 s)"
    )
