"""Files written safely: atomically, under a lock, with OS failures as package errors.

Every writer of the package goes through :func:`atomic_path` (or :func:`atomic_write`):
the new file is written beside the target and moved over it only when complete, so a
reader sees the old file or the new one, never half of one, and a killed writer's
temporary file is removed by the next writer (:func:`clean_stale_temps`). Writers of one
file across processes serialise with :func:`locked`. An OS failure (full disk, read-only
folder, a folder where a file belongs...) becomes a
:class:`~odmd_bench.errors.StorageError` (an ``OSError``) naming the path, the cause and
the fix (:func:`storage_error`).
"""

from __future__ import annotations

import contextlib
import errno as errno_codes
import os
import re
import shutil
import socket
import stat
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

from odmd_bench.errors import MissingDataError, OdmdError, StorageError

#: Temporary files of a dead writer (or of any writer, after this many seconds) are
#: removed by the next writer of the same file.
STALE_TEMP_SECONDS = 3600.0


# --------------------------------------------------------------------- OS failures


def os_cause(e: BaseException) -> tuple[str, int | None]:
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


_ELSEWHERE = "write to another folder"
_DATA_ELSEWHERE = "write to another folder (the data folder: --data-dir or $ODMD_BENCH_DATA)"
_FIXES = {
    errno_codes.ENOSPC: "free space on that disk, or ELSEWHERE",
    errno_codes.EFBIG: "raise the file size limit (ulimit -f), or ELSEWHERE",
    errno_codes.EDQUOT: "free space within your disk quota, or ELSEWHERE",
    errno_codes.EACCES: "make that folder writable (and its files readable), or ELSEWHERE",
    errno_codes.EPERM: "make that file and its folder writable (lsattr shows a file made immutable), or ELSEWHERE",
    errno_codes.EROFS: "that file system is read-only: ELSEWHERE",
    errno_codes.ENOTDIR: "a part of that path is a file, not a folder: ELSEWHERE",
    errno_codes.EISDIR: "a folder stands where the file belongs: remove it (rm -r PATH) and run the command again",
    errno_codes.ELOOP: "the path is a loop of symbolic links: remove one of them",
}
#: A file that another process holds open for writing (HDF5's file locking): not damaged.
_IN_USE = (errno_codes.EAGAIN, errno_codes.EWOULDBLOCK)


def _in_data_folder(path: Path) -> bool:
    """Whether ``path`` is a data file (``.h5``) or in the default data folder."""
    from odmd_bench.data.registry import default_data_dir

    if path.suffix == ".h5":
        return True
    try:
        folder = default_data_dir().absolute()
        return path.absolute() == folder or folder in path.absolute().parents
    except (OSError, ValueError):
        return False


def storage_error(
    e: BaseException, path: str | os.PathLike[str], action: str, fix: str | None = None
) -> StorageError:
    """A :class:`StorageError` for ``e``: ``cannot ACTION PATH: CAUSE; FIX``.

    Without ``fix``, the fix follows the cause; a data file's (``.h5``) also names the
    data folder's options. A file in use by another process is said to be so, whatever
    ``fix`` says (it is not damaged: nothing needs rebuilding).
    """
    cause, code = os_cause(e)
    if code in _IN_USE:
        cause, fix = (
            f"another process has it open for writing ({cause})",
            "wait until that process has finished, then run the command again",
        )
    elsewhere = _DATA_ELSEWHERE if _in_data_folder(Path(path)) else _ELSEWHERE
    hint = fix or _FIXES.get(
        code or -1, "check the path and its permissions, then run the command again"
    ).replace("PATH", str(path)).replace("ELSEWHERE", elsewhere)
    cls = MissingDataError if code == errno_codes.ENOENT else StorageError
    return cls(f"cannot {action} {path}: {cause}; {hint}", errno=code, filename=str(path))


