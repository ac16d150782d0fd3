"""Maintainer script: (re)write the pinned manifests ``splits/<benchmark>.json``.

Run only when a new benchmark version is cut or the file format changes (a generator
change is a new generator version, and old pinned content hashes must never change):

    python scripts/pin_splits.py --original ../shared/odmd-original

It imports the original release's robot sets into ``splits/odmd-v1/robot-<split>.h5``,
generates every ``odmd-v1`` set from the seeds below and converts every known original
file of ``odmd-paper`` and ``odms-detection``, and records for each set its size, its
content SHA-256 and its metadata SHA-256 (docs/integrity.md). With ``--check`` it
writes nothing and exits 1 if a recomputed pin differs from the committed one.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from odmd_bench.data.generator import GENERATOR_VERSION, generate
from odmd_bench.data.hashing import content_sha256, group_attrs, set_arrays
from odmd_bench.data.importer import find_originals, read_original
from odmd_bench.data.io import write_sets
from odmd_bench.data.manifests import read_manifest
from odmd_bench.data.registry import BENCHMARKS

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
DESCRIPTIONS = {
    "odmd-v1": "ODMD sets by generator version 1 (preset odmd, the paper's Normal-set "
    "configuration) from fixed seeds, plus the real robot sets of the original release",
    "odmd-paper": "the original 2021 ODMD release, converted by `odmd-bench import`: each set "
    "is the conversion of the original file with SHA-256 source_sha256",
    "odms-detection": "the ODMS benchmark converted to boxes, from the original release, "
    "converted by `odmd-bench import`: each set is the conversion of the original file with "
    "SHA-256 source_sha256",
}


def _hashes(ex: Any, set_name: str) -> dict[str, Any]:
    attrs = group_attrs(ex, set_name)
    return {"n": len(ex), "sha256": attrs["content_sha256"], "meta_sha256": attrs["meta_sha256"]}


def pin_v1(originals: dict[tuple[str, str, str], Any], write_files: bool) -> dict[str, Any]:
    """The ``odmd-v1`` manifest (writing the committed robot files if asked)."""
    from odmd_bench.data.store import build_set

    out: dict[str, Any] = {"benchmark": "odmd-v1", "description": DESCRIPTIONS["odmd-v1"], "splits": {}}
    for split, n in SIZES.items():
        entries: dict[str, Any] = {}
        for set_name, pert in PERTURBATION.items():
            seed = SEEDS[(split, set_name)]
            entries[set_name] = {
                "kind": "generated",
                "generator_version": GENERATOR_VERSION,
                "preset": "odmd",
                "perturbation": pert,
                "seed": seed,
                "n": n,
                "sha256": content_sha256(set_arrays(generate(n, "odmd", pert, rng=seed))),
            }
        paper = originals[("odmd-paper", split, "robot")]
        robot = dataclasses.replace(paper, attrs={**paper.attrs, "benchmark": "odmd-v1", "split": split})
        rel = f"odmd-v1/robot-{split}.h5"
        if write_files:
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
    # The metadata hashes are those of the sets as `generate` builds them.
    for split, entries in out["splits"].items():
        for set_name, entry in entries.items():
            ex = build_set(BENCHMARKS["odmd-v1"], split, set_name)
            h = _hashes(ex, set_name)
            if h["sha256"] != entry["sha256"]:
                sys.exit(f"odmd-v1 {split} {set_name}: built set differs from the one pinned now; rerun")
            entry["meta_sha256"] = h["meta_sha256"]
    return out


def pin_imported(benchmark: str, originals: dict[tuple[str, str, str], Any]) -> dict[str, Any]:
    """The manifest of an imported benchmark."""
    out: dict[str, Any] = {"benchmark": benchmark, "description": DESCRIPTIONS[benchmark], "splits": {}}
    for split in ("val", "test"):
        entries: dict[str, Any] = {}
        for set_name in BENCHMARKS[benchmark].sets:
            ex = originals[(benchmark, split, set_name)]
            entries[set_name] = {
                "kind": "import",
                "source": ex.attrs["source_file"],
                "source_sha256": ex.attrs["source_sha256"],
                **_hashes(ex, set_name),
            }
        out["splits"][split] = entries
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--original", required=True, help="the original release's data folder")
    ap.add_argument("--check", action="store_true", help="compare with the committed pins; write nothing")
    args = ap.parse_args()
    originals: dict[tuple[str, str, str], Any] = {}
    for path in find_originals(args.original):
        ex = read_original(path)
        originals[(ex.attrs["benchmark"], ex.attrs["split"], ex.attrs["set"])] = ex
    manifests = {"odmd-paper": pin_imported("odmd-paper", originals)}
    manifests["odms-detection"] = pin_imported("odms-detection", originals)
    manifests["odmd-v1"] = pin_v1(originals, write_files=not args.check)
    differ = []
    for name, data in manifests.items():
        path = ROOT / "splits" / f"{name}.json"
        if args.check:
            read_manifest.cache_clear()
            if read_manifest(name) != data:
                differ.append(name)
            continue
        path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
        print(f"wrote {path}")
    if differ:
        sys.exit(f"pins differ from the committed ones: {', '.join(differ)}")


if __name__ == "__main__":
    main()
