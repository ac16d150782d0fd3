"""The OS-error vocabulary: an operating system's failure as a package error, with its fix.

An ``OSError`` (or h5py's ``RuntimeError`` carrying ``errno = N``) from reading or writing
a file becomes a :class:`~odmd_bench.errors.StorageError` (an ``OSError``;
:class:`~odmd_bench.errors.MissingDataError` for a missing file) that names the path, the
cause and the fix: ``cannot ACTION PATH: CAUSE; FIX`` (:func:`storage_error`). The writers
of :mod:`odmd_bench.outputs` and the data files' readers (:mod:`odmd_bench.data.io`) word
their failures through it, so that one failure reads the same whichever command met it.

Written by hand: no library turns an errno into what to do about it (``os.strerror``
says what happened, not what to do), and the fix depends on the package's own files (a
data file's names the data folder's options).
"""

from __future__ import annotations

import errno as errno_codes
import os
import re
from pathlib import Path

from odmd_bench.errors import MissingDataError, StorageError


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
    from odmd_bench.data_folder import default_data_dir

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


__all__ = ["is_os_failure", "os_cause", "storage_error"]
