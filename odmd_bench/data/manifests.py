"""The pinned manifests in ``splits/`` (installed as ``odmd_bench.splits``)."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

from odmd_bench.errors import DataError


def splits_dir() -> Path:
    """The folder holding the manifests and the committed robot sets.

    Installed, it is the package ``odmd_bench.splits``. Imported from a source checkout
    instead (Python started in the repository's root, where ``odmd_bench/`` shadows the
    installed package and has no ``splits`` inside), it is the checkout's ``splits/``.
    """
    try:
        return Path(str(resources.files("odmd_bench.splits")))
    except ModuleNotFoundError:
        checkout = Path(__file__).resolve().parents[2] / "splits"
        if (checkout / "odmd-v1.json").is_file():
            return checkout
        raise DataError(
            "the pinned manifests (odmd_bench.splits) are not installed; reinstall odmd-bench"
        ) from None


@cache
def read_manifest(name: str) -> dict[str, Any]:
    """The JSON manifest ``splits/<name>.json``."""
    path = splits_dir() / f"{name}.json"
    try:
        data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataError(f"no pinned manifest {path}") from None
    except json.JSONDecodeError as e:
        raise DataError(f"pinned manifest {path} is not valid JSON: {e}") from None
    return data


def pinned_sizes(benchmark: str, split: str) -> dict[str, int]:
    """``{set: number of examples}`` of one split as the benchmark's manifest pins them.

    Empty for a benchmark or split without a manifest entry; a set without a pinned
    ``n`` is left out.
    """
    try:
        entries = read_manifest(benchmark)["splits"][split]
    except (DataError, KeyError, TypeError):
        return {}
    return {s: int(e["n"]) for s, e in entries.items() if isinstance(e, dict) and isinstance(e.get("n"), int)}


def known_originals() -> dict[str, dict[str, Any]]:
    """``{sha256: entry}`` for every file of the original release (``splits/odmd-original.json``)."""
    files = read_manifest("odmd-original")["files"]
    return {e["sha256"]: {**e, "path": p} for p, e in files.items()}
