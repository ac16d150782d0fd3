"""``predict``'s reader of an earlier commit against this checkout, on the 1M-row sequences file.

Run from the repository root (the environment of this checkout, with its dependencies):

    python benchmarks/reader_before_after.py 2610d0e [ROUNDS]

The file is :func:`bench_predict.sequences_file`'s (100,000 sequences of 10 observations,
about 150 MB), written once to a temporary folder. The earlier commit is extracted with
``git archive`` and run through ``PYTHONPATH``, as ``benchmarks/before_after.py`` does;
this checkout runs the same way. Each run is a fresh process that reads the file's bytes
and times one ``read_sequences`` call (checks and conversion to examples included, and
any import the reader makes on the way: pandas, here). Three readers, in an order that
turns every round:

* ``before``: the earlier commit as this processor runs it;
* ``before-float64``: the same with ``odmd_bench.inputs.decimals.use_extended = False``,
  the path of every platform whose ``long double`` is not x87's 80 bits (Windows, macOS
  on Apple silicon, Linux on ARM); skipped where the commit has no such module;
* ``after``: this checkout.

Prints the median and minimum wall and CPU time of each and the ratios of the medians
(CPU time is the steadier figure on a shared machine), with the CPU model.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from before_after import _extract  # noqa: E402

_RUN = """
import json, sys, time
data = open(sys.argv[1], "rb").read()
from odmd_bench.predict.sequences import read_sequences
if sys.argv[2] == "float64":
    from odmd_bench.inputs import decimals
    decimals.use_extended = False
wall, cpu = time.perf_counter(), time.process_time()
seqs = read_sequences(data, (640, 480))
wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
assert len(seqs) == 100_000
print(json.dumps([wall, cpu]))
"""


def _cpu_model() -> str:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return "unknown"


def main() -> None:
    """Time the readers, alternating, and print the medians."""
    rev = sys.argv[1] if len(sys.argv) > 1 else "2610d0e"
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    work = Path(tempfile.mkdtemp(prefix="odmd-reader-before-after-"))
    try:
        (work / "before").mkdir()
        _extract(rev, work / "before")
        from bench_predict import sequences_file

        path = work / "sequences.csv"
        path.write_bytes(sequences_file())
        trees = {"before": work / "before", "after": Path.cwd().resolve()}
        readers = {"before": ("before", "extended"), "after": ("after", "")}
        if (trees["before"] / "odmd_bench" / "inputs" / "decimals.py").exists():
            readers["before-float64"] = ("before", "float64")
        times: dict[str, list[tuple[float, float]]] = {name: [] for name in readers}
        names = list(readers)
        for i in range(rounds):
            for name in names[i % len(names) :] + names[: i % len(names)]:
                tree, mode = readers[name]
                env = {**os.environ, "PYTHONPATH": str(trees[tree]), "OPENBLAS_NUM_THREADS": "1"}
                out = subprocess.run(
                    [sys.executable, "-c", _RUN, str(path), mode],
                    env=env,
                    cwd=work,
                    check=True,
                    capture_output=True,
                    text=True,
                ).stdout
                times[name].append(tuple(json.loads(out)))  # type: ignore[arg-type]
        print(f"CPU: {_cpu_model()}; {rounds} rounds; file {path.stat().st_size / 1e6:.0f} MB")
        med = {
            n: (statistics.median(w for w, _ in t), statistics.median(c for _, c in t))
            for n, t in times.items()
        }
        for name, t in times.items():
            print(
                f"{name:15} wall median {med[name][0]:.2f} s (min {min(w for w, _ in t):.2f}), "
                f"CPU median {med[name][1]:.2f} s (min {min(c for _, c in t):.2f})"
            )
        for name in (n for n in names if n != "after"):
            print(
                f"after / {name}: wall {med['after'][0] / med[name][0]:.2f}, CPU {med['after'][1] / med[name][1]:.2f}"
            )
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
