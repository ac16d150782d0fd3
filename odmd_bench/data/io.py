"""The HDF5 schema: writing and reading sets, checked against their hashes.

One file per benchmark and split; one group per set holding at least ``boxes``,
``detected``, ``camera`` and ``depth`` (docs/format.md) plus whatever else the source
knew, with the attributes and the two hashes of :mod:`odmd_bench.data.hashing`. Files
are written through :func:`~odmd_bench.outputs.atomic.atomic_path`.

Every OS or HDF5 failure while reading or writing becomes a
:class:`~odmd_bench.errors.StorageError` (an ``OSError``) or, for a damaged file, a
:class:`~odmd_bench.errors.DataError`, naming the path, the cause and the fix.
"""

from __future__ import annotations

import errno as errno_codes
import os
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.data.hashing import (
    CORE_ARRAYS,
    attr_value,
    content_sha256,
    group_attrs,
    meta_sha256,
    plain_value,
    set_arrays,
)
from odmd_bench.errors import DataError, MissingDataError, OdmdError, StorageError
from odmd_bench.os_errors import is_os_failure, os_cause, storage_error
from odmd_bench.outputs import atomic_path

#: Version of the file layout written here (an attribute of every file). Version 2
#: added ``meta_sha256``; files of another version are refused and rebuilt.
FORMAT_VERSION = 2

#: Exceptions h5py raises for a damaged or unreadable file.
_H5_FAILURES = (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError, AttributeError)


def write_sets(
    path: str | os.PathLike[str],
    sets: Mapping[str, Examples],
    *,
    file_attrs: Mapping[str, Any] | None = None,
    compress: bool = False,
    digests: Mapping[str, str] | None = None,
) -> dict[str, str]:
    """Write ``{set name: examples}`` to one HDF5 file, atomically.

    Each group gets the examples' ``attrs`` plus ``set``, ``n``, ``n_obs``,
    ``content_sha256`` and ``meta_sha256`` (see :func:`group_attrs`). Data-folder files
    are stored uncompressed (reading them is twice as fast, for about 30% more disk);
    ``compress`` (gzip) is for files that are committed. ``digests`` are content
    hashes the caller has just computed from these very arrays (they are not computed
    again). Returns ``{set name: content hash}``.

    Raises:
        StorageError: the file cannot be written (full disk, size limit, read-only
            folder...); nothing is left behind and an existing file is untouched.
    """
    options: dict[str, Any] = (
        {"compression": "gzip", "compression_opts": 4, "shuffle": True} if compress else {}
    )
    import h5py

    hashes: dict[str, str] = {}
    target = Path(path)
    with atomic_path(target, into_devices=False) as tmp:
        try:
            with h5py.File(tmp, "w", track_order=True) as f:
                f.attrs["format_version"] = FORMAT_VERSION
                for k, v in (file_attrs or {}).items():
                    if v is not None:
                        f.attrs[k] = attr_value(v)
                for name, ex in sets.items():
                    arrays = set_arrays(ex)
                    digest = (digests or {}).get(name) or content_sha256(arrays)
                    hashes[name] = digest
                    g = f.create_group(name, track_order=True)
                    for k, a in arrays.items():
                        g.create_dataset(k, data=a, **options)
                    for k, v in group_attrs(ex, name, digest).items():
                        g.attrs[k] = v
        except (OSError, RuntimeError) as e:
            if isinstance(e, OdmdError) or not is_os_failure(e):
                raise
            raise storage_error(e, target, "write") from None
    return hashes


def _open_h5(p: Path, fix: str | None) -> Any:
    import h5py

    if p.is_dir():
        # In the data folder a folder in a data file's place is debris: say how to clear it.
        advice = f"; remove it (rm -r {p}) and {fix}" if fix else "; give the path of an HDF5 file"
        raise StorageError(
            f"cannot read {p}: it is a folder, not a data file{advice}",
            errno=errno_codes.EISDIR,
            filename=str(p),
        )
    try:
        mode = p.stat().st_mode
    except OSError:
        mode = None  # h5py says why below
    if mode is not None and not stat.S_ISREG(mode):
        # h5py would wait forever on a pipe with no writer, or read a device without end.
        raise DataError(f"{p} is not a regular file (a pipe, socket or device)" + (f"; {fix}" if fix else ""))
    try:
        return h5py.File(p, "r")
    except FileNotFoundError:
        raise MissingDataError(
            f"no data file at {p}" + (f"; {fix}" if fix else ""), errno=errno_codes.ENOENT, filename=str(p)
        ) from None
    except _H5_FAILURES as e:
        if is_os_failure(e) and not isinstance(e, FileNotFoundError):
            raise storage_error(e, p, "read", fix) from None
        cause, _ = os_cause(e)
        raise DataError(f"{p} is not a readable HDF5 file ({cause})" + (f"; {fix}" if fix else "")) from None


