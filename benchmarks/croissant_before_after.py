"""``set_file_bytes`` (a set's Croissant JSON file) of an earlier commit against this checkout, per set.

Run from the repository root (the environment of this checkout):

    python benchmarks/croissant_before_after.py 7843ef5 --original ../shared/odmd-original

The earlier commit's ``odmd_bench/data/croissant/set_files.py`` (read with ``git show``) is
loaded beside this checkout's, both on the same sets in one process: every set of odmd-v1
(generated into a temporary data folder) and kitti-tracking, and with ``--original`` every
set of odmd-paper and odms-detection. Each round times both on each set, alternating which
goes first, in CPU time (``time.process_time``: a busy machine's other processes do not
count). Prints, per set, the two medians and whether the bytes are the same (they must be).
"""

from __future__ import annotations

import importlib.util
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from before_sets import arguments, cpu_model, data_folder

from odmd_bench import Examples

ROUNDS = 3
MODULE = "odmd_bench/data/croissant/set_files.py"


def _module_of(rev: str, folder: Path) -> ModuleType:
    source = subprocess.run(["git", "show", f"{rev}:{MODULE}"], check=True, capture_output=True).stdout
    path = folder / "set_files_before.py"
    path.write_bytes(source)
    spec = importlib.util.spec_from_file_location("set_files_before", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _cpu(f: Callable[[Examples], bytes], ex: Examples) -> tuple[float, bytes]:
    start = time.process_time()
    out = f(ex)
    return time.process_time() - start, out


def main() -> None:
    """Time both on every set and print a line per set, then the totals."""
    args = arguments(__doc__.split("\n", 1)[0])

    from odmd_bench import load_split
    from odmd_bench.data.croissant.set_files import set_file_bytes
    from odmd_bench.data.registry import get_benchmark

    work, data = data_folder("odmd-croissant-before-after-", args.original)
    before = _module_of(args.rev, work).set_file_bytes
    names = ["odmd-v1", "kitti-tracking"] + (["odmd-paper", "odms-detection"] if args.original else [])
    print(f"{args.rev} -> this checkout; {cpu_model()}; CPU seconds, median of {ROUNDS}")
    totals = {"before": 0.0, "after": 0.0}
    same_everywhere = True
    for name in names:
        b = get_benchmark(name)
        for split in b.splits:
            for set_name, ex in load_split(split, b, data).items():
                times: dict[str, list[float]] = {"before": [], "after": []}
                outs = {}
                for r in range(ROUNDS):
                    order = [("before", before), ("after", set_file_bytes)]
                    for which, f in order if r % 2 == 0 else order[::-1]:
                        t, outs[which] = _cpu(f, ex)
                        times[which].append(t)
                same = outs["before"] == outs["after"]
                same_everywhere &= same
                med = {k: statistics.median(v) for k, v in times.items()}
                for k in totals:
                    totals[k] += med[k]
                print(
                    f"{name:15s} {split:4s} {set_name:8s} {len(ex):5d} examples  before {med['before']:.3f} s  "
                    f"after {med['after']:.3f} s  ({med['after'] / med['before']:.2f})  same bytes: {same}"
                )
    ratio = totals["after"] / totals["before"]
    print(f"all sets: before {totals['before']:.2f} s, after {totals['after']:.2f} s ({ratio:.2f})")
    if not same_everywhere:
        sys.exit("the bytes differ")


if __name__ == "__main__":
    main()
