"""Temporary files: named for their target and their writer, removed by the next writer.

A file is written under a temporary name beside its target
(:func:`~odmd_bench.outputs.atomic.atomic_path` moves it over the target when complete),
or in the system's temporary folder (what goes to a device; :func:`temp_folder`). The
name holds the writer's machine and process (``.NAME.HOST-PID.XXXX.tmp``), so that the
next writer of the same file removes a dead writer's leftover and never a live writer's
(:func:`clean_stale_temps`). :func:`ensure_folder` creates the folder a file goes in.

Written by hand: :mod:`tempfile` makes the files but neither names them for their writer
nor removes a killed writer's, and no library tells a dead writer's file from a live one's.
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
from collections.abc import Iterator
from pathlib import Path

from odmd_bench.errors import StorageError
from odmd_bench.os_errors import _DATA_ELSEWHERE, storage_error

#: Temporary files of a dead writer (or of any writer, after this many seconds) are
#: removed by the next writer of the same file.
STALE_TEMP_SECONDS = 3600.0


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


__all__ = ["STALE_TEMP_SECONDS", "clean_stale_temps", "ensure_folder", "temp_folder"]
