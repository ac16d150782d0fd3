"""Options shared by several commands, declared once.

Public for plug-in commands (entry-point group ``odmd_bench.commands``), so that an added
command takes ``--data-dir`` as every other command does.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

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


def data_folder_problems(outputs: Mapping[str, Path | None], data_dir: Path | None) -> list[str]:
    """A problem for each output file (``None`` or ``-``: stdout) inside the data folder.

    The data folder holds the benchmarks' files, which a report written over one would
    destroy; paths are compared by what they resolve to.
    """
    from odmd_bench.data.registry import resolve_data_dir

    folder = Path(os.path.realpath(resolve_data_dir(data_dir)))
    problems = []
    for opt, path in outputs.items():
        if path is None or str(path) == "-":
            continue
        target = Path(os.path.realpath(path))
        if target == folder or folder in target.parents:
            problems.append(
                f"{opt} {path} is inside the data folder {folder}, which holds the benchmarks' files; "
                "write it elsewhere"
            )
    return problems


#: The options a method may take; each is passed only to a method whose ``predict`` does.
METHOD_OPTIONS: tuple[str, ...] = (
    "weights",
    "weights_sha256",
    "config",
    "selection",
    "mode",
    "combine",
    "device",
)

F = TypeVar("F", bound=Callable[..., Any])


def method_options(f: F) -> F:
    """Add ``--weights``, ``--weights-sha256``, ``--config``, ``--selection``, ``--mode``, ``--combine`` and ``--device`` to a command running a method."""
    decorators = [
        click.option(
            "--weights",
            type=click.Path(exists=True, dir_okay=False, path_type=Path),
            default=None,
            help="Checkpoint file, for the methods that load one (see odmd-bench baseline --list).",
        ),
        click.option(
            "--weights-sha256",
            "weights_sha256",
            default=None,
            metavar="HEX",
            help="The SHA-256 the --weights file must have (refused otherwise); a file with a JSON "
            "record beside it, or the original release's checkpoint, is checked without it.",
        ),
        click.option(
            "--config",
            default=None,
            help="Named configuration, for the methods that have them (see odmd-bench baseline --list).",
        ),
        click.option(
            "--selection",
            default=None,
            help="How the weights were selected, for the methods that ship several "
            "(see odmd-bench baseline --list).",
        ),
        click.option(
            "--mode",
            default=None,
            help="Mode, for the methods that have several (see odmd-bench baseline --list).",
        ),
        click.option(
            "--combine",
            default=None,
            help="How a method combines its per-axis solutions, for the methods that have several: "
            "mean (the paper) or lsq (least squares, weighted by each axis's signal; parallax, "
            "expansion).",
        ),
        click.option(
            "--device",
            type=click.Choice(["cpu", "cuda", "auto"]),
            default=None,
            help="Where a network runs, for the methods that have one (DBox): cpu (the default), cuda, "
            "or auto (cuda when torch sees a GPU).",
        ),
    ]
    for decorate in reversed(decorators):
        f = decorate(f)
    return f


def given_options(method: Any, **values: Any) -> dict[str, Any]:
    """The method options given on the command line, checked against what ``method`` takes.

    Raises:
        UsageError: an option the method does not take (every one named).
    """
    from odmd_bench import methods

    options = {k: v for k, v in values.items() if v is not None}
    methods.check_options(method, options, spell=lambda k: f"--{k.replace('_', '-')}")
    return options


def _refuse_nonfinite(
    kind: click.ParamType, value: Any, param: click.Parameter | None, ctx: click.Context | None
) -> None:
    """Fail (a usage error, exit 2) where ``value`` reads as NaN or an infinity."""
    if isinstance(value, (str, int, float)) and not isinstance(value, bool):
        try:
            number = float(value)
        except ValueError:
            return  # not a number at all: click says so
        if not math.isfinite(number):
            kind.fail(f"{value} is not a finite number (NaN and infinities are refused)", param, ctx)


class FiniteFloat(click.types.FloatParamType):
    """A number option's type: any finite float (click's ``float`` takes ``nan`` and ``inf``)."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        """The float, or a usage error for NaN and infinities."""
        _refuse_nonfinite(self, value, param, ctx)
        return super().convert(value, param, ctx)


class FiniteFloatRange(click.FloatRange):
    """:class:`click.FloatRange` refusing NaN (which every bound lets through: each comparison with it is false)."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        """The float, or a usage error for NaN and infinities."""
        _refuse_nonfinite(self, value, param, ctx)
        return super().convert(value, param, ctx)


#: Every float option of every command takes this type or :class:`FiniteFloatRange`
#: (``tests/test_battery.py`` tries NaN and infinities on each).
FINITE_FLOAT = FiniteFloat()

__all__ = [
    "FINITE_FLOAT",
    "METHOD_OPTIONS",
    "FiniteFloat",
    "FiniteFloatRange",
    "data_dir_option",
    "data_dir_or_out_option",
    "given_options",
    "method_options",
    "same_file",
]
