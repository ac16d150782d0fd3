"""Atomic writes of one file or of several, all or none.

Every writer of the package goes through :func:`atomic_path` (or :func:`atomic_write`):
the new file is written beside the target and moved over it only when complete, so a
reader sees the old file or the new one, never half of one, and a killed writer's
temporary file is removed by the next writer
(:func:`~odmd_bench.outputs.temps.clean_stale_temps`). Several files are replaced all or
none (:func:`atomic_paths`, :func:`atomic_texts`). An OS failure (full disk, read-only
folder, a folder where a file belongs...) becomes a
:class:`~odmd_bench.errors.StorageError` naming the path, the cause and the fix
(:func:`~odmd_bench.os_errors.storage_error`).

Written by hand: the libraries that write a file atomically (``atomicwrites``, archived
since 2022; ``safer``) replace one file at a time; none replaces several files all or
none, putting back those already moved when one cannot be, as a board's files and a
report beside its figure need.
"""

from __future__ import annotations

import contextlib
import errno as errno_codes
import os
import shutil
import stat
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

from odmd_bench.errors import OdmdError
from odmd_bench.os_errors import storage_error
from odmd_bench.outputs.temps import _temp_beside, _temp_elsewhere, clean_stale_temps


def write_target(path: str | os.PathLike[str], *, into_devices: bool = True) -> tuple[Path, bool]:
    """The file that writing ``path`` changes, and whether it is replaced atomically.

    A symbolic link is followed (the link stays and its target gets the new content,
    as a shell's ``>`` does). A regular file, a missing one or a folder (refused when
    written) is replaced atomically. An existing device, pipe or socket (``/dev/null``,
    ``/dev/stdout``, ``/dev/fd/N``, a FIFO) is written into, never replaced, through the
    path as given (``/dev/stdout`` leads to a pipe that has no path of its own); with
    ``into_devices=False`` (the data files) it is replaced like a regular file instead,
    so that a pipe in a data file's place can never block a writer.

    Raises:
        StorageError: the path is a loop of symbolic links, or cannot be looked at.
    """
    given = Path(path)
    led_to = Path(os.path.realpath(given)) if given.is_symlink() else given  # what replacing changes
    try:
        mode = os.stat(given).st_mode  # through any links
    except FileNotFoundError:  # missing, or a link to nothing: made where the link leads
        return led_to, True
    except OSError as e:
        if e.errno in (errno_codes.ENOTDIR, errno_codes.EACCES):
            return given, True  # the write says why, with the folder's fix
        raise storage_error(e, path, "write") from None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode) or not into_devices:
        return led_to, True
    return given, False


#: Errors of a write that ran out of room (or of a failing disk): named with the file.
_FULL = (errno_codes.ENOSPC, errno_codes.EFBIG, errno_codes.EDQUOT, errno_codes.EIO)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str], *, into_devices: bool = True) -> Iterator[Path]:
    """A temporary file name beside ``path``; on success, the file is moved over ``path``.

    If the body raises (or the process dies), ``path`` is untouched: an existing good
    file is never lost and no half-written file is left under the final name (a
    SIGKILLed writer's temporary file is removed by the next writer, see
    :func:`clean_stale_temps`). OS failures of the file operations (full disk,
    read-only folder, a folder in the file's place...) raise :class:`StorageError`.
    A symbolic link is followed, and a device or pipe is written into once the body
    succeeds (:func:`write_target`). For writers that want a file name (h5py,
    savefig); see also :func:`atomic_write`. ``into_devices=False``: a device or pipe in
    the file's place is replaced instead (the data files).
    """
    with atomic_paths([path], into_devices=into_devices) as (tmp,):
        yield tmp


