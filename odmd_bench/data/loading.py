"""Loading a benchmark's sets from the data folder: read and verified, nothing written.

Every load checks a set's two hashes, its identity (benchmark, split, set) against
where it was found and, where the set is a pinned one, its pins in ``splits/``
(:func:`~odmd_bench.data.manifests.pin_problem`). A file that fails is refused with the
command that rebuilds it; it is never used. Loading never generates: making a missing
set of a generated benchmark is a step of the entry points (``odmd_bench.load``,
``load_split``, ``evaluate``; :mod:`odmd_bench.data.store`), taken before they load.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from odmd_bench.data.examples import Examples
from odmd_bench.data.io import read_set
from odmd_bench.data.manifests import pin_problem
from odmd_bench.data.registry import Benchmark, rebuild_command, set_file
from odmd_bench.errors import DataError, MissingDataError


def read_checked(
    path: Path,
    bench: Benchmark,
    split: str,
    set_name: str,
    data_dir: str | os.PathLike[str] | None = None,
    *,
    fix: str | None = None,
) -> Examples:
    """Read one set of ``bench``/``split`` from ``path`` with every check of a load.

    ``fix`` replaces the default advice (run the command that rebuilds the file).

    Raises:
        DataError: damaged, altered, stale, misplaced or not the pinned set; the
            message gives the command that rebuilds it (``StorageError`` for an OS
            failure, ``MissingDataError`` for a missing file).
    """
    fix = fix or f"run `{rebuild_command(bench, data_dir)}` to rebuild it"
    ex = read_set(path, set_name, expect={"benchmark": bench.name, "split": split}, fix=fix)
    problem = pin_problem(bench, split, set_name, ex.attrs)
    if problem:
        raise DataError(f"{path} is stale or altered; {fix}", [problem])
    return ex


def is_missing(path: Path) -> bool:
    """Whether nothing at all is at ``path`` (a dangling link is something: a load says why)."""
    return not path.exists() and not path.is_symlink()


def split_file(bench: Benchmark, split: str, data_dir: str | os.PathLike[str] | None = None) -> Path:
    """The file of ``bench``/``split`` in the data folder, which must be there.

    Raises:
        UsageError: an unknown split.
        MissingDataError: no file there, with the command that makes it.
    """
    path = set_file(bench, split, data_dir)
    if is_missing(path):
        if bench.generated:
            how = f"run `{rebuild_command(bench, data_dir)}` first"
        else:
            how = (
                f"it is imported, not generated: run `{rebuild_command(bench, data_dir)}` "
                "(PATH/TO/odmd-original: the original release's data folder) first"
            )
        raise MissingDataError(
            f"{bench.name} {split} is not in the data folder ({path} is missing); {how}",
            filename=str(path),
        )
    return path


def read_split(
    bench: Benchmark,
    split: str,
    data_dir: str | os.PathLike[str] | None = None,
    sets: Iterable[str] | None = None,
) -> dict[str, Examples]:
    """``{set: examples}`` of the sets (default: all) of one split, each verified.

    ``sets`` are sets of ``bench`` (the entry point checked them). The file must be in
    the data folder (:func:`split_file`).
    """
    path = split_file(bench, split, data_dir)
    names = list(sets) if sets is not None else list(bench.sets)
    return {s: read_checked(path, bench, split, s, data_dir) for s in names}