def _read_error(e: BaseException, p: Path, where: str, fix: str | None) -> OdmdError:
    """A failure while reading ``where`` (in file ``p``): of the OS, or of a damaged file."""
    if is_os_failure(e):
        return storage_error(e, p, "read", fix)
    cause, _ = os_cause(e)
    return DataError(
        f"{where} is damaged and cannot be read ({type(e).__name__}: {cause}); {fix or _DEFAULT_FIX}"
    )


_DEFAULT_FIX = "delete it and generate or import again"


def read_set(
    path: str | os.PathLike[str],
    set_name: str,
    *,
    verify: bool = True,
    expect: Mapping[str, str] | None = None,
    fix: str | None = None,
) -> Examples:
    """Read one set back, checked.

    Args:
        path: the HDF5 file.
        set_name: the group to read.
        verify: check the arrays against the stored ``content_sha256``, the other
            attributes against ``meta_sha256`` and the format version.
        expect: identity the file must have where it records one, e.g.
            ``{"benchmark": "odmd-v1", "split": "test"}`` (checked against the file's
            and the group's attributes); the group's ``set`` must be ``set_name``.
        fix: the step that repairs the file, added to every error (e.g. the command
            that rebuilds it).

    Raises:
        MissingDataError: no file at ``path``.
        StorageError: the file cannot be read (permissions, a folder in its place).
        DataError: the file is damaged, altered, stale or not where it belongs.
    """
    p = Path(path)
    hint = fix or _DEFAULT_FIX
    f = _open_h5(p, fix)
    where = f"{p}:{set_name}"
    try:
        with f:
            if set_name not in f:
                raise DataError(
                    f"{p} holds no set {set_name!r} (it has: {', '.join(f.keys()) or 'none'}); {hint}"
                )
            g = f[set_name]
            missing = [k for k in CORE_ARRAYS if k not in g]
            if missing:
                raise DataError(f"{where} lacks the arrays {', '.join(missing)}; {hint}")
            members, shapes = _members(g)
            if shapes:
                raise DataError(f"{where} is not a set of examples; {hint}", shapes)
            try:
                arrays = {k: m[()] for k, m in members.items()}
            except MemoryError:
                size = sum(m.size * m.dtype.itemsize for m in members.values())
                raise DataError(
                    f"{where}: its arrays ({size:,} bytes) do not fit in memory; {hint}"
                ) from None
            attrs = {k: plain_value(v) for k, v in g.attrs.items()}
            file_attrs = {k: plain_value(v) for k, v in f.attrs.items()}
    except OdmdError:
        raise
    except _H5_FAILURES as e:
        raise _read_error(e, p, where, fix) from None
    problems = _identity_problems(file_attrs, attrs, set_name, expect or {})
    if problems:
        raise DataError(f"{where} is not the set expected here; {hint}", problems)
    if verify:
        _verify(where, file_attrs, attrs, arrays, hint)
    for k in FILE_IDENTITY:  # checked against the path above; no other file attribute is hashed
        if k in file_attrs:
            attrs.setdefault(k, file_attrs[k])
    try:
        return Examples(
            boxes=arrays.pop("boxes"),
            detected=arrays.pop("detected"),
            camera=arrays.pop("camera"),
            depth=arrays.pop("depth"),
            observation_depth=arrays.pop("observation_depth", None),
            extras=arrays,
            attrs=attrs,
        )
    except DataError as e:
        raise DataError(f"{where}: {e.message}; {hint}", e.problems) from None


#: The file attributes a set takes as its own (where it lacks them): its identity, which
#: is checked against where the file is found. Others are covered by no hash and ignored.
FILE_IDENTITY = ("benchmark", "split")


