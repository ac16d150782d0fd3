"""Maintainer script: (re)write the shipped ``kitti-tracking`` sets and their manifest.

Run only when a new rules version is cut (:data:`odmd_bench.kitti.windows.RULES_VERSION`)
or the file format changes; old pins must never change silently:

    python scripts/pin_kitti.py --kitti ../shared/kitti-tracking

It makes the sets from the KITTI tracking files (:func:`odmd_bench.kitti.sets.build_sets`),
writes them compressed to ``splits/kitti-tracking/<split>.h5`` and records for each set
its size, content SHA-256, metadata SHA-256 and the SHA-256 of its input files in
``splits/kitti-tracking.json``. With ``--check`` it writes nothing and exits 1 if a
recomputed pin differs from the committed one.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from odmd_bench.data.hashing import group_attrs
from odmd_bench.data.io import write_sets
from odmd_bench.kitti.sets import BENCHMARK, build_sets

ROOT = Path(__file__).resolve().parent.parent
DESCRIPTION = (
    "Static objects of the 21 KITTI tracking training sequences (labels under CC BY-NC-SA 3.0), "
    "windows of 10 observations every 2nd frame by rules version 1 (docs/kitti.md), camera "
    "motion from ORB-SLAM3 stereo; val sequences 0000-0009, test 0010-0020; the sets are the "
    "committed files, made by `odmd-bench import kitti-tracking`"
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kitti", type=Path, default=ROOT.parent / "shared" / "kitti-tracking")
    ap.add_argument("--check", action="store_true", help="write nothing; exit 1 if a pin differs")
    args = ap.parse_args(argv)
    sets, counts = build_sets(args.kitti)
    manifest: dict = {"benchmark": BENCHMARK, "description": DESCRIPTION, "splits": {}}
    for split, by_set in sets.items():
        rel = f"{BENCHMARK}/{split}.h5"
        entries = {}
        for name, ex in by_set.items():
            a = group_attrs(ex, name)
            entries[name] = {
                "kind": "file",
                "file": rel,
                "source_sha256": str(ex.attrs["source_sha256"]),
                "n": len(ex),
                "sha256": a["content_sha256"],
                "meta_sha256": a["meta_sha256"],
            }
        manifest["splits"][split] = entries
        if not args.check:
            write_sets(
                ROOT / "splits" / rel,
                by_set,
                file_attrs={"benchmark": BENCHMARK, "split": split},
                compress=True,
            )
        print(split, {k: len(v) for k, v in by_set.items()}, counts[split])
    path = ROOT / "splits" / f"{BENCHMARK}.json"
    text = json.dumps(manifest, indent=2) + "\n"
    if args.check:
        same = path.is_file() and path.read_text(encoding="utf-8") == text
        print("pins match" if same else f"pins differ from {path}")
        return 0 if same else 1
    path.write_text(text, encoding="utf-8")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
