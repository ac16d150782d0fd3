"""The package's exceptions.

Every user mistake raises a subclass of :class:`OdmdError`; the CLI turns these into
a one-pass report on stderr and exit status 2. Anything else is a bug (exit 1).
"""

from __future__ import annotations

from collections.abc import Sequence


class OdmdError(Exception):
    """Base class of every error the package raises on purpose.

    ``problems`` lists each problem found, one line each, so that a report can name
    every problem at once instead of stopping at the first.
    """

    def __init__(self, message: str, problems: Sequence[str] = ()) -> None:
        self.message = message
        self.problems = list(problems)
        super().__init__(self.render())

    def render(self) -> str:
        if not self.problems:
            return self.message
        lines = [self.message] + [f"  - {p}" for p in self.problems]
        return "\n".join(lines)


class ConfigError(OdmdError):
    """A camera or generator configuration is invalid (field named in the message)."""


class DataError(OdmdError):
    """A data file is missing, corrupt, or does not match its pinned manifest."""


class ImportRefused(DataError):
    """An original-release file was refused (unknown hash, hostile pickle, bad layout)."""


class ValidationError(OdmdError):
    """A predictions file cannot be scored; ``problems`` names every problem found."""


class UsageError(OdmdError):
    """A bad combination of arguments (unknown benchmark, split, set, method...)."""
