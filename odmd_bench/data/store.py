"""Building, verifying and loading the benchmark files.

Every benchmark has a pinned manifest ``splits/<benchmark>.json``: for each split and
set its size, its content SHA-256 and its metadata SHA-256 (docs/integrity.md). For
``odmd-v1`` it also says how each set is made: the generator version, preset,
perturbation and seed, or, for the robot sets, the committed HDF5 file under
``splits/odmd-v1/``. For the imported benchmarks it names the original file whose
conversion gives the set.

Every load checks a set's two hashes, its identity (benchmark, split, set) against
where it was found and, where the set is a pinned one, the pins. Writers
(:func:`ensure_generated`, the importer) hold a lock on the split's file while they
read, merge and replace it.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from odmd_bench.data.examples import Examples
from odmd_bench.data.generator import GENERATOR_VERSION, generate
from odmd_bench.data.hashing import content_sha256, group_attrs, set_arrays
from odmd_bench.data.io import read_set, write_sets
from odmd_bench.data.manifests import read_manifest, splits_dir
from odmd_bench.data.registry import (
    BENCHMARKS,
    SPLITS,
    Benchmark,
    check_set,
    check_split,
    rebuild_command,
    resolve_benchmark,
    set_file,
)
from odmd_bench.errors import DataError, MissingDataError, UsageError
from odmd_bench.outputs import clean_stale_temps, locked

log = logging.getLogger("odmd_bench")

Progress = Callable[[str], None]


def manifest(benchmark: str | Benchmark) -> dict[str, Any]:
    """The pinned manifest of a benchmark (``splits/<benchmark>.json``)."""
    return read_manifest(resolve_benchmark(benchmark).name)


def pin(benchmark: str | Benchmark, split: str, set_name: str) -> dict[str, Any]:
    """The manifest entry of one set: ``n``, ``sha256``, ``meta_sha256`` and its source."""
    b = resolve_benchmark(benchmark)
    try:
        return dict(manifest(b)["splits"][split][set_name])
    except KeyError:
        raise DataError(f"splits/{b.name}.json pins no set {split} {set_name}") from None


def build_set(benchmark: str | Benchmark, split: str, set_name: str) -> Examples:
    """Make one set of a generated benchmark from its manifest entry.

    The set is not yet checked against the pins; :func:`ensure_generated` does that.
    """
    b = resolve_benchmark(benchmark)
    if not b.generated:
        raise DataError(f"benchmark {b.name!r} is imported, not generated: run `{rebuild_command(b)}`")
    entry = pin(b, split, set_name)
    if entry["kind"] == "generated":
        if entry["generator_version"] != GENERATOR_VERSION:
            raise DataError(
                f"{b.name} {split} {set_name} needs generator version {entry['generator_version']}, "
                f"this package has version {GENERATOR_VERSION}"
            )
        ex = generate(entry["n"], entry["preset"], entry["perturbation"], rng=entry["seed"])
        ex.attrs.update(source="generator", seed=entry["seed"], preset=entry["preset"])
    elif entry["kind"] == "file":
        ex = read_set(
            splits_dir() / entry["file"],
            set_name,
            fix="the package's own files are damaged: reinstall odmd-bench",
        )
    else:
        raise DataError(f"manifest entry for {b.name} {split} {set_name} has unknown kind {entry['kind']!r}")
    ex.attrs.update(benchmark=b.name, split=split, set=set_name)
    return ex


def is_pinned(benchmark: str | Benchmark, attrs: Mapping[str, Any]) -> bool:
    """Whether a loaded set of ``benchmark`` is its pinned version.

    Loading refuses a set that differs from its pins (:func:`pin_problem`), so this is
    always True for a generated benchmark, and for an imported one exactly when the set
    is the conversion of a known original; False for a set imported with
    ``--allow-unknown`` or written by other means, whose scores do not compare with the
    paper's.
    """
    if resolve_benchmark(benchmark).generated:
        return True
    from odmd_bench.data.manifests import known_originals

    source = attrs.get("source_sha256")
    return source is not None and str(source) in known_originals()


def pin_problem(benchmark: str | Benchmark, split: str, set_name: str, attrs: dict[str, Any]) -> str | None:
    """A problem line if a set with these attributes is not its pinned version, else None.

    ``attrs`` are the set's stored attributes (``content_sha256`` and ``meta_sha256``
    included, as :func:`~odmd_bench.data.hashing.group_attrs` gives them). A set of a
    generated benchmark must always match its pins. A set of an imported benchmark
    must match them when it is the conversion of a known original file (its
    ``source_sha256`` is in ``splits/odmd-original.json``); sets imported with
    ``--allow-unknown`` or written by other means are not pinned, and are checked
    against their own hashes only.
    """
    b = resolve_benchmark(benchmark)
    if not is_pinned(b, attrs):
        return None
    entry = pin(b, split, set_name)
    source = attrs.get("source_sha256")
    if not b.generated and source != entry["source_sha256"]:
        from odmd_bench.data.manifests import known_originals

        return (
            f"{b.name} {split} {set_name}: the set is the conversion of "
            f"{known_originals()[str(source)]['path']}, not of the file pinned for it in "
            f"splits/{b.name}.json"
        )
    for key, what in (("sha256", "content_sha256"), ("meta_sha256", "meta_sha256")):
        got = str(attrs.get(what))
        if got != entry[key]:
            label = "content" if key == "sha256" else "metadata"
            return (
                f"{b.name} {split} {set_name}: {label} SHA-256 {got[:16]}... differs from "
                f"the pinned {entry[key][:16]}... in splits/{b.name}.json"
            )
    return None


def check_against_manifest(benchmark: str | Benchmark, split: str, set_name: str, digest: str) -> str | None:
    """A problem line if ``digest`` is not the pinned content hash of that set, else None."""
    b = resolve_benchmark(benchmark)
    entry = pin(b, split, set_name)
    if entry["sha256"] != digest:
        return (
            f"{b.name} {split} {set_name}: content SHA-256 {digest[:16]}... differs from "
            f"the pinned {entry['sha256'][:16]}... in splits/{b.name}.json"
        )
    return None


def read_checked(
    path: Path,
    benchmark: str | Benchmark,
    split: str,
    set_name: str,
    data_dir: str | os.PathLike[str] | None = None,
    *,
    fix: str | None = None,
) -> Examples:
    """Read one set of ``benchmark``/``split`` from ``path`` with every check of a load.

    ``fix`` replaces the default advice (run the command that rebuilds the file).

    Raises:
        DataError: damaged, altered, stale, misplaced or not the pinned set; the
            message gives the command that rebuilds it (``StorageError`` for an OS
            failure, ``MissingDataError`` for a missing file).
    """
    b = resolve_benchmark(benchmark)
    fix = fix or f"run `{rebuild_command(b, data_dir)}` to rebuild it"
    ex = read_set(path, set_name, expect={"benchmark": b.name, "split": split}, fix=fix)
    problem = pin_problem(b, split, set_name, ex.attrs)
    if problem:
        raise DataError(f"{path} is stale or altered; {fix}", [problem])
    return ex


def _why_not_right(path: Path, b: Benchmark, split: str) -> str | None:
    """None if ``path`` holds every set of the split with its pins, else why not."""
    if not path.exists() and not path.is_symlink():
        return "missing"
    try:
        for s in b.sets:
            read_checked(path, b, split, s, fix="it is rebuilt")
    except DataError as e:
        return e.render()
    return None


def ensure_generated(
    benchmark: str | Benchmark = "odmd-v1",
    splits: Iterable[str] = ("val", "test"),
    data_dir: str | os.PathLike[str] | None = None,
    *,
    force: bool = False,
    progress: Progress | None = None,
) -> dict[str, dict[str, Any]]:
    """Write (or reuse) the files of a generated benchmark, each verified against ``splits/``.

    A file that already holds every set with its pinned hashes is reused; otherwise
    (missing, damaged, altered, stale) the sets are generated, checked against the
    manifest *before* writing, written atomically (a temp file renamed over the old
    one) and read back and checked again; what was replaced, and why, is reported
    through ``progress``. The check-and-write holds the split's lock, so concurrent
    runs write each file once.

    Returns ``{split: {"path": Path, "reused": bool, "sets": {set: hash}, "replaced":
    reason or None}}``.

    Raises:
        DataError: the generated numbers do not match the pins (nothing written).
        StorageError: the file cannot be written (the message says why and what to do).
    """
    say = progress or log.info
    b = resolve_benchmark(benchmark)
    if not b.generated:
        raise DataError(f"benchmark {b.name!r} is imported, not generated: run `{rebuild_command(b)}`")
    out: dict[str, dict[str, Any]] = {}
    for split in splits:
        check_split(split)
        path = set_file(b, split, data_dir)
        for p in clean_stale_temps(path):
            say(f"removed a dead writer's temporary file {p}")
        why = None if force else _why_not_right(path, b, split)
        if not force and why is None:
            out[split] = _reused(path, b, split, say)
            continue
        with locked(path):
            if not force:  # another process may have written it while we waited
                why = _why_not_right(path, b, split)
                if why is None:
                    out[split] = _reused(path, b, split, say)
                    continue
            if why not in (None, "missing"):
                say(f"replacing {path}: {why}")
            out[split] = _write_generated(path, b, split, say)
            out[split]["replaced"] = None if why == "missing" else (why or "--force")
    return out


def _reused(path: Path, b: Benchmark, split: str, say: Progress) -> dict[str, Any]:
    """What :func:`ensure_generated` reports for a file that is already right."""
    say(f"{path}: already up to date")
    return {"path": path, "reused": True, "sets": _pinned_hashes(b, split), "replaced": None}


def _write_generated(path: Path, b: Benchmark, split: str, say: Progress) -> dict[str, Any]:
    sets: dict[str, Examples] = {}
    digests: dict[str, str] = {}
    problems = []
    for s in b.sets:
        say(f"{b.name} {split}: making set {s}")
        ex = build_set(b, split, s)
        attrs = group_attrs(ex, s, content_sha256(set_arrays(ex)))
        digests[s] = attrs["content_sha256"]
        problem = pin_problem(b, split, s, attrs)
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
    write_sets(path, sets, file_attrs={"benchmark": b.name, "split": split}, digests=digests)
    why = _why_not_right(path, b, split)
    if why is not None:
        raise DataError(f"{path}: written file failed verification: {why}")
    say(f"{path}: written and verified")
    return {"path": path, "reused": False, "sets": _pinned_hashes(b, split)}


def _pinned_hashes(b: Benchmark, split: str) -> dict[str, str]:
    """The pinned content hash of every set of a split (what a verified file holds)."""
    return {s: pin(b, split, s)["sha256"] for s in b.sets}


def _path_for(split: str, b: Benchmark, data_dir: str | os.PathLike[str] | None) -> Path:
    check_split(split)
    path = set_file(b, split, data_dir)
    if not path.exists() and not path.is_symlink():
        if b.generated:
            log.warning("%s is missing; generating %s %s first", path, b.name, split)
            ensure_generated(b, [split], data_dir)
        else:
            raise MissingDataError(
                f"{b.name} {split} is not in the data folder ({path} is missing); it is "
                f"imported, not generated: run `{rebuild_command(b, data_dir)}` "
                "(PATH/TO/odmd-original: the original release's data folder) first",
                filename=str(path),
            )
    return path


def load(
    split: str,
    set_name: str,
    benchmark: str | Benchmark = "odmd-v1",
    data_dir: str | os.PathLike[str] | None = None,
) -> Examples:
    """The examples of one set, read from the data folder and verified.

    A generated benchmark that is missing is generated first (logged). The set's
    content and metadata hashes must match its file's records, the file must be the
    one of ``benchmark``/``split`` (where it says), and a pinned set must match its
    pins (docs/integrity.md). A file that fails is refused with the command that
    rebuilds it; it is never used.

    Example:
        >>> import tempfile
        >>> tmp = tempfile.TemporaryDirectory()  # a data folder of its own
        >>> ex = load("test", "robot", data_dir=tmp.name)  # generates odmd-v1 test first
        >>> ex.boxes.shape, ex.attrs["benchmark"], ex.attrs["set"]
        ((3000, 10, 4), 'odmd-v1', 'robot')
        >>> tmp.cleanup()
    """
    known = benchmark if isinstance(benchmark, Benchmark) else BENCHMARKS.get(benchmark)
    if split not in SPLITS and set_name in SPLITS and split in getattr(known, "sets", ()):
        # load("robot", "test"): otherwise told only that "test" is no set
        name = getattr(known, "name", benchmark)
        tail = "" if name == "odmd-v1" else f", {name!r}"
        raise UsageError(
            f"load({split!r}, {set_name!r}): the split comes first, then the set: "
            f"load({set_name!r}, {split!r}{tail})"
        )
    b = resolve_benchmark(benchmark)
    check_set(b, set_name)
    path = _path_for(split, b, data_dir)
    return read_checked(path, b, split, set_name, data_dir)


def load_split(
    split: str,
    benchmark: str | Benchmark = "odmd-v1",
    data_dir: str | os.PathLike[str] | None = None,
    sets: Iterable[str] | None = None,
) -> dict[str, Examples]:
    """``{set: examples}`` for the sets (default: all) of one split of a benchmark."""
    if split not in SPLITS and isinstance(benchmark, str) and benchmark in SPLITS and split in BENCHMARKS:
        # load_split("odmd-v1", "test"): otherwise told only that "test" is no benchmark
        raise UsageError(
            f"load_split({split!r}, {benchmark!r}): the split comes first, then the benchmark: "
            f"load_split({benchmark!r}, {split!r})"
        )
    b = resolve_benchmark(benchmark)
    names = list(sets) if sets is not None else list(b.sets)
    return {s: load(split, s, b, data_dir) for s in names}
