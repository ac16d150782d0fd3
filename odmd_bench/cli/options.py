"""Options shared by several commands, declared once."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from odmd_bench.data.registry import DATA_DIR_ENV

DATA_DIR_HELP = (
    f"Data folder [default: ${DATA_DIR_ENV}, else the OS's user data folder, "
    "e.g. ~/.local/share/odmd-bench; `odmd-bench data-dir` prints it]."
)


def data_dir_option_with(*aliases: str) -> Any:
    """The ``--data-dir`` option (parameter ``data_dir``), with extra names ``aliases``."""
    return click.option(
        "--data-dir",
        *aliases,
        "data_dir",
        type=click.Path(file_okay=False, path_type=Path),
        default=None,
        help=DATA_DIR_HELP,
    )


#: ``--data-dir``: the data folder (``None``: the default, see ``odmd-bench data-dir``).
data_dir_option = data_dir_option_with()
