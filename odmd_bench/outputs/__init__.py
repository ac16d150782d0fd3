"""Files written safely: atomically, under a lock, with OS failures as package errors.

Every writer of the package goes through :func:`atomic_path` (or :func:`atomic_write`):
the new file is written beside the target and moved over it only when complete, so a
reader sees the old file or the new one, never half of one, and a killed writer's
temporary file is removed by the next writer (:func:`clean_stale_temps`). Writers of one
file across processes serialise with :func:`locked`. An OS failure (full disk, read-only
folder, a folder where a file belongs...) becomes a
:class:`~odmd_bench.errors.StorageError` (an ``OSError``) naming the path, the cause and
the fix (:func:`~odmd_bench.os_errors.storage_error`).

The rooms: :mod:`~odmd_bench.outputs.atomic` (one file or several, all or none),
:mod:`~odmd_bench.outputs.temps` (temporary files and the removal of a dead writer's),
:mod:`~odmd_bench.outputs.lock` (the writers' lock). The layer beside
:mod:`odmd_bench.inputs`: it imports nothing of the package but the errors and
:mod:`odmd_bench.os_errors`.
"""

from __future__ import annotations

from odmd_bench.outputs.atomic import atomic_path, atomic_paths, atomic_texts, atomic_write, write_target
from odmd_bench.outputs.lock import locked
from odmd_bench.outputs.temps import STALE_TEMP_SECONDS, clean_stale_temps, ensure_folder, temp_folder

__all__ = [
    "STALE_TEMP_SECONDS",
    "atomic_path",
    "atomic_paths",
    "atomic_texts",
    "atomic_write",
    "clean_stale_temps",
    "temp_folder",
    "ensure_folder",
    "locked",
    "write_target",
]
