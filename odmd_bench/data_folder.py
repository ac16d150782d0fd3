"""The data folder's default place: ``$ODMD_BENCH_DATA``, else the OS's user data folder.

At the bottom of the package (it imports nothing of it): the data's registry
(:mod:`odmd_bench.data.registry`) resolves a data folder with it, and the OS-error
vocabulary (:mod:`odmd_bench.os_errors`) names the data folder's options in the fix of a
failure within it.
"""

from __future__ import annotations

import os
from pathlib import Path

#: Environment variable that overrides the default data folder.
DATA_DIR_ENV = "ODMD_BENCH_DATA"


def default_data_dir() -> Path:
    r"""The data folder: ``$ODMD_BENCH_DATA`` if set, else the OS's user data folder.

    The user data folder follows each OS's convention through ``platformdirs``:
    ``$XDG_DATA_HOME/odmd-bench`` (``~/.local/share/odmd-bench``) on Linux,
    ``~/Library/Application Support/odmd-bench`` on macOS and
    ``%LOCALAPPDATA%\odmd-bench`` on Windows.
    """
    env = os.environ.get(DATA_DIR_ENV)
    if env:
        return Path(env).expanduser()
    import platformdirs  # here, not at the top: most commands are given a folder or the variable

    return Path(platformdirs.user_data_dir("odmd-bench", appauthor=False))


__all__ = ["DATA_DIR_ENV", "default_data_dir"]
