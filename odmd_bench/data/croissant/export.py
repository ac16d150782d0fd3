"""A benchmark's Croissant description exported: from the data folder, as text, written to a folder with its files."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from odmd_bench.data.croissant.description import croissant
from odmd_bench.data.croissant.vocabulary import SUFFIX
from odmd_bench.data.registry import Benchmark
from odmd_bench.outputs import atomic_paths, ensure_folder


def croissant_text(doc: Mapping[str, Any]) -> str:
    """The description as the file holds it: indented JSON, keys in the order built, a final newline."""
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


def write_croissant(
    out: str | os.PathLike[str], benchmark: Benchmark, doc: Mapping[str, Any], files: Mapping[str, bytes]
) -> list[Path]:
    """Write ``OUT/BENCHMARK.croissant.json`` and the files it describes, all or none.

    Returns:
        The paths written, the description first.

    Raises:
        StorageError: a file cannot be written (nothing is replaced then).
    """
    folder = Path(out)
    paths = [folder / f"{benchmark.name}{SUFFIX}", *(folder / rel for rel in files)]
    for p in paths:
        ensure_folder(p.parent)
    with atomic_paths(paths) as temps:
        temps[0].write_text(croissant_text(doc), encoding="utf-8")
        for tmp, data in zip(temps[1:], files.values(), strict=True):
            tmp.write_bytes(data)
    return paths


def describe_benchmark(
    benchmark: Benchmark, data_dir: str | os.PathLike[str] | None = None
) -> tuple[dict[str, Any], dict[str, bytes]]:
    """:func:`croissant` of a benchmark's sets as found in the data folder (each verified on load).

    A generated benchmark missing there is generated first; an imported one must have
    been imported (the error names the command).
    """
    from odmd_bench.data.store import load_split

    return croissant(benchmark, {s: load_split(s, benchmark, data_dir) for s in benchmark.splits})
