"""A Ctrl-C while the ``odmd-bench`` command starts ends it quietly, with status 130.

The command's modules take a while to import (numpy and its own: about 0.2 s on an idle
machine, more on a busy one), and Python's own handler turns a Ctrl-C in that time into
a ``KeyboardInterrupt`` traceback. The package imports this module first, which, when the
process is the command line (the ``odmd-bench`` script or ``python -m odmd_bench``) and
Python's default handler is in place, installs one that ends the process at once with
:data:`EXIT_INTERRUPTED` and the line "interrupted" (nothing has been written yet), until
:func:`odmd_bench.cli.main.main` installs its own. A program that imports the package
keeps its handler. No library does this: it is the few lines below.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from types import FrameType

#: Exit status of an interrupted command (128 + SIGINT, as a shell reports one).
EXIT_INTERRUPTED = 130


def is_command(argv: list[str] | None = None, orig_argv: list[str] | None = None) -> bool:
    """Whether this process is the ``odmd-bench`` command (its script, or ``python -m odmd_bench``)."""
    argv = sys.argv if argv is None else argv
    orig_argv = list(getattr(sys, "orig_argv", [])) if orig_argv is None else orig_argv
    name = os.path.basename(argv[0]) if argv else ""
    if name.removesuffix(".exe").removesuffix("-script.py") == "odmd-bench":
        return True
    return any(a == "-m" and b == "odmd_bench" for a, b in zip(orig_argv, orig_argv[1:], strict=False))


def end_now(signum: int = signal.SIGINT, frame: FrameType | None = None) -> None:
    """A SIGINT handler: say "interrupted" and end the process with :data:`EXIT_INTERRUPTED`, at once."""
    with contextlib.suppress(OSError):  # standard error is closed: end all the same
        os.write(2, b"interrupted\n")
    os._exit(EXIT_INTERRUPTED)


def quiet_start() -> None:
    """Install :func:`end_now` for SIGINT where this process is the command and nothing else handles it."""
    if not is_command() or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        return
    with contextlib.suppress(ValueError):  # not the main thread: leave it
        signal.signal(signal.SIGINT, end_now)


quiet_start()