def _copy_into(source: Path, device: Path) -> None:
    """Write ``source``'s bytes into ``device`` (a pipe, a terminal, /dev/null...)."""
    try:
        with open(source, "rb") as src, open(device, "wb") as dst:
            shutil.copyfileobj(src, dst)
    except OSError as e:
        raise storage_error(e, device, "write") from None


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` for writing; on success it replaces ``path``.

    See :func:`atomic_path`.
    """
    # Text is UTF-8 whatever the locale; a file name that is not UTF-8 (it reaches Python
    # with its bytes escaped) is written back as those bytes.
    text = "b" not in mode
    with (
        atomic_path(path) as tmp,
        open(tmp, mode, encoding="utf-8" if text else None, errors="surrogateescape" if text else None) as fh,
    ):
        yield fh


def _backup(target: Path) -> Path | None:
    """A second name for ``target``'s current file (a hard link, else a copy), or None if none."""
    if not (target.is_file() and not target.is_symlink()):
        return None
    fd, name = _temp_beside(target)
    os.close(fd)
    os.unlink(name)
    try:
        os.link(target, name)
    except OSError:  # a file system without hard links
        shutil.copy2(target, name)
    return Path(name)


def _commit(moves: list[tuple[Path, Path]]) -> None:
    """Move each ``(temporary, target)``; if one cannot be moved, put back those moved before.

    Every target is looked at first (a folder in a file's place fails before anything
    moves); the old files are kept under second names until every move has succeeded.
    Only a process killed between two moves (microseconds) can leave some new files
    beside some old ones.
    """
    for _, target in moves:
        if target.is_dir() and not target.is_symlink():
            raise storage_error(IsADirectoryError(errno_codes.EISDIR, "Is a directory"), target, "write")
    try:
        for tmp, _ in moves:
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
        # One file needs no second name: its one move replaces it, or leaves it as it was.
        backups = [_backup(target) for _, target in moves] if len(moves) > 1 else [None] * len(moves)
    except OSError as e:
        raise storage_error(*_named(e, [target for _, target in moves])) from None
    done = 0
    try:
        for tmp, target in moves:
            os.replace(tmp, target)
            done += 1
    except OSError as e:
        for (_, target), old in zip(moves[:done], backups[:done], strict=True):
            with contextlib.suppress(OSError):
                if old is None:
                    os.unlink(target)
                else:
                    os.replace(old, target)
        raise storage_error(e, moves[done][1], "write") from None
    finally:
        for old in backups:
            if old is not None:
                with contextlib.suppress(OSError):
                    os.unlink(old)


def _named(e: OSError, targets: Sequence[Path]) -> tuple[OSError, Path, str]:
    """``storage_error``'s arguments for a failure writing ``targets``: the file if one, else their folder."""
    return (e, targets[0], "write") if len(targets) == 1 else (e, targets[0].parent, "write into")


@contextlib.contextmanager
def atomic_paths(
    paths: Sequence[str | os.PathLike[str]], *, into_devices: bool = True
) -> Iterator[list[Path]]:
    """Temporary file names for several paths; on success all replace their paths, or none does.

    The body writes each temporary file (text, HDF5, a figure...). Then every file is
    moved over its path; if a move fails (a file that cannot be replaced), the files
    already moved get their old versions back, so a failure anywhere leaves every path
    as it was. Devices and pipes among the paths (:func:`write_target`) are written into
    after every file has been moved; with ``into_devices=False`` they are replaced too.
    """
    plans = [write_target(p, into_devices=into_devices) for p in paths]
    temps: list[Path] = []
    try:
        for target, replace in plans:
            if replace:
                clean_stale_temps(target)
                fd, tmp = _temp_beside(target)
                os.close(fd)
                temps.append(Path(tmp))
            else:
                temps.append(_temp_elsewhere())
        try:
            yield list(temps)
        except OSError as e:
            if isinstance(e, OdmdError) or e.errno not in _FULL:
                raise
            raise storage_error(*_named(e, [target for target, _ in plans])) from None
        _commit([(tmp, target) for tmp, (target, replace) in zip(temps, plans, strict=True) if replace])
        for through, (device, replace) in zip(temps, plans, strict=True):
            if not replace:
                _copy_into(through, device)
    finally:
        for left in temps:
            with contextlib.suppress(OSError):
                os.unlink(left)


@contextlib.contextmanager
def atomic_texts(
    texts: Sequence[tuple[str | os.PathLike[str], str]],
    also: Sequence[str | os.PathLike[str]] = (),
) -> Iterator[list[Path]]:
    """Write several text files so that none replaces its old version unless all are written.

    Each ``(path, text)`` is written to its temporary file on entry; the body runs and
    gets the temporary files of the paths ``also`` to write (a figure, say); on success
    every file is moved over its path (:func:`atomic_paths`). A failure anywhere, in the
    body or in a move, leaves every path as it was.
    """
    with atomic_paths([*(p for p, _ in texts), *also]) as temps:
        for (_, text), tmp in zip(texts, temps, strict=False):
            with open(tmp, "w", encoding="utf-8", errors="surrogateescape") as fh:
                fh.write(text)
        yield temps[len(texts) :]


__all__ = ["atomic_path", "atomic_paths", "atomic_texts", "atomic_write", "write_target"]
