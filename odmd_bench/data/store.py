"""Building, verifying and loading the benchmark files.

``odmd-v1`` is defined by ``splits/odmd-v1.json``: for each split and generated set the
generator version, preset, perturbation, seed, size and content SHA-256; for the robot
sets, the committed HDF5 file under ``splits/odmd-v1/`` and its content SHA-256.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from odmd_bench.data.examples import Examples
from odmd_bench.data.generator import GENERATOR_VERSION, generate
from odmd_bench.data.io import content_sha256, read_set, set_arrays, write_sets
from odmd_bench.data.manifests import read_manifest, splits_dir
from odmd_bench.data.registry import check_set, check_split, get_benchmark, set_file
from odmd_bench.errors import DataError

log = logging.getLogger("odmd_bench")

Progress = Callable[[str], None]


def manifest(benchmark: str) -> dict[str, Any]:
    """The pinned manifest of a generated benchmark."""
    b = get_benchmark(benchmark)
    if not b.generated:
        raise DataError(f"benchmark {benchmark!r} is imported, not generated; it has no generation manifest")
    return read_manifest(benchmark)


def build_set(benchmark: str, split: str, set_name: str) -> Examples:
    """Make one set of a generated benchmark from its manifest entry (not verified)."""
    entry = manifest(benchmark)["splits"][split][set_name]
    if entry["kind"] == "generated":
        if entry["generator_version"] != GENERATOR_VERSION:
            raise DataError(
                f"{benchmark} {split} {set_name} needs generator version {entry['generator_version']}, "
                f"this package has version {GENERATOR_VERSION}"
            )
        ex = generate(entry["n"], entry["preset"], entry["perturbation"], rng=entry["seed"])
        ex.attrs.update(source="generator", seed=entry["seed"], preset=entry["preset"])
    elif entry["kind"] == "file":
        ex = read_set(splits_dir() / entry["file"], set_name)
    else:
        raise DataError(
            f"manifest entry for {benchmark} {split} {set_name} has unknown kind {entry['kind']!r}"
        )
    ex.attrs.update(benchmark=benchmark, split=split, set=set_name)
    return ex


def check_against_manifest(benchmark: str, split: str, set_name: str, digest: str) -> str | None:
    """A problem line if ``digest`` is not the pinned hash of that set, else None."""
    entry = manifest(benchmark)["splits"][split][set_name]
    if entry["sha256"] != digest:
        return (
            f"{benchmark} {split} {set_name}: content SHA-256 {digest[:16]}... differs from "
            f"the pinned {entry['sha256'][:16]}... in splits/{benchmark}.json"
        )
    return None


def _file_is_right(path: Path, benchmark: str, split: str) -> bool:
    b = get_benchmark(benchmark)
    if not path.exists():
        return False
    try:
        for s in b.sets:
            ex = read_set(path, s)
            if check_against_manifest(benchmark, split, s, str(ex.attrs["content_sha256"])):
                return False
    except DataError:
        return False
    return True


def ensure_generated(
    benchmark: str = "odmd-v1",
    splits: Iterable[str] = ("val", "test"),
    data_dir: str | os.PathLike[str] | None = None,
    *,
    force: bool = False,
    progress: Progress | None = None,
) -> dict[str, dict[str, Any]]:
    """Write (or reuse) the files of a generated benchmark, each verified against ``splits/``.

    A file that already holds every set with its pinned hash is reused; otherwise the
    sets are generated, checked against the manifest *before* writing, written
    atomically (a temp file renamed over the old one) and read back and checked again.

    Returns ``{split: {"path": Path, "reused": bool, "sets": {set: hash}}}``.
    """
    say = progress or log.info
    b = get_benchmark(benchmark)
    out: dict[str, dict[str, Any]] = {}
    for split in splits:
        check_split(split)
        path = set_file(benchmark, split, data_dir)
        if not force and _file_is_right(path, benchmark, split):
            say(f"{path}: already up to date")
            out[split] = {"path": path, "reused": True, "sets": _hashes(path, b.sets)}
            continue
        sets: dict[str, Examples] = {}
        problems = []
        for s in b.sets:
            say(f"{benchmark} {split}: making set {s}")
            ex = build_set(benchmark, split, s)
            problem = check_against_manifest(benchmark, split, s, content_sha256(set_arrays(ex)))
            if problem:
                problems.append(problem)
            sets[s] = ex
        if problems:
            raise DataError(
                "generated data do not match the pinned hashes (nothing was written); this "
                "machine's numpy produces different numbers, or the generator changed without "
                "a version bump",
                problems,
            )
        write_sets(path, sets, file_attrs={"benchmark": benchmark, "split": split})
        if not _file_is_right(path, benchmark, split):
            raise DataError(f"{path}: written file failed verification")
        say(f"{path}: written and verified")
        out[split] = {"path": path, "reused": False, "sets": _hashes(path, b.sets)}
    return out


def _hashes(path: Path, sets: Iterable[str]) -> dict[str, str]:
    import h5py

    with h5py.File(path, "r") as f:
        return {s: str(f[s].attrs["content_sha256"]) for s in sets}


def _path_for(split: str, benchmark: str, data_dir: str | os.PathLike[str] | None) -> Path:
    b = get_benchmark(benchmark)
    check_split(split)
    path = set_file(benchmark, split, data_dir)
    if not path.exists():
        if b.generated:
            log.warning("%s is missing; generating %s %s first", path, benchmark, split)
            ensure_generated(benchmark, [split], data_dir)
        else:
            raise DataError(
                f"{benchmark} {split} is not in the data folder ({path} is missing); it is "
                "imported, not generated: run `odmd-bench import PATH/TO/odmd-original` "
                "(the original release's data folder) first"
            )
    return path


def load(
    split: str,
    set_name: str,
    benchmark: str = "odmd-v1",
    data_dir: str | os.PathLike[str] | None = None,
) -> Examples:
    """The examples of one set, read from the data folder and verified.

    A generated benchmark that is missing is generated first (logged). The set's
    content hash must match its file record and, for generated benchmarks, the pinned
    manifest.

    Example:
        >>> ex = load("test", "robot")  # doctest: +SKIP
        >>> ex.boxes.shape
        (3000, 10, 4)
    """
    b = get_benchmark(benchmark)
    check_set(b, set_name)
    path = _path_for(split, benchmark, data_dir)
    ex = read_set(path, set_name)
    if b.generated:
        problem = check_against_manifest(benchmark, split, set_name, str(ex.attrs["content_sha256"]))
        if problem:
            raise DataError(
                f"{path} is stale or altered; run `odmd-bench generate --benchmark {benchmark}` to rebuild it",
                [problem],
            )
    return ex


def load_split(
    split: str,
    benchmark: str = "odmd-v1",
    data_dir: str | os.PathLike[str] | None = None,
    sets: Iterable[str] | None = None,
) -> dict[str, Examples]:
    """``{set: examples}`` for the sets (default: all) of one split of a benchmark."""
    b = get_benchmark(benchmark)
    names = list(sets) if sets is not None else list(b.sets)
    return {s: load(split, s, benchmark, data_dir) for s in names}