def _members(g: Any) -> tuple[dict[str, Any], list[str]]:
    """The members of set group ``g`` in file order, and what is wrong with them, looked at without reading them.

    Every member must be an array of one example per row: ``boxes`` (N, n_obs, 4) and
    nothing larger than it, so that a damaged or hostile file cannot make a reader
    allocate more than the set's size. Each member is looked up once (an HDF5 lookup
    costs more than many small arrays' reading).
    """
    import h5py

    boxes = g["boxes"]
    if not isinstance(boxes, h5py.Dataset) or len(boxes.shape) != 3 or boxes.shape[2] != 4:
        return {}, [
            f"boxes must be an (N, n_obs, 4) array, got {getattr(boxes, 'shape', type(boxes).__name__)}"
        ]
    n = boxes.shape[0]
    members: dict[str, Any] = {}
    problems = []
    for k in g:
        m = members[k] = boxes if k == "boxes" else g[k]
        if not isinstance(m, h5py.Dataset):
            problems.append(f"{k!r} is a {type(m).__name__}, not an array")
        elif not m.shape or m.shape[0] != n:
            problems.append(f"{k!r} has shape {m.shape}; every array has one row per example ({n})")
        elif m.size > boxes.size:
            problems.append(f"{k!r} has {m.size:,} values, more than boxes' {boxes.size:,}")
    return members, problems


def _identity_problems(
    file_attrs: Mapping[str, Any], attrs: Mapping[str, Any], set_name: str, expect: Mapping[str, str]
) -> list[str]:
    problems = []
    if "set" in attrs and attrs["set"] != set_name:
        problems.append(f"its group {set_name!r} says it is set {attrs['set']!r}")
    for key, want in expect.items():
        for scope, a in (("file", file_attrs), ("set", attrs)):
            if key in a and a[key] != want:
                problems.append(f"the {scope} says {key} {a[key]!r}, but it is found as {key} {want!r}")
    return problems


def _verify(
    where: str,
    file_attrs: Mapping[str, Any],
    attrs: Mapping[str, Any],
    arrays: Mapping[str, np.ndarray],
    hint: str,
) -> None:
    version = file_attrs.get("format_version")
    if version != FORMAT_VERSION:
        raise DataError(
            f"{where} has file format version {version}, this odmd-bench reads version "
            f"{FORMAT_VERSION} (it is stale); {hint}"
        )
    for key, what, actual in (
        ("content_sha256", "is corrupt or altered: its arrays", content_sha256(arrays)),
        (
            "meta_sha256",
            "is altered: its attributes (intrinsics, image size, identity...)",
            meta_sha256(attrs),
        ),
    ):
        stored = attrs.get(key)
        if stored != actual:
            raise DataError(
                f"{where} {what} hash to {actual[:16]}..., the file records {str(stored)[:16]}...; {hint}"
            )


def set_names(path: str | os.PathLike[str], fix: str | None = None) -> list[str]:
    """The sets (groups) a file holds, in file order.

    Raises:
        StorageError, DataError: as :func:`read_set`.
    """
    p = Path(path)
    f = _open_h5(p, fix)
    try:
        with f:
            return list(f.keys())
    except _H5_FAILURES as e:
        raise _read_error(e, p, str(p), fix) from None


def file_summary(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What a file holds: its attributes and, per set, size, arrays and attributes.

    Raises:
        StorageError, DataError: the file cannot be read, or is damaged.
    """
    import h5py

    p = Path(path)
    f = _open_h5(p, None)
    try:
        with f:
            if "format_version" not in f.attrs:
                raise DataError(
                    f"{p} is an HDF5 file, but not one odmd-bench writes (it has no format_version); "
                    "info reads the data files of odmd-bench generate and import"
                )
            out: dict[str, Any] = {
                "path": str(p),
                "attrs": {k: plain_value(v) for k, v in f.attrs.items()},
                "sets": {},
            }
            for name, g in f.items():
                if not isinstance(g, h5py.Group):
                    raise DataError(
                        f"{p}: {name!r} is an array where a set (a group) belongs; {_DEFAULT_FIX}"
                    )
                out["sets"][name] = {
                    "arrays": {
                        k: (str(d.dtype), list(d.shape))
                        if isinstance(d, h5py.Dataset)
                        else ("not an array", [])
                        for k, d in g.items()
                    },
                    "attrs": {k: plain_value(v) for k, v in g.attrs.items()},
                }
    except OdmdError:
        raise
    except _H5_FAILURES as e:
        raise _read_error(e, p, str(p), None) from None
    return out


__all__ = [
    "FORMAT_VERSION",
    "file_summary",
    "read_set",
    "set_names",
    "write_sets",
]
