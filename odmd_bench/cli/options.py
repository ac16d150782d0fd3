"""Options shared by several commands, declared once.

Public for plug-in commands (entry-point group ``odmd_bench.commands``), so that an added
command takes ``--data-dir`` as every other command does.
"""

from __future__ import annotations

import os
from pathlib import Path

import click

from odmd_bench.data.registry import DATA_DIR_ENV

DATA_DIR_HELP = (
    f"Data folder [default: ${DATA_DIR_ENV}, else the OS's user data folder, "
    "e.g. ~/.local/share/odmd-bench; `odmd-bench data-dir` prints it]."
)

_DATA_DIR_TYPE = click.Path(file_okay=False, path_type=Path)

#: ``--data-dir``: the data folder (``None``: the default, see ``odmd-bench data-dir``).
data_dir_option = click.option(
    "--data-dir", "data_dir", type=_DATA_DIR_TYPE, default=None, help=DATA_DIR_HELP
)

#: The same option for ``generate``, which also takes it as ``--out`` (docs/format.md).
data_dir_or_out_option = click.option(
    "--data-dir", "--out", "data_dir", type=_DATA_DIR_TYPE, default=None, help=DATA_DIR_HELP
)


def same_file(a: Path, b: Path) -> bool:
    """Whether two paths name one file (symbolic and hard links alike)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


__all__ = ["data_dir_option", "data_dir_or_out_option", "same_file"]
