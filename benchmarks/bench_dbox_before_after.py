"""DBox's speed suite of an earlier commit against this checkout's, alternating, in one run.

Run from the repository root, in this checkout's environment (not a test: it has none)::

    python benchmarks/bench_dbox_before_after.py 2610d0e --rounds 5 -k "threads1 and test_inference"

The earlier commit is extracted with ``git archive`` into a temporary folder (its
``baselines/`` linked as ``odmd_bench_baselines``, its ``splits/`` copied to where its
package reads them) and its ``benchmarks/bench_dbox.py`` runs through ``PYTHONPATH``;
this checkout's runs as installed. Each round runs both suites, alternating which goes
first, each in a fresh pytest process (``--benchmark-only``, the cases ``-k`` selects)
writing pytest-benchmark's JSON. Printed per case (tree, test, impl, threads): the median
over the rounds of each run's median, and the least and largest of them, in ms; and the
CPU model.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path


def _extract(rev: str, into: Path) -> None:
    archive = subprocess.run(["git", "archive", rev], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    (into / "odmd_bench_baselines").symlink_to("baselines")
    if not (into / "odmd_bench" / "splits").exists():  # installed as odmd_bench.splits
        shutil.copytree(into / "splits", into / "odmd_bench" / "splits")


def _cpu() -> str:
    cpuinfo = Path("/proc/cpuinfo")
    lines = cpuinfo.read_text().splitlines() if cpuinfo.exists() else []
    return next((line.split(":", 1)[1].strip() for line in lines if line.startswith("model name")), "unknown")


def main() -> None:
    """Run both suites round by round and print the medians."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("rev", help="the earlier commit")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("-k", default="threads1", help="pytest's -k: the cases to run")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="odmd-dbox-before-after-"))
    (work / "before").mkdir()
    _extract(args.rev, work / "before")
    trees = {"before": work / "before", "after": Path.cwd().resolve()}
    medians: dict[tuple[str, str, str, int], list[float]] = {}
    try:
        for i in range(args.rounds):
            for name in ("before", "after") if i % 2 else ("after", "before"):
                tree = trees[name]
                env = dict(os.environ)
                if name == "before":
                    env["PYTHONPATH"] = str(tree)
                out = work / f"{name}-{i}.json"
                cmd = [sys.executable, "-m", "pytest", str(tree / "benchmarks" / "bench_dbox.py"), "-q"]
                cmd += ["-p", "no:randomly", "-p", "no:cacheprovider", "--benchmark-only", "-k", args.k]
                cmd += ["--benchmark-json", str(out)]
                subprocess.run(cmd, cwd=tree, env=env, check=True, stdout=subprocess.DEVNULL)
                for bench in json.loads(out.read_text())["benchmarks"]:
                    info = bench["extra_info"]
                    key = (name, bench["name"].split("[")[0], str(info["impl"]), int(info["threads"]))
                    medians.setdefault(key, []).append(bench["stats"]["median"] * 1e3)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"CPU: {_cpu()}; before: {args.rev}; after: this checkout; {args.rounds} rounds, alternating")
    for (name, test, impl, threads), ms in sorted(medians.items(), key=lambda kv: kv[0][1:] + kv[0][:1]):
        print(
            f"{test:16} {impl:9} threads {threads}  {name:6}: median {statistics.median(ms):7.2f} ms "
            f"(runs {min(ms):.2f}-{max(ms):.2f})"
        )


if __name__ == "__main__":
    main()
