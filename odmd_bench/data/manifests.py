"""The pinned manifests in ``splits/`` (installed as ``odmd_bench.splits``) and the pins in them.

Every benchmark has a pinned manifest ``splits/<benchmark>.json``: for each split and
set its size, its content SHA-256 and its metadata SHA-256 (docs/integrity.md). For
``odmd-v1`` it also says how each set is made: the generator version, preset,
perturbation and seed, or, for the robot sets, the committed HDF5 file under
``splits/odmd-v1/``. For the imported benchmarks it names the original file whose
conversion gives the set. ``splits/odmd-original.json`` pins the files of the original
release.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

from odmd_bench.data.registry import Benchmark
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


_HEX64 = re.compile(r"[0-9a-f]{64}")

#: Fields of a set's pin, by kind, beside ``n``, ``sha256`` and ``meta_sha256``.
_PIN_FIELDS: dict[str, dict[str, type]] = {
    "generated": {"generator_version": int, "preset": str, "perturbation": str, "seed": int},
    "import": {"source": str, "source_sha256": str},
    "file": {"file": str, "source_sha256": str},
}


def _field_problems(entry: dict[str, Any], fields: dict[str, type], where: str) -> list[str]:
    problems = []
    for key, kind in fields.items():
        value = entry.get(key)
        if not isinstance(value, kind) or isinstance(value, bool):
            problems.append(f"{where}: {key} must be {'an integer' if kind is int else 'text'}")
        elif key.endswith("sha256") and not _HEX64.fullmatch(str(value)):
            problems.append(f"{where}: {key} must be 64 lowercase hex digits")
    return problems


def manifest_problems(name: str, data: Any) -> list[str]:
    """What is wrong with the layout of manifest ``name`` (empty when nothing is).

    A benchmark's manifest pins each set of each split (``n``, ``sha256``,
    ``meta_sha256``, and by ``kind`` how it is made); ``odmd-original`` pins each file of
    the release by ``sha256``.
    """
    if not isinstance(data, dict):
        return ["the manifest must be a JSON object"]
    if name == "odmd-original":
        files = data.get("files")
        if not isinstance(files, dict) or not files:
            return ["files must map each file of the release to its pin"]
        problems = []
        for path, entry in files.items():
            if not isinstance(entry, dict):
                problems.append(f"files[{path!r}] must be an object")
                continue
            target = {"benchmark": str, "split": str, "set": str} if "benchmark" in entry else {"kind": str}
            problems += _field_problems(entry, {"sha256": str, **target}, f"files[{path!r}]")
        return problems
    splits = data.get("splits")
    if not isinstance(splits, dict) or not splits:
        return ["splits must map each split to its sets"]
    problems = []
    for split, sets in splits.items():
        if not isinstance(sets, dict) or not sets:
            problems.append(f"splits[{split!r}] must map each set to its pin")
            continue
        for set_name, entry in sets.items():
            where = f"{split} {set_name}"
            if not isinstance(entry, dict):
                problems.append(f"{where}: the pin must be an object")
                continue
            kind = entry.get("kind")
            if kind not in _PIN_FIELDS:
                problems.append(f"{where}: kind must be one of {', '.join(_PIN_FIELDS)}")
                continue
            problems += _field_problems(entry, {"n": int, "sha256": str, "meta_sha256": str}, where)
            problems += _field_problems(entry, _PIN_FIELDS[kind], where)
            if isinstance(entry.get("n"), int) and entry["n"] < 1:
                problems.append(f"{where}: n must be at least 1")
    return problems


@cache
def read_manifest(name: str) -> dict[str, Any]:
    """The JSON manifest ``splits/<name>.json``, its layout checked (:func:`manifest_problems`).

    Raises:
        DataError: the file is missing, not JSON, or not laid out as a manifest (a
            damaged installation: the fix is to reinstall).
    """
    path = splits_dir() / f"{name}.json"
    try:
        data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataError(f"no pinned manifest {path}; reinstall odmd-bench") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise DataError(f"pinned manifest {path} cannot be read ({e}); reinstall odmd-bench") from None
    problems = manifest_problems(name, data)
    if problems:
        raise DataError(f"pinned manifest {path} is damaged; reinstall odmd-bench", problems)
    return data


def manifest(bench: Benchmark) -> dict[str, Any]:
    """The pinned manifest of a benchmark (``splits/<benchmark>.json``)."""
    return read_manifest(bench.name)


def pin(bench: Benchmark, split: str, set_name: str) -> dict[str, Any]:
    """The manifest entry of one set: ``n``, ``sha256``, ``meta_sha256`` and its source."""
    try:
        return dict(manifest(bench)["splits"][split][set_name])
    except KeyError:
        raise DataError(f"splits/{bench.name}.json pins no set {split} {set_name}") from None


def pinned_sizes(bench: Benchmark, split: str) -> dict[str, int]:
    """``{set: number of examples}`` of one split as the benchmark's manifest pins them.

    Empty for a split without a manifest entry.

    Raises:
        DataError: the manifest is missing or damaged.
    """
    try:
        entries = manifest(bench)["splits"][split]
    except KeyError:
        return {}
    return {s: int(e["n"]) for s, e in entries.items()}


def known_originals() -> dict[str, dict[str, Any]]:
    """``{sha256: entry}`` for every file of the original release (``splits/odmd-original.json``)."""
    files = read_manifest("odmd-original")["files"]
    return {e["sha256"]: {**e, "path": p} for p, e in files.items()}


def is_pinned(bench: Benchmark, attrs: Mapping[str, Any]) -> bool:
    """Whether a loaded set of ``bench`` is its pinned version.

    Loading refuses a set that differs from its pins (:func:`pin_problem`), so this is
    always True for a generated benchmark, and for an imported one exactly when the set
    is the conversion of a known original; False for a set imported with
    ``--allow-unknown`` or written by other means, whose scores do not compare with the
    paper's.
    """
    if bench.generated:
        return True
    source = attrs.get("source_sha256")
    return source is not None and str(source) in known_originals()


def pin_problem(bench: Benchmark, split: str, set_name: str, attrs: Mapping[str, Any]) -> str | None:
    """A problem line if a set with these attributes is not its pinned version, else None.

    ``attrs`` are the set's stored attributes (``content_sha256`` and ``meta_sha256``
    included, as :func:`~odmd_bench.data.hashing.group_attrs` gives them). A set of a
    generated benchmark must always match its pins. A set of an imported benchmark
    must match them when it is the conversion of a known original file (its
    ``source_sha256`` is in ``splits/odmd-original.json``); sets imported with
    ``--allow-unknown`` or written by other means are not pinned, and are checked
    against their own hashes only.
    """
    if not is_pinned(bench, attrs):
        return None
    entry = pin(bench, split, set_name)
    source = attrs.get("source_sha256")
    if not bench.generated and source != entry["source_sha256"]:
        return (
            f"{bench.name} {split} {set_name}: the set is the conversion of "
            f"{known_originals()[str(source)]['path']}, not of the file pinned for it in "
            f"splits/{bench.name}.json"
        )
    for key, what in (("sha256", "content_sha256"), ("meta_sha256", "meta_sha256")):
        got = str(attrs.get(what))
        if got != entry[key]:
            label = "content" if key == "sha256" else "metadata"
            return (
                f"{bench.name} {split} {set_name}: {label} SHA-256 {got[:16]}... differs from "
                f"the pinned {entry[key][:16]}... in splits/{bench.name}.json"
            )
    return None


def check_against_manifest(bench: Benchmark, split: str, set_name: str, digest: str) -> str | None:
    """A problem line if ``digest`` is not the pinned content hash of that set, else None."""
    entry = pin(bench, split, set_name)
    if entry["sha256"] != digest:
        return (
            f"{bench.name} {split} {set_name}: content SHA-256 {digest[:16]}... differs from "
            f"the pinned {entry['sha256'][:16]}... in splits/{bench.name}.json"
        )
    return None
