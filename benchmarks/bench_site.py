r"""The leaderboard site of the committed board: its build time and its index's size.

Targets: the build <= 20 s on 2 cores, figures included; index.html <= 300 KB.

Run with the boards' data in place (``odmd-bench leaderboard check`` builds it):

    .venv/bin/pytest benchmarks/bench_site.py --benchmark-only -p no:randomly -s

``build_site`` does everything ``odmd-bench leaderboard site`` does but write the files:
build the board from the entries (every entry re-scored), the paired comparisons, the figures, the pages.
The index's size is printed (``index_bytes`` in ``extra_info``) with and without figures.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_site_build(benchmark: Any) -> None:
    pytest.importorskip("matplotlib")
    from odmd_bench.leaderboard.site import build_site

    def build() -> dict[str, bytes]:
        return build_site(REPO / "leaderboard", figures=True)[0]

    files = benchmark.pedantic(build, rounds=3, iterations=1, warmup_rounds=1)
    start = time.process_time()
    plain = build_site(REPO / "leaderboard", figures=False)[0]
    cpu_plain = time.process_time() - start
    benchmark.extra_info.update(
        {
            "files": len(files),
            "site_bytes": sum(len(v) for v in files.values()),
            "index_bytes": len(files["index.html"]),
            "index_bytes_without_figures": len(plain["index.html"]),
            "cpu_s_without_figures": cpu_plain,
        }
    )
    print(
        f"\n{len(files)} files, {sum(len(v) for v in files.values()):,} bytes; index.html "
        f"{len(files['index.html']):,} bytes ({len(plain['index.html']):,} without figures); "
        f"build without figures {cpu_plain:.2f} s of CPU"
    )