def is_os_failure(e: BaseException) -> bool:
    """True for an error of the operating system (not of a damaged file's contents)."""
    if isinstance(e, OSError) and isinstance(e.errno, int):
        return True
    return isinstance(e, RuntimeError | OSError) and re.search(r"errno = \d+", str(e)) is not None


def ensure_folder(folder: Path) -> None:
    """Create ``folder`` (and its parents), or raise a :class:`StorageError` saying why not."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        what = next(
            (
                f"a symbolic link to {os.readlink(q)}, which does not exist"
                for q in (folder, *folder.parents)
                if q.is_symlink() and not q.exists()
            ),
            "a file",
        )
        raise StorageError(
            f"cannot use {folder} as a folder: it is {what}; move it away, or {_DATA_ELSEWHERE}",
            errno=errno_codes.ENOTDIR,
            filename=str(folder),
        ) from None
    except OSError as e:
        raise storage_error(e, folder, "create the folder") from None


# ------------------------------------------------------------------ atomic writes


def _read_umask() -> int:
    """The process's umask, read once (setting it to read it is racy with other threads)."""
    try:  # Linux says it without changing it
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: Permissions of the files the package writes: what ``open`` would give them.
_FILE_MODE = 0o666 & ~_read_umask()


#: A temporary file's name: ``.NAME.HOST-PID.XXXX.tmp`` beside the file NAME it becomes.
_TEMP_NAME = re.compile(r"\.(?P<name>.+)\.[A-Za-z0-9]*-[0-9]+\.[^.]+\.tmp")
#: What the package's files and folders in the system's temporary folder start with.
_SYSTEM_TEMP_PREFIX = "odmd-bench."


def _temp_prefix(target: Path) -> str:
    # A temporary file written through a temporary file of its own (the plot's figure into
    # the board's temporary file, say) is named for the final target, so that the next
    # writer of that target finds it too.
    name = target.name
    while (nested := _TEMP_NAME.fullmatch(name)) is not None:
        name = nested.group("name")
    return f".{name}."


def _host() -> str:
    """This machine's name, reduced to what is safe in a file name (no dots, no dashes)."""
    return re.sub(r"[^A-Za-z0-9]", "", socket.gethostname())[:32] or "host"


