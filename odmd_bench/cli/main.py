"""The ``odmd-bench`` command line: parse, call the library, print. No logic here.

Each area's commands live in ``odmd_bench/cli/<area>.py`` and are added below.
Errors: the package's own exceptions (bad input, bad usage) print a one-pass report
and exit 2, and so does any ``OSError`` (one line: the path and the cause); click's
usage errors exit 2; anything else is a bug and exits 1. When the command was given
``--format json``, errors are printed to stderr as one JSON object
``{"error": ..., "problems": [...]}``. A reader that closes the pipe early
(``odmd-bench info FILE | head -1``) ends the command quietly, with status 141
(128 + SIGPIPE, as a shell reports a command killed by SIGPIPE), whatever the command
and however large its output: standard output writes every byte or fails
(:class:`_WholeWrites`), since Python's own buffered stdout returns from a write the pipe
took only part of without an error, and the rest would be dropped with status 0. A
standard output closed before the command starts (``odmd-bench ... >&-``) is the same
case: the command does its work, and its first write to standard output ends it with
status 141 (a command that prints nothing ends with 0); the closed descriptors 0, 1 and
2 are pointed at ``/dev/null`` first, so that no file the command opens takes their
place. A Ctrl-C ends the command with status 130 and one line, never a traceback, at
any moment: while the modules import (:mod:`odmd_bench._interrupt`), while it runs
(no partial file is left), and after (an interrupt is never swallowed into 0).
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import sys
import traceback
from typing import Any

import click

from odmd_bench import __version__
from odmd_bench.errors import OdmdError, UsageError

#: Exit status when stdout is closed by its reader.
EXIT_BROKEN_PIPE = 141


class _WholeWrites(io.RawIOBase):
    """A file descriptor whose ``write`` writes every byte, or raises (``BrokenPipeError``)."""

    def __init__(self, fd: int) -> None:
        super().__init__()
        self._fd = fd

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._fd

    def isatty(self) -> bool:
        return os.isatty(self._fd)

    def write(self, b: Any) -> int:
        view = memoryview(b).cast("B")
        total = len(view)
        while view:
            view = view[os.write(self._fd, view) :]
        return total


def whole_stdout() -> None:
    """Make ``sys.stdout`` write every byte or raise, keeping its encoding (see the module docstring)."""
    out = sys.stdout
    try:
        fd = out.fileno()
        out.flush()
    except (AttributeError, OSError, ValueError):  # none, or not a real file (tests)
        return
    sys.stdout = io.TextIOWrapper(
        _WholeWrites(fd),
        encoding=out.encoding,
        errors=out.errors,
        line_buffering=bool(getattr(out, "line_buffering", False)),
        write_through=True,
    )


def _wants_json(args: list[str]) -> bool:
    """True if the command line gives ``--format json`` (or ``--format=json``)."""
    for i, a in enumerate(args):
        if a == "--format=json" or (a == "--format" and i + 1 < len(args) and args[i + 1] == "json"):
            return True
    return False


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's last flush cannot fail."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # not a real file (tests): nothing to protect
        pass


def _os_error_line(e: OSError) -> str:
    cause = e.strerror or str(e) or type(e).__name__
    where = " -> ".join(str(f) for f in (e.filename, e.filename2) if f is not None)
    if not where and isinstance(e, FileNotFoundError) and not _cwd_exists():
        return f"the current folder no longer exists (it was removed): {cause}; cd to a folder that exists"
    return f"{where}: {cause}" if where else cause


def _cwd_exists() -> bool:
    try:
        os.getcwd()
    except OSError:
        return False
    return True


#: Entry-point group of commands that other packages add (``train-dbox`` is one).
COMMAND_GROUP = "odmd_bench.commands"


def _plugin_commands() -> dict[str, Any]:
    """``{name: entry point}`` of the commands registered in :data:`COMMAND_GROUP`."""
    from importlib import metadata

    return {ep.name: ep for ep in metadata.entry_points(group=COMMAND_GROUP)}


class _Group(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*super().list_commands(ctx), *_plugin_commands()})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        # Plug-in commands are loaded when asked for, so that no other command pays for them.
        command = super().get_command(ctx, cmd_name)
        if command is not None:
            return command
        ep = _plugin_commands().get(cmd_name)
        if ep is None:
            return None
        try:
            loaded = ep.load()
        except ModuleNotFoundError as e:
            from odmd_bench.extras import missing_module_error

            raise missing_module_error(e, f"command {cmd_name!r} ({ep.value})") from None
        if not isinstance(loaded, click.Command):
            raise UsageError(f"command {cmd_name!r} ({ep.value}) is not a click command")
        return loaded

    def resolve_command(self, ctx: click.Context, args: list[str]) -> Any:
        # Remember the command line, to answer in JSON when it asks for JSON output.
        ctx.meta["odmd_bench.args"] = list(args)
        return super().resolve_command(ctx, args)

    def _report(self, ctx: click.Context, message: str, problems: list[str], text: str) -> None:
        if _wants_json(ctx.meta.get("odmd_bench.args", [])):
            click.echo(json.dumps({"error": message, "problems": problems}), err=True)
        else:
            click.echo(text, err=True)

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except OdmdError as e:
            self._report(ctx, e.message, e.problems, f"error: {e.render()}")
            ctx.exit(2)
        except BrokenPipeError:
            _silence_stdout()
            ctx.exit(EXIT_BROKEN_PIPE)
        except (click.exceptions.Exit, click.exceptions.Abort):
            raise
        except click.ClickException as e:
            if not _wants_json(ctx.meta.get("odmd_bench.args", [])):
                raise
            self._report(ctx, e.format_message(), [], "")
            ctx.exit(e.exit_code)
        except ModuleNotFoundError as e:  # an optional dependency a command needs
            from odmd_bench.extras import missing_module_error

            err = missing_module_error(e, f"odmd-bench {ctx.invoked_subcommand or ''}".strip())
            self._report(ctx, err.message, err.problems, f"error: {err.render()}")
            ctx.exit(2)
        except OSError as e:
            line = _os_error_line(e)
            self._report(ctx, line, [], f"error: {line}")
            ctx.exit(2)
        except KeyboardInterrupt:
            click.echo("interrupted; no partial file was left behind", err=True)
            ctx.exit(130)
        except Exception:
            click.echo(
                "internal error (a bug in odmd-bench; please report it with this trace):\n"
                + traceback.format_exc(),
                err=True,
            )
            ctx.exit(1)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="odmd-bench")
def cli() -> None:
    """odmd-bench: data, evaluation and baselines for ODMD (Griffin and Corso, CVPR 2021)."""
    import logging

    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger = logging.getLogger("odmd_bench")
    if not logger.handlers:
        logger.addHandler(handler)
    logger.setLevel(logging.INFO)


def _register() -> None:
    from odmd_bench.cli import baseline, data, evaluate, leaderboard, plot, predict

    for module in (data, baseline, predict, evaluate, plot, leaderboard):
        for command in module.COMMANDS:
            cli.add_command(command)


_register()


class _ClosedOutput(io.RawIOBase):
    """Standard output when it was closed before the command started: every write fails as a broken pipe."""

    def writable(self) -> bool:
        return True

    def write(self, b: Any) -> int:
        raise BrokenPipeError(errno.EBADF, "standard output is closed")


def _open_closed_descriptors() -> bool:
    """Point each closed standard descriptor (0, 1, 2) at /dev/null; whether standard output was closed.

    In order, so that each ``os.open`` takes the lowest free descriptor, the one closed.
    Standard output closed becomes :class:`_ClosedOutput`; standard error closed, a
    sink; standard input stays ``None`` (``-`` says it is closed).
    """
    closed_out = sys.stdout is None
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            with contextlib.suppress(OSError):
                os.open(os.devnull, os.O_RDWR)
    if closed_out:
        sys.stdout = io.TextIOWrapper(_ClosedOutput(), encoding="utf-8", write_through=True)
    if sys.stderr is None:
        sys.stderr = open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115 (for the process's life)
    return closed_out


#: Whether a SIGINT came while :func:`main` ran (see :func:`_interrupt`).
_interrupted = False


def _interrupt(signum: int, frame: Any) -> None:
    """SIGINT while the command runs: remembered, then Python's KeyboardInterrupt."""
    global _interrupted
    _interrupted = True
    raise KeyboardInterrupt


