"""The data folder's entry points: generate a benchmark's files, load its sets.

:func:`ensure_generated` writes (or reuses) the files of a generated benchmark, each
checked against its pins in ``splits/`` (:mod:`odmd_bench.data.manifests`); it holds a
lock on the split's file while it reads, merges and replaces it. :func:`load` and
:func:`load_split` take a benchmark's name or object, resolve it once, generate a
missing split of a generated benchmark first (the one step that writes), and then load
it through :mod:`odmd_bench.data.loading`, which reads and verifies and writes nothing.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from odmd_bench.data.examples import Examples
from odmd_bench.data.generator import GENERATOR_VERSION, generate
from odmd_bench.data.hashing import content_sha256, group_attrs, set_arrays
from odmd_bench.data.io import read_set, write_sets
from odmd_bench.data.loading import is_missing, read_checked, read_split
from odmd_bench.data.manifests import pin, pin_problem, splits_dir
from odmd_bench.data.registry import (
    BENCHMARKS,
    SPLITS,
    Benchmark,
    check_set,
    rebuild_command,
    resolve_benchmark,
    set_file,
)
from odmd_bench.errors import DataError, UsageError
from odmd_bench.outputs import clean_stale_temps, locked

log = logging.getLogger("odmd_bench")

Progress = Callable[[str], None]


def build_set(b: Benchmark, split: str, set_name: str) -> Examples:
    """Make one set of a generated benchmark from its manifest entry.

    The set is not yet checked against the pins; :func:`ensure_generated` does that.
    """
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


def _why_not_right(path: Path, b: Benchmark, split: str) -> str | None:
    """None if ``path`` holds every set of the split with its pins, else why not."""
    if is_missing(path):
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
    return {split: _ensure_split(set_file(b, split, data_dir), b, split, force, say) for split in splits}


def _ensure_split(path: Path, b: Benchmark, split: str, force: bool, say: Progress) -> dict[str, Any]:
    """:func:`ensure_generated` for one split of ``b``, whose file is ``path``."""
    for p in clean_stale_temps(path):
        say(f"removed a dead writer's temporary file {p}")
    why = None if force else _why_not_right(path, b, split)
    if force or why is not None:
        with locked(path):
            if not force:  # another process may have written it while we waited
                why = _why_not_right(path, b, split)
            if force or why is not None:
                if why not in (None, "missing"):
                    say(f"replacing {path}: {why}")
                out = _write_generated(path, b, split, say)
                out["replaced"] = None if why == "missing" else (why or "--force")
                return out
    return _reused(path, b, split, say)


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
    return {"path": path, "reused": False, "sets": digests}  # each checked against its pin above


def _pinned_hashes(b: Benchmark, split: str) -> dict[str, str]:
    """The pinned content hash of every set of a split (what a verified file holds)."""
    return {s: pin(b, split, s)["sha256"] for s in b.sets}


def generate_missing(b: Benchmark, split: str, data_dir: str | os.PathLike[str] | None = None) -> None:
    """Generate ``split`` of ``b`` first where its file is missing and ``b`` is generated (logged).

    The step an entry point takes before it loads: a missing split of an imported
    benchmark is left for the load to refuse, with the command that imports it.
    """
    path = set_file(b, split, data_dir)
    if b.generated and is_missing(path):
        log.warning("%s is missing; generating %s %s first", path, b.name, split)
        _ensure_split(path, b, split, False, log.info)


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
    return _load(split, resolve_benchmark(benchmark), [set_name], data_dir)[set_name]


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
    return _load(split, b, list(sets) if sets is not None else list(b.sets), data_dir)


def _load(
    split: str, b: Benchmark, names: list[str], data_dir: str | os.PathLike[str] | None
) -> dict[str, Examples]:
    """The sets ``names`` of ``b``/``split``, checked, generated first where missing, verified."""
    for s in names:
        check_set(b, s)
    generate_missing(b, split, data_dir)
    return read_split(b, split, data_dir, names)
