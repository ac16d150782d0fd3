"""The HDF5 schema: writing, reading and hashing sets; atomic, locked file writes.

One file per benchmark and split; one group per set holding at least ``boxes``,
``detected``, ``camera`` and ``depth`` (docs/format.md) plus whatever else the source
knew. Two hashes make a set's integrity (docs/integrity.md):

- ``content_sha256``, over its arrays (names, dtypes, shapes and little-endian
  bytes, in name order), never over the container's bytes, so it is the same
  whatever HDF5 library version or compression wrote the file;
- ``meta_sha256``, over every other attribute of its group (intrinsics, image size,
  identity, generator version, source...), as canonical JSON.

Every OS or HDF5 failure while reading or writing becomes a
:class:`~odmd_bench.errors.StorageError` (an ``OSError``) or, for a damaged file, a
:class:`~odmd_bench.errors.DataError`, naming the path, the cause and the fix.
"""

from __future__ import annotations

import contextlib
import errno as errno_codes
import hashlib
import json
import os
import re
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DataError, MissingDataError, OdmdError, StorageError

#: Version of the file layout written here (an attribute of every file). Version 2
#: added ``meta_sha256``; files of another version are refused and rebuilt.
FORMAT_VERSION = 2

_CORE = ("boxes", "detected", "camera", "depth")

#: Group attributes that are not covered by ``meta_sha256`` (the two hashes).
HASH_ATTRS = ("content_sha256", "meta_sha256")

#: Temporary files of a dead writer (or of any writer, after this many seconds) are
#: removed by the next writer of the same file.
STALE_TEMP_SECONDS = 3600.0

#: Exceptions h5py raises for a damaged or unreadable file.
_H5_FAILURES = (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError, AttributeError)


# --------------------------------------------------------------------- OS failures


def _cause(e: BaseException) -> tuple[str, int | None]:
    """A short cause (``File too large (errno 27)``) and the errno, where known."""
    code = e.errno if isinstance(e, OSError) and isinstance(e.errno, int) else None
    text = str(e)
    if code is None:
        m = re.search(r"errno = (\d+)", text)
        code = int(m.group(1)) if m else None
    if code is not None:
        return f"{os.strerror(code)} (errno {code})", code
    text = re.sub(r"\s+", " ", text).strip()
    # h5py repeats HDF5's long internal context in parentheses; keep its first part.
    text = re.sub(r" \(file read failed: time = .*", "", text)
    return (text[:200] + "...") if len(text) > 200 else text or type(e).__name__, None


_FIXES = {
    errno_codes.ENOSPC: "free space on that disk, or point --data-dir / $ODMD_BENCH_DATA at another folder",
    errno_codes.EFBIG: "raise the file size limit (ulimit -f), or point --data-dir / $ODMD_BENCH_DATA elsewhere",
    errno_codes.EDQUOT: "free space within your disk quota, or point --data-dir / $ODMD_BENCH_DATA elsewhere",
    errno_codes.EACCES: "make that folder writable (and its files readable), or point --data-dir / "
    "$ODMD_BENCH_DATA at a folder of yours",
    errno_codes.EPERM: "make that folder writable, or point --data-dir / $ODMD_BENCH_DATA at a folder of yours",
    errno_codes.EROFS: "that file system is read-only: point --data-dir / $ODMD_BENCH_DATA at a writable folder",
    errno_codes.ENOTDIR: "a part of that path is a file, not a folder: point --data-dir / $ODMD_BENCH_DATA "
    "at a folder",
    errno_codes.EISDIR: "a folder stands where the file belongs: remove it (rm -r PATH) and run the command again",
}


def storage_error(
    e: BaseException, path: str | os.PathLike[str], action: str, fix: str | None = None
) -> StorageError:
    """A :class:`StorageError` for ``e``: ``cannot ACTION PATH: CAUSE; FIX``."""
    cause, code = _cause(e)
    hint = fix or _FIXES.get(code or -1, "check the path and its permissions, then run the command again")
    hint = hint.replace("PATH", str(path))
    cls = MissingDataError if code == errno_codes.ENOENT else StorageError
    return cls(f"cannot {action} {path}: {cause}; {hint}", errno=code, filename=str(path))