def main() -> None:
    """Run the command line (the ``odmd-bench`` script and ``python -m odmd_bench``)."""
    import signal

    from odmd_bench._interrupt import EXIT_INTERRUPTED, end_now

    with contextlib.suppress(ValueError):  # not the main thread: Python's handler stays
        signal.signal(signal.SIGINT, _interrupt)
    code: int | str | None = 0
    try:
        if not _open_closed_descriptors():
            whole_stdout()
        cli.main(prog_name="odmd-bench")
    except SystemExit as e:
        code = e.code
    except BrokenPipeError:
        _silence_stdout()
        code = EXIT_BROKEN_PIPE
    except KeyboardInterrupt:  # outside a command (click's own handling turns it into 1)
        code = EXIT_INTERRUPTED
    try:
        sys.stdout.flush()
    except BrokenPipeError:  # the reader left before the last line was flushed
        _silence_stdout()
        code = code or EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        pass
    with contextlib.suppress(ValueError):  # from here an interrupt ends the process at once
        signal.signal(signal.SIGINT, end_now)
    if _interrupted:  # never swallowed: whatever caught the KeyboardInterrupt
        if code != EXIT_INTERRUPTED:
            with contextlib.suppress(OSError, ValueError, AttributeError):
                sys.stderr.write("interrupted\n")
        code = EXIT_INTERRUPTED
    sys.exit(code)
