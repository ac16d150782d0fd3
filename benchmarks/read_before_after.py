"""A verified read of a set (``read_set``) of an earlier commit against this checkout.

Run from the repository root (the environment of this checkout):

    python benchmarks/read_before_after.py 118680b --original ../shared/odmd-original

The earlier commit is extracted with ``git archive`` into a temporary folder; both trees read
the same files (odmd-v1 val and test, generated once by this checkout, and with
``--original`` odmd-paper and odms-detection imported), each in a fresh process of its own
(``PYTHONPATH``), alternating which goes first. A process reads every set of those files
``REPEATS`` times with every check of a load and reports its CPU time per read
(``time.process_time``: other processes do not count) and a digest of what it read (every
array's dtype, shape and bytes, every attribute), which must be the same for both. Prints
the median over the rounds of each.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from before_after import _extract  # git archive of the commit into a folder
from before_sets import arguments, cpu_model, data_folder

ROUNDS = 5
REPEATS = 10

#: What each process runs: argv[1] the data folder, argv[2] how many reads of each set.
READ = """
import hashlib, json, sys, time
from pathlib import Path
from odmd_bench.data.io import read_set, set_names
files = sorted(Path(sys.argv[1]).glob("*/*.h5"))
sets = [(f, s) for f in files for s in set_names(f)]
digest = hashlib.sha256()
for f, s in sets:
    ex = read_set(f, s)
    arrays = {"boxes": ex.boxes, "detected": ex.detected, "camera": ex.camera, "depth": ex.depth,
              "observation_depth": ex.observation_depth, **ex.extras}
    for k in sorted(arrays):
        a = arrays[k]
        digest.update(repr((k, None if a is None else (a.dtype.str, a.shape))).encode())
        if a is not None:
            digest.update(a.tobytes())
    digest.update(json.dumps(ex.attrs, sort_keys=True, default=repr).encode())
start = time.process_time()
for _ in range(int(sys.argv[2])):
    for f, s in sets:
        read_set(f, s)
ms = (time.process_time() - start) * 1000 / (int(sys.argv[2]) * len(sets))
print(json.dumps({"ms": ms, "sets": len(sets), "digest": digest.hexdigest()}))
"""


def _run(tree: Path, data: Path) -> dict[str, object]:
    env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, "-P", "-c", READ, str(data), str(REPEATS)],
        env=env,
        check=True,
        capture_output=True,
        text=True,
        cwd=tree,
    )
    return json.loads(out.stdout.splitlines()[-1])


def main() -> None:
    """Time both trees, alternating, and print the medians."""
    args = arguments(__doc__.split("\n", 1)[0])
    work, data = data_folder("odmd-read-before-after-", args.original)
    before = work / "before"
    before.mkdir()
    _extract(args.rev, before)
    trees = {"before": before, "after": Path.cwd()}
    print(f"{args.rev} -> this checkout; {cpu_model()}")
    times: dict[str, list[float]] = {"before": [], "after": []}
    digests = set()
    for r in range(ROUNDS):
        order = list(trees) if r % 2 == 0 else list(trees)[::-1]
        for which in order:
            got = _run(trees[which], data)
            times[which].append(float(got["ms"]))  # type: ignore[arg-type]
            digests.add(got["digest"])
    n = got["sets"]
    med = {k: statistics.median(v) for k, v in times.items()}
    print(
        f"read_set, {n} sets, CPU ms a read (median of {ROUNDS} processes, {REPEATS} reads of each set): "
        f"before {med['before']:.2f}, after {med['after']:.2f} ({med['after'] / med['before']:.2f}); "
        f"same sets read: {len(digests) == 1}"
    )
    if len(digests) != 1:
        sys.exit("the two read different sets")


if __name__ == "__main__":
    main()