def _temp_beside(target: Path) -> tuple[int, str]:
    ensure_folder(target.parent)
    try:
        # The writer's machine and pid are in the name, so that a later writer can tell a
        # dead writer's leftover from a live writer's file (see clean_stale_temps).
        fd, tmp = tempfile.mkstemp(
            prefix=f"{_temp_prefix(target)}{_host()}-{os.getpid()}.", suffix=".tmp", dir=target.parent
        )
    except OSError as e:
        raise storage_error(e, target.parent, "write into") from None
    try:  # mkstemp makes 0600; give the file the permissions open() would
        if hasattr(os, "fchmod"):
            os.fchmod(fd, _FILE_MODE)
        else:  # pragma: no cover - Windows
            os.chmod(tmp, _FILE_MODE)
    except OSError as e:
        os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
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

    Only files named as :func:`atomic_path` names them (``.NAME.HOST-PID.XXXX.tmp``
    beside ``target``) are considered. One written on this machine is removed when its
    writer's process no longer exists, and never while it does. One written on another
    machine (a shared data folder), or by an earlier version without the writer in its
    name, is removed only when older than ``max_age`` seconds. Returns the removed paths.
    """
    target = Path(target)
    prefix = _temp_prefix(target)
    # "." + prefix: a temporary file's own temporary file as versions before 0.1.1 named it
    return _clean(target.parent, prefix, max_age) + _clean(target.parent, "." + prefix, max_age)


def _clean(folder: Path, prefix: str, max_age: float, *, folders: bool = False) -> list[Path]:
    """Remove ``PREFIX HOST-PID.XXXX.tmp`` files (and with ``folders``, folders) of dead writers in ``folder``."""
    removed: list[Path] = []
    try:
        entries = list(folder.iterdir())
    except OSError:
        return removed
    now = time.time()
    for p in entries:
        name = p.name
        if not (name.startswith(prefix) and name.endswith(".tmp")):
            continue
        writer, _, _ = name[len(prefix) : -len(".tmp")].partition(".")
        host, _, pid_text = writer.rpartition("-")
        try:
            st = p.lstat()
        except OSError:
            continue
        is_folder = stat.S_ISDIR(st.st_mode)
        if not (stat.S_ISREG(st.st_mode) or (folders and is_folder)):
            continue
        if host == _host() and pid_text.isdigit():  # written here: the process decides
            stale = int(pid_text) != os.getpid() and not _pid_alive(int(pid_text))
        else:
            stale = now - st.st_mtime > max_age
        if stale:
            with contextlib.suppress(OSError):
                if is_folder:
                    shutil.rmtree(p)
                else:
                    p.unlink()
                removed.append(p)
    return removed


@contextlib.contextmanager
def temp_folder() -> Iterator[Path]:
    """A new folder in the system's temporary folder, removed on exit.

    A killed writer's folder (and a killed writer's file of :func:`atomic_paths` for a
    device) is removed by the next writer, as :func:`clean_stale_temps` does beside files.
    """
    base = Path(tempfile.gettempdir())
    _clean(base, _SYSTEM_TEMP_PREFIX, STALE_TEMP_SECONDS, folders=True)
    try:
        folder = Path(
            tempfile.mkdtemp(prefix=f"{_SYSTEM_TEMP_PREFIX}{_host()}-{os.getpid()}.", suffix=".tmp")
        )
    except OSError as e:
        raise storage_error(e, base, "write into") from None
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


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


def _temp_elsewhere() -> Path:
    """An empty temporary file in the system's temporary folder (for what goes to a device)."""
    base = Path(tempfile.gettempdir())
    _clean(base, _SYSTEM_TEMP_PREFIX, STALE_TEMP_SECONDS, folders=True)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f"{_SYSTEM_TEMP_PREFIX}{_host()}-{os.getpid()}.", suffix=".tmp")
    except OSError as e:
        raise storage_error(e, base, "write into") from None
    os.close(fd)
    return Path(tmp)


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


@contextlib.contextmanager
def locked(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Hold an exclusive lock for writing ``path``, across processes.

    The lock is :class:`filelock.FileLock` (``flock`` on POSIX, ``LockFileEx`` on
    Windows) on the file ``.NAME.lock`` beside ``path``; the kernel releases it when its
    holder dies, so a killed writer never leaves a lock behind. The lock file is removed
    before the lock is released (only a killed writer's stays, until the next writer of
    ``path`` removes it). Readers do not lock:
    every write replaces the file atomically, so a reader sees the old file or the new
    one. Blocks until the lock is free. Yields the lock file's path.

    Raises:
        StorageError: the lock file cannot be created (the message says why and what to do).
    """
    from filelock import FileLock  # here: it takes 0.1 s to import, and most commands never lock

    target = Path(path)
    ensure_folder(target.parent)
    lock = target.parent / f".{target.name}.lock"
    held = FileLock(lock)
    try:
        held.acquire()
    except OSError as e:
        raise storage_error(e, lock, "create the lock file") from None
    try:
        yield lock
    finally:
        # Removed while held, so that no empty lock file is left in the data folder: a
        # writer waiting on it then holds a lock on a file with no name, which filelock
        # (3.21 on) sees and gives up for the new file, so two writers never both hold.
        with contextlib.suppress(OSError):
            lock.unlink()
        held.release()


__all__ = [
    "STALE_TEMP_SECONDS",
    "atomic_path",
    "atomic_paths",
    "atomic_texts",
    "atomic_write",
    "clean_stale_temps",
    "temp_folder",
    "ensure_folder",
    "is_os_failure",
    "locked",
    "os_cause",
    "storage_error",
    "write_target",
]
