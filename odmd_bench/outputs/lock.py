"""The writers' lock: one writer of a file at a time, across processes.

:func:`locked` holds :class:`filelock.FileLock` on ``.NAME.lock`` beside the file; this
module adds the lock file's place, its removal, and a
:class:`~odmd_bench.errors.StorageError` saying why a lock file cannot be created.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from odmd_bench.os_errors import storage_error
from odmd_bench.outputs.temps import ensure_folder


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


__all__ = ["locked"]
