"""``evaluate`` and ``generate`` of an earlier commit against this checkout, fresh processes.

Run from the repository root (the environment of this checkout, with its dependencies):

    python benchmarks/before_after.py 72cdd90

The earlier commit is extracted with ``git archive`` into a temporary folder (its
``splits/`` copied to where its package reads them) and run through ``PYTHONPATH``; this
checkout runs the same way. Each round runs both, alternating which goes first; every
run is a fresh process with its own data folder. Prints the median and minimum of each.
Both commits must have the ``generate``, ``baseline box-ls`` and ``evaluate`` commands.
"""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROUNDS = 11


def _extract(rev: str, into: Path) -> None:
    archive = subprocess.run(["git", "archive", rev], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    if not (into / "odmd_bench" / "splits").exists():  # installed as odmd_bench.splits
        shutil.copytree(into / "splits", into / "odmd_bench" / "splits")


def _main_call(tree: Path) -> str:
    new = (tree / "odmd_bench" / "cli" / "main.py").exists()
    return f"from odmd_bench.cli{'.main' if new else ''} import main; main()"


def main() -> None:
    """Time both trees and print the medians."""
    rev = sys.argv[1] if len(sys.argv) > 1 else "HEAD~1"
    work = Path(tempfile.mkdtemp(prefix="odmd-before-after-"))
    (work / "before").mkdir()
    _extract(rev, work / "before")
    trees = {"before": work / "before", "after": Path.cwd().resolve()}

    def run(name: str, *args: str, data: Path | None = None) -> float:
        env = {
            **os.environ,
            "PYTHONPATH": str(trees[name]),
            "ODMD_BENCH_DATA": str(data or work / f"data-{name}"),
        }
        start = time.perf_counter()
        cmd = [sys.executable, "-c", _main_call(trees[name]), *args]
        # From the temporary folder: `-c` puts the current folder first on sys.path.
        subprocess.run(
            cmd, env=env, cwd=work, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        return time.perf_counter() - start

    for name in trees:
        run(name, "generate")
        run(name, "baseline", "box-ls", "-o", str(work / f"{name}.csv"))
    times: dict[str, dict[str, list[float]]] = {n: {"evaluate": [], "reuse": [], "new": []} for n in trees}
    for i in range(ROUNDS):
        for name in ("before", "after") if i % 2 else ("after", "before"):
            times[name]["evaluate"].append(run(name, "evaluate", str(work / f"{name}.csv")))
            times[name]["reuse"].append(run(name, "generate"))
            times[name]["new"].append(run(name, "generate", data=Path(tempfile.mkdtemp(dir=work))))
    labels = {
        "evaluate": "evaluate 12,000 rows",
        "reuse": "generate, files right",
        "new": "generate, empty folder",
    }
    for name, t in times.items():
        cells = [f"{labels[k]} median {statistics.median(v):.3f} s (min {min(v):.3f})" for k, v in t.items()]
        print(f"{name:6} ({rev if name == 'before' else 'this checkout'}): " + "; ".join(cells))
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
