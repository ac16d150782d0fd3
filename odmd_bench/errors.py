"""The package's exceptions.

Every user mistake raises a subclass of :class:`OdmdError`; the CLI turns these into
a one-pass report on stderr and exit status 2. Anything else is a bug (exit 1).

Each class also subclasses the matching builtin, so that code catching builtins keeps
working: bad values are :class:`ValueError`, a file or folder that cannot be read or
written is :class:`OSError` (:class:`FileNotFoundError` when it is missing).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

#: Longest message or problem line kept in a report; the rest is cut and counted, so
#: that a hostile or broken input cannot flood a terminal or a CI log.
MAX_LINE = 1000


def _cap(text: str) -> str:
    if len(text) <= MAX_LINE:
        return text
    return f"{text[:MAX_LINE]}... ({len(text) - MAX_LINE} more characters)"


def show_value(value: Any, limit: int = 80) -> str:
    """``value`` for a message: its ``repr`` when a plain value, else its type, cut to ``limit``.

    Never raises: input under suspicion (a configuration, a pickle) may hold an integer of
    more digits than Python prints, or an object whose ``repr`` fails.
    """
    plain = str | bytes | int | float | tuple | list | None
    try:
        text = repr(value) if isinstance(value, plain) else type(value).__name__
    except (ValueError, RecursionError):  # an integer too long to print; a list holding itself
        kind = type(value).__name__
        text = f"{'an' if kind[:1] in 'aeiou' else 'a'} {kind} too large to print"
    return text if len(text) <= limit else text[: limit - 3] + "..."


class OdmdError(Exception):
    """Base class of every error the package raises on purpose.

    ``problems`` lists each problem found, one line each, so that a report can name
    every problem at once instead of stopping at the first. Lines longer than
    :data:`MAX_LINE` characters are cut.
    """

    def __init__(self, message: str, problems: Sequence[str] = ()) -> None:
        self.message = _cap(str(message))
        self.problems = [_cap(str(p)) for p in problems]
        super().__init__(self.render())

    def render(self) -> str:
        """The message and one indented line per problem."""
        if not self.problems:
            return self.message
        lines = [self.message] + [f"  - {p}" for p in self.problems]
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """``{"error": message, "problems": [...]}``, the JSON form of the report."""
        return {"error": self.message, "problems": list(self.problems)}

    def __str__(self) -> str:
        return self.render()

    def __reduce__(self) -> Any:
        return (type(self), (self.message, self.problems))


class ConfigError(OdmdError, ValueError):
    """A camera or generator configuration is invalid (field named in the message)."""


class DataError(OdmdError, ValueError):
    """A data file is missing, corrupt, stale, or does not match its pinned manifest."""


class StorageError(DataError, OSError):
    """A file or folder cannot be read or written (an OS or HDF5 failure).

    The message names the path, the cause and the command or step that fixes it.
    ``errno`` and ``filename`` are set where the operating system gave them.
    """

    def __init__(
        self,
        message: str,
        problems: Sequence[str] = (),
        *,
        errno: int | None = None,
        filename: str | None = None,
    ) -> None:
        super().__init__(message, problems)
        self.errno = errno
        self.filename = filename

    def __reduce__(self) -> Any:
        return (_rebuild, (type(self), self.message, self.problems, self.errno, self.filename))


def _rebuild(
    cls: type[StorageError], message: str, problems: list[str], errno: int | None, filename: str | None
) -> StorageError:
    return cls(message, problems, errno=errno, filename=filename)


class MissingDataError(StorageError, FileNotFoundError):
    """A data file that should exist does not (the message says which command makes it)."""


class DepthRangeError(DataError):
    """A method's depths are not finite or lie beyond the bound; ``where`` holds their indices.

    Not a bug of the method: what it was given (the examples' numbers, its options, its
    weights) makes them, and the message names those.
    """

    def __init__(self, message: str, problems: Sequence[str] = (), where: Sequence[int] = ()) -> None:
        super().__init__(message, problems)
        self.where = tuple(int(i) for i in where)

    def __reduce__(self) -> Any:
        return (type(self), (self.message, self.problems, self.where))


class ImportRefused(DataError):
    """An original-release file was refused (unknown hash, hostile pickle, bad layout)."""


class ValidationError(OdmdError, ValueError):
    """A predictions file cannot be scored; ``problems`` names every problem found."""


class UsageError(OdmdError, ValueError):
    """A bad combination of arguments (unknown benchmark, split, set, method...)."""


class MethodError(OdmdError, RuntimeError):
    """A registered method of another distribution (a plug-in) failed or broke its promise.

    The message names the method, where it comes from and, for an exception it raised,
    the line of the plug-in's code that raised it: a bug of that method, not of odmd-bench.
    """
