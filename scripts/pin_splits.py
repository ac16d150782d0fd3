"""Maintainer script: (re)write ``splits/odmd-v1.json`` and the committed robot sets.

Run only when a new benchmark version is cut (a generator change is a new generator
version, and old pinned hashes must never change):

    python scripts/pin_splits.py --original ../shared/odmd-original

It imports the original release's robot sets into ``splits/odmd-v1/robot-<split>.h5``,
generates every set from the seeds below and records sizes and content hashes.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from odmd_bench.data.generator import GENERATOR_VERSION, generate
from odmd_bench.data.importer import import_release
from odmd_bench.data.io import content_sha256, read_set, set_arrays, write_sets

ROOT = Path(__file__).resolve().parent.parent
SIZES = {"val": 2400, "test": 3000}
SEEDS = {
    ("val", "normal"): 1_100_001,
    ("val", "camera"): 1_100_002,
    ("val", "object"): 1_100_003,
    ("test", "normal"): 2_100_001,
    ("test", "camera"): 2_100_002,
    ("test", "object"): 2_100_003,
}
PERTURBATION = {"normal": "normal", "camera": "camera", "object": "object"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--original", required=True, help="the original release's data folder")
    args = ap.parse_args()
    out: dict = {
        "benchmark": "odmd-v1",
        "description": "ODMD sets by generator version 1 (preset odmd, the paper's Normal-set "
        "configuration) from fixed seeds, plus the real robot sets of the original release",
        "splits": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        import_release(args.original, tmp, benchmark="odmd-paper")
        for split, n in SIZES.items():
            entries: dict = {}
            for set_name, pert in PERTURBATION.items():
                seed = SEEDS[(split, set_name)]
                ex = generate(n, "odmd", pert, rng=seed)
                entries[set_name] = {
                    "kind": "generated",
                    "generator_version": GENERATOR_VERSION,
                    "preset": "odmd",
                    "perturbation": pert,
                    "seed": seed,
                    "n": n,
                    "sha256": content_sha256(set_arrays(ex)),
                }
            robot = read_set(Path(tmp) / "odmd-paper" / f"{split}.h5", "robot")
            robot.attrs.update(benchmark="odmd-v1", split=split)
            rel = f"odmd-v1/robot-{split}.h5"
            write_sets(
                ROOT / "splits" / rel, {"robot": robot}, file_attrs={"benchmark": "odmd-v1"}, compress=True
            )
            entries["robot"] = {
                "kind": "file",
                "file": rel,
                "source_sha256": robot.attrs["source_sha256"],
                "n": len(robot),
                "sha256": content_sha256(set_arrays(robot)),
            }
            out["splits"][split] = entries
    path = ROOT / "splits" / "odmd-v1.json"
    path.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