def _is_os_failure(e: BaseException) -> bool:
    """True for an error of the operating system (not of a damaged file's contents)."""
    if isinstance(e, OSError) and isinstance(e.errno, int):
        return True
    return isinstance(e, RuntimeError | OSError) and re.search(r"errno = \d+", str(e)) is not None


def ensure_folder(folder: Path) -> None:
    """Create ``folder`` (and its parents), or raise a :class:`StorageError` saying why not."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise StorageError(
            f"cannot use {folder} as a folder: it is a file; point --data-dir / $ODMD_BENCH_DATA "
            "at a folder (or move the file away)",
            errno=errno_codes.ENOTDIR,
            filename=str(folder),
        ) from None
    except OSError as e:
        raise storage_error(e, folder, "create the folder") from None


# ------------------------------------------------------------------ atomic writes


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _temp_prefix(target: Path) -> str:
    return f".{target.name}."


def _temp_beside(target: Path) -> tuple[int, str]:
    ensure_folder(target.parent)
    try:
        # The writer's pid is in the name, so that a later writer can tell a dead
        # writer's leftover from a live writer's file (see clean_stale_temps).
        fd, tmp = tempfile.mkstemp(
            prefix=f"{_temp_prefix(target)}{os.getpid()}.", suffix=".tmp", dir=target.parent
        )
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file normal permissions
    except OSError as e:
        raise storage_error(e, target.parent, "write into") from None
    return fd, tmp


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # another user's live process, or no way to tell: keep its file
    return True


def clean_stale_temps(target: str | os.PathLike[str], max_age: float = STALE_TEMP_SECONDS) -> list[Path]:
    """Remove this package's temporary files for ``target`` left by dead writers.

    Only files named as :func:`atomic_path` names them (``.NAME.PID.XXXX.tmp`` beside
    ``target``) are considered. One is removed when its writer's process no longer
    exists on this machine, or when it is older than ``max_age`` seconds (a dead
    writer whose pid was reused; leftovers of earlier versions without a pid). A
    live writer's recent temporary file is never touched. Returns the removed paths.
    """
    target = Path(target)
    prefix = _temp_prefix(target)
    removed: list[Path] = []
    try:
        entries = list(target.parent.iterdir())
    except OSError:
        return removed
    now = time.time()
    for p in entries:
        name = p.name
        if not (name.startswith(prefix) and name.endswith(".tmp")):
            continue
        middle = name[len(prefix) : -len(".tmp")]
        pid_text, _, _ = middle.partition(".")
        try:
            st = p.lstat()
        except OSError:
            continue
        if not p.is_file() or p.is_symlink():
            continue
        old = now - st.st_mtime > max_age
        dead = pid_text.isdigit() and int(pid_text) != os.getpid() and not _pid_alive(int(pid_text))
        if old or dead:
            with contextlib.suppress(OSError):
                p.unlink()
                removed.append(p)
    return removed


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary file name beside ``path``; on success, the file is moved over ``path``.

    If the body raises (or the process dies), ``path`` is untouched: an existing good
    file is never lost and no half-written file is left under the final name (a
    SIGKILLed writer's temporary file is removed by the next writer, see
    :func:`clean_stale_temps`). OS failures of the file operations (full disk,
    read-only folder, a folder in the file's place...) raise :class:`StorageError`.
    For writers that want a file name (h5py, savefig); see also :func:`atomic_write`.
    """
    target = Path(path)
    clean_stale_temps(target)
    fd, tmp = _temp_beside(target)
    os.close(fd)
    try:
        yield Path(tmp)
        try:
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
            os.replace(tmp, target)
        except OSError as e:
            raise storage_error(e, target, "write") from None
    except OSError as e:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(e, OdmdError) or e.errno not in (
            errno_codes.ENOSPC,
            errno_codes.EFBIG,
            errno_codes.EDQUOT,
            errno_codes.EIO,
        ):
            raise
        raise storage_error(e, target, "write") from None
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` for writing; on success it replaces ``path``
    (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, mode) as fh:
        yield fh


@contextlib.contextmanager
def locked(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Hold an exclusive lock for writing ``path``, across processes.

    The lock is ``fcntl.flock`` (``msvcrt.locking`` on Windows) on the file
    ``.NAME.lock`` beside ``path``, which stays (deleting a lock file lets two
    writers lock two different files). Readers do not lock: every write replaces the
    file atomically, so a reader sees the old file or the new one. Blocks until the
    lock is free. Yields the lock file's path.
    """
    target = Path(path)
    ensure_folder(target.parent)
    lock = target.parent / f".{target.name}.lock"
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666 & ~_umask())
    except OSError as e:
        raise storage_error(e, lock, "create the lock file") from None
    try:
        if sys.platform == "win32":  # pragma: no cover - not run on Linux CI
            import msvcrt

            while True:  # LK_LOCK tries for 10 s, then raises: wait as long as flock does
                try:
                    msvcrt.locking(fd, msvcrt.LK_LOCK, 1)
                    break
                except OSError:
                    continue
        else:
            import fcntl

            fcntl.flock(fd, fcntl.LOCK_EX)
        yield lock
    finally:
        os.close(fd)  # closing the descriptor releases the lock


# ----------------------------------------------------------------------- hashing


def set_arrays(ex: Examples) -> dict[str, np.ndarray]:
    """All arrays of a set by their name in the file."""
    arrays = {name: getattr(ex, name) for name in _CORE}
    if ex.observation_depth is not None:
        arrays["observation_depth"] = ex.observation_depth
    for k, v in ex.extras.items():
        if k in arrays:
            raise DataError(f"extra array {k!r} clashes with a core array")
        arrays[k] = v
    return arrays


def content_sha256(arrays: Mapping[str, np.ndarray]) -> str:
    """SHA-256 of a set's arrays, independent of how they are stored.

    For each array in name order: its name, little-endian dtype string and shape as
    one JSON line, then its C-order little-endian bytes.
    """
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.asarray(arrays[name])
        dt = a.dtype.newbyteorder("<") if a.dtype.byteorder == ">" else a.dtype
        a = np.ascontiguousarray(a, dtype=dt)
        header = json.dumps([name, dt.str, list(a.shape)], separators=(",", ":"))
        h.update(header.encode() + b"\n")
        h.update(a.tobytes())
    return h.hexdigest()


def _py(v: Any) -> Any:
    """An attribute value as plain Python (what reading it back gives)."""
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    return v


def _attr_value(v: Any) -> Any:
    if isinstance(v, dict | list | tuple):
        return json.dumps(v, sort_keys=True)
    return v


def meta_sha256(attrs: Mapping[str, Any]) -> str:
    """SHA-256 of a set's attributes other than its two hashes, as canonical JSON.

    The JSON object has sorted keys, plain Python values (what reading the file
    back gives: ``int``, ``float``, ``bool``, ``str``) and no whitespace. Float
    values are written exactly (shortest round-trip form), so ``fx = 205.5`` and
    ``fx = 205.50000000000003`` hash differently.
    """
    body = {k: _py(v) for k, v in attrs.items() if k not in HASH_ATTRS}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def group_attrs(ex: Examples, name: str, digest: str | None = None) -> dict[str, Any]:
    """The attributes :func:`write_sets` stores for set ``name`` of ``ex``, hashes included.

    ``digest`` is the content hash if already computed.
    """
    digest = digest or content_sha256(set_arrays(ex))
    raw = {**ex.attrs, "set": name, "n": len(ex), "n_obs": ex.n_obs}
    attrs = {k: _py(_attr_value(v)) for k, v in raw.items() if v is not None and k not in HASH_ATTRS}
    attrs["content_sha256"] = digest
    attrs["meta_sha256"] = meta_sha256(attrs)
    return attrs


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# ----------------------------------------------------------------- writing, reading


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
    with atomic_path(target) as tmp:
        try:
            with h5py.File(tmp, "w", track_order=True) as f:
                f.attrs["format_version"] = FORMAT_VERSION
                for k, v in (file_attrs or {}).items():
                    if v is not None:
                        f.attrs[k] = _attr_value(v)
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
            if isinstance(e, OdmdError) or not _is_os_failure(e):
                raise
            raise storage_error(e, target, "write") from None
    return hashes


def _open_h5(p: Path, fix: str | None) -> Any:
    import h5py

    if p.is_dir():
        raise StorageError(
            f"cannot read {p}: it is a folder, not a data file; remove it (rm -r {p})"
            + (f" and {fix}" if fix else ""),
            errno=errno_codes.EISDIR,
            filename=str(p),
        )
    try:
        return h5py.File(p, "r")
    except FileNotFoundError:
        raise MissingDataError(
            f"no data file at {p}" + (f"; {fix}" if fix else ""), errno=errno_codes.ENOENT, filename=str(p)
        ) from None
    except _H5_FAILURES as e:
        if _is_os_failure(e) and not isinstance(e, FileNotFoundError):
            raise storage_error(e, p, "read", fix) from None
        cause, _ = _cause(e)
        raise DataError(f"{p} is not a readable HDF5 file ({cause})" + (f"; {fix}" if fix else "")) from None


def _damaged(p: Path, where: str, e: BaseException, fix: str | None) -> DataError:
    cause, _ = _cause(e)
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
            missing = [k for k in _CORE if k not in g]
            if missing:
                raise DataError(f"{where} lacks the arrays {', '.join(missing)}; {hint}")
            arrays = {k: g[k][()] for k in g}
            attrs = {k: _py(v) for k, v in g.attrs.items()}
            file_attrs = {k: _py(v) for k, v in f.attrs.items()}
    except OdmdError:
        raise
    except _H5_FAILURES as e:
        if _is_os_failure(e):
            raise storage_error(e, p, "read", fix) from None
        raise _damaged(p, where, e, hint) from None
    problems = _identity_problems(file_attrs, attrs, set_name, expect or {})
    if problems:
        raise DataError(f"{where} is not the set expected here; {hint}", problems)
    if verify:
        _verify(where, file_attrs, attrs, arrays, hint)
    for k, v in file_attrs.items():
        if k != "format_version":  # a property of the container, not of the set
            attrs.setdefault(k, v)
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
    stored = attrs.get("content_sha256")
    actual = content_sha256(arrays)
    if stored != actual:
        raise DataError(
            f"{where} is corrupt or altered: its arrays hash to {actual[:16]}..., "
            f"the file records {str(stored)[:16]}...; {hint}"
        )
    stored_meta = attrs.get("meta_sha256")
    actual_meta = meta_sha256(attrs)
    if stored_meta != actual_meta:
        raise DataError(
            f"{where} is altered: its attributes (intrinsics, image size, identity...) hash to "
            f"{actual_meta[:16]}..., the file records {str(stored_meta)[:16]}...; {hint}"
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
        if _is_os_failure(e):
            raise storage_error(e, p, "read", fix) from None
        raise _damaged(p, str(p), e, fix) from None


def file_summary(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What a file holds: its attributes and, per set, size, arrays and attributes.

    Raises:
        StorageError, DataError: the file cannot be read, or is damaged.
    """
    p = Path(path)
    f = _open_h5(p, None)
    try:
        with f:
            out: dict[str, Any] = {
                "path": str(p),
                "attrs": {k: _py(v) for k, v in f.attrs.items()},
                "sets": {},
            }
            for name, g in f.items():
                out["sets"][name] = {
                    "arrays": {k: (str(d.dtype), list(d.shape)) for k, d in g.items()},
                    "attrs": {k: _py(v) for k, v in g.attrs.items()},
                }
    except _H5_FAILURES as e:
        if _is_os_failure(e):
            raise storage_error(e, p, "read") from None
        raise _damaged(p, str(p), e, _DEFAULT_FIX) from None
    return out
