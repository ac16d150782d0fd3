"""A method run inside a command that runs many: its output kept off standard output, its failure contained."""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import MethodError, OdmdError
from odmd_bench.methods.failures import raised
from odmd_bench.methods.method import Method


@contextlib.contextmanager
def output_to_stderr() -> Iterator[None]:
    """Standard output goes to standard error while the block runs, Python's and the process's (fd 1).

    A method's prints, and a C library's, cannot corrupt what a command writes to
    standard output (``leaderboard audit --format json``). Where fd 1 or 2 is not open,
    only Python's ``sys.stdout`` is redirected.
    """
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    saved = None
    with contextlib.suppress(OSError):
        saved = os.dup(1)
        os.dup2(2, 1)
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        with contextlib.suppress(Exception):
            sys.stderr.flush()
        if saved is not None:
            os.dup2(saved, 1)
            os.close(saved)


def run_contained(
    method: Method, examples: Examples, **options: Any
) -> tuple[np.ndarray, dict[str, int | str]]:
    """:meth:`Method.run` with a plug-in contained, for commands that run many methods in one process.

    The method's standard output goes to standard error (:func:`output_to_stderr`), and a
    plug-in (a method of another distribution) that exits (``sys.exit``), runs out of
    memory or raises anything else becomes a :class:`MethodError` naming it, so that the
    caller can report that one method and go on with the others. ``KeyboardInterrupt``
    is the user's and passes; so does anything odmd-bench's own methods raise (their bugs
    are ours).
    """
    with output_to_stderr():
        try:
            return method.run(examples, **options)
        except (OdmdError, KeyboardInterrupt):
            raise
        except BaseException as e:
            if method.is_own:
                raise
            what = f"exited (SystemExit {e.code!r})" if isinstance(e, SystemExit) else f"failed: {raised(e)}"
            raise MethodError(
                f"method {method.name!r} ({method.target}, from {method.source}) {what}; a bug of that "
                "method, not of odmd-bench"
            ) from None
