"""Options shared by several commands, declared once.

Public for plug-in commands (entry-point group ``odmd_bench.commands``), so that an added
command takes ``--data-dir`` as every other command does.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

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

#: ``--root``: the leaderboard folder of the ``leaderboard`` commands (see :func:`leaderboard_root`).
root_option = click.option(
    "--root",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="The leaderboard folder [default: leaderboard/ in the current folder or a parent].",
)

#: ``--original``: the original release, imported where the ``leaderboard`` commands need odmd-paper.
original_option = click.option(
    "--original",
    type=click.Path(exists=True, file_okay=False, path_type=Path),
    envvar="ODMD_ORIGINAL",
    default=None,
    help="The original ODMD release's data folder (e.g. ../shared/odmd-original), imported into the "
    "data folder when odmd-paper is missing there [env: ODMD_ORIGINAL].",
)


def leaderboard_root(root: Path | None) -> Path:
    """``--root``, or the leaderboard folder found from the current one."""
    from odmd_bench.leaderboard import find_root

    return root if root is not None else find_root()


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


_METHOD = "odmd_bench.method"
_PARAMS = "odmd_bench.method_params"


def _click_type(option: Any) -> click.ParamType:
    if option.choices:
        return click.Choice(list(option.choices))
    if option.type is Path:
        return click.Path(exists=True, dir_okay=False, path_type=Path)
    return {str: click.STRING, int: click.INT, float: click.FLOAT, bool: click.BOOL}[option.type]


class MethodCommand(click.Command):
    """A command that runs a method: the options the method declares are the command's too.

    The method is named by an argument or an option of the command (``method_param``:
    ``baseline NAME``, ``predict --method NAME``). It is found in the command line
    before the line is parsed (every option takes one value, so that the name can be
    found without knowing the method's options), loaded, and its declared options
    (:attr:`odmd_bench.methods.Method.options`) become click options: typed, their
    choices checked (a usage error, exit 2, naming the valid ones), listed by
    ``--help`` under the method's name. The callback gets them as keywords (``None``:
    not given), for :func:`given_options`. An option another registered method declares
    is refused naming that method (``--mode applies to robust only, not to 'box-ls'``).
    """

    def __init__(self, *args: Any, method_param: str, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.method_param = method_param

    def _own(self) -> dict[str, click.Parameter]:
        return {o: p for p in self.params for o in (*p.opts, *p.secondary_opts) if o.startswith("-")}

    def method_name(self, ctx: click.Context, args: list[str]) -> str | None:
        """The method's name in ``args`` (``None``: not named), without parsing them."""
        own = self._own()
        positional = []
        i = 0
        while i < len(args):
            word = args[i]
            i += 1
            if word == "--":
                positional += args[i:]
                break
            if not word.startswith("-") or word == "-":
                positional.append(word)
                continue
            flag, eq, value = word.partition("=")
            param = own.get(flag)
            if param is None and not flag.startswith("--") and flag[:2] in own:
                param, eq, value = own[flag[:2]], "=", flag[2:]  # -oFILE
            if flag in ctx.help_option_names or (isinstance(param, click.Option) and param.is_flag):
                continue
            takes = param.nargs if param is not None else 1
            if param is not None and param.name == self.method_param:
                return value if eq else (args[i] if i < len(args) else None)
            i += takes - (1 if eq else 0)
        argument = next((p for p in self.params if p.name == self.method_param), None)
        if isinstance(argument, click.Argument):
            return positional[0] if positional else None
        return None

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        """Load the method ``args`` name and add its options, then parse as click does."""
        from odmd_bench import methods
        from odmd_bench.errors import UsageError

        name = self.method_name(ctx, args)
        method = None
        if name is not None:
            try:
                method = methods.load(name)
            except UsageError:
                # --list lists every method, the broken ones too; shell completion
                # (resilient parsing) completes a name being typed
                if not (ctx.resilient_parsing or "--list" in args):
                    raise
        ctx.meta[_METHOD] = method
        if method is not None:
            try:
                ctx.meta[_PARAMS] = self._method_params(method)
                self._refuse_undeclared(ctx, method, args)
            except UsageError:
                if not ctx.resilient_parsing:
                    raise
        return super().parse_args(ctx, args)

    def _method_params(self, method: Any) -> list[click.Option]:
        from odmd_bench.errors import UsageError

        own = self._own()
        names = {p.name for p in self.params}
        clash = [o.flag for o in method.options if o.flag in own or o.name in names]
        if clash:
            raise UsageError(
                f"method {method.name!r} ({method.target}, from {method.source}) declares "
                f"{', '.join(clash)}, which odmd-bench {self.name} takes itself; the method must rename it"
            )
        out = []
        for o in method.options:
            shown = "" if o.default is None else f" [default: {_format(o.default)}]"
            out.append(
                click.Option(
                    [o.flag, o.name],
                    type=_click_type(o),
                    default=None,
                    metavar=o.metavar,
                    help=o.help + shown,
                )
            )
        return out

    def _refuse_undeclared(self, ctx: click.Context, method: Any, args: list[str]) -> None:
        from odmd_bench import methods

        known = {*self._own(), *ctx.help_option_names, *(o.flag for o in method.options)}
        unknown = []
        for word in args:
            if word == "--":
                break
            flag = word.partition("=")[0]
            if flag.startswith("--") and flag not in known:
                unknown.append(flag[2:].replace("-", "_"))
        declared = {k: None for k in unknown if methods.declaring(k)}
        if declared:
            methods.check_options(method, declared, spell=lambda k: "--" + k.replace("_", "-"))

    def get_params(self, ctx: click.Context) -> list[click.Parameter]:
        """The command's own parameters, then the method's options, then ``--help``."""
        params = super().get_params(ctx)
        extra = ctx.meta.get(_PARAMS, [])
        if not extra:
            return params
        help_option = self.get_help_option(ctx)
        own = [p for p in params if p is not help_option]
        return [*own, *extra, *([help_option] if help_option is not None else [])]

    def format_options(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command's options, then the method's under its name (or how to see them)."""
        extra = ctx.meta.get(_PARAMS, [])
        records = [r for p in self.get_params(ctx) if p not in extra and (r := p.get_help_record(ctx))]
        with formatter.section("Options"):
            formatter.write_dl(records)
        method = ctx.meta.get(_METHOD)
        if method is None:
            formatter.write_paragraph()
            param = next((p for p in self.params if p.name == self.method_param), None)
            named = "NAME" if isinstance(param, click.Argument) else f"{param.opts[0] if param else ''} NAME"
            formatter.write_text(
                f"The options a method declares are options of this command too: odmd-bench {self.name} "
                f"{named} --help lists them (odmd-bench baseline --list lists every method's)."
            )
            return
        mine = [r for p in extra if (r := p.get_help_record(ctx))]
        with formatter.section(f"Options of method {method.name} ({method.source})"):
            if mine:
                formatter.write_dl(mine)
            else:
                formatter.write_text("none (its module declares no OPTIONS)")


def _format(value: Any) -> str:
    from odmd_bench.methods import format_value

    return format_value(value)


def given_options(method: Any, **values: Any) -> dict[str, Any]:
    """The method options given on the command line (``None``: not given), checked.

    Returns:
        ``{keyword: value}`` in the order the method declares them.

    Raises:
        UsageError: an option the method does not declare (every one named, with the
            methods that do), or a value of the wrong type or not one of its choices.
    """
    from odmd_bench import methods

    options = {k: v for k, v in values.items() if v is not None}
    methods.check_options(method, options, spell=lambda k: f"--{k.replace('_', '-')}")
    return dict(method.values(options))


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
    "FiniteFloat",
    "FiniteFloatRange",
    "MethodCommand",
    "data_dir_option",
    "data_dir_or_out_option",
    "given_options",
    "same_file",
]
