"""The optional extras (``pip install 'odmd-bench[dbox]'``, ``[plot]``, ``[all]``).

``pip install odmd-bench`` alone gives the data, the evaluator, the analytical methods
and the leaderboard check. A command that needs an optional module imports it through
:func:`require`, so that a missing one is a usage error naming the extra to install
(exit 2), never a traceback.

>>> require("math", "plot").sqrt(4.0)
2.0
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import sys
from importlib import metadata
from types import ModuleType

from odmd_bench.errors import UsageError

#: The distribution whose extras are named.
DISTRIBUTION = "odmd-bench"


def install_hint(extra: str) -> str:
    """The command that installs ``extra``, quoted for every shell.

    Example:
        >>> install_hint("dbox")
        "pip install 'odmd-bench[dbox]'"
    """
    return f"pip install '{DISTRIBUTION}[{extra}]'"


def require(module: str, extra: str, purpose: str = "this command") -> ModuleType:
    """Import ``module``, or say which extra provides it.

    Args:
        module: the module to import, e.g. ``"torch"`` or ``"matplotlib.figure"``.
        extra: the extra of odmd-bench that installs it, e.g. ``"dbox"``.
        purpose: what needs it, for the message (``"baseline 'dbox'"``).

    Returns:
        The imported module.

    Raises:
        UsageError: ``module`` (or the package it is in) is not installed. A module
            missing inside an installed package is a broken installation and is
            re-raised as it is.
    """
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as e:
        if e.name is None or not (module == e.name or module.startswith(e.name + ".")):
            raise
        raise missing_module_error(e, purpose, extra) from None


def is_installed(module: str) -> bool:
    """Whether ``module`` can be imported (without importing it, except its parents).

    Example:
        >>> is_installed("math"), is_installed("no_such_module_here")
        (True, False)
    """
    if module in sys.modules:
        return sys.modules[module] is not None  # None: imports of it are blocked
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def extra_providing(module: str) -> str | None:
    """The smallest extra of the installed odmd-bench that requires ``module``'s package.

    The import name's top level is taken as the distribution name (true of torch and
    matplotlib). None when no extra requires it or odmd-bench's metadata is not there.

    Args:
        module: an import name, e.g. ``"torch.nn"``.

    Returns:
        The extra's name, or None.
    """
    try:
        requires = metadata.requires(DISTRIBUTION) or []
    except metadata.PackageNotFoundError:
        return None
    wanted = _normalise(module.split(".")[0])
    members: dict[str, set[str]] = {}
    for requirement in requires:
        name = re.match(r"[A-Za-z0-9._-]+", requirement)
        extra = re.search(r"""extra\s*==\s*["']([^"']+)["']""", requirement)
        if name and extra:
            members.setdefault(extra.group(1), set()).add(_normalise(name.group(0)))
    providing = [extra for extra, names in members.items() if wanted in names]
    return min(providing, key=lambda extra: (len(members[extra]), extra)) if providing else None


def missing_module_error(error: ModuleNotFoundError, purpose: str, extra: str | None = None) -> UsageError:
    """A usage error for a module that is not installed, naming the extra that installs it.

    Args:
        error: the import's error; ``error.name`` is the missing module.
        purpose: what needs it, for the message.
        extra: the extra to name; default: the one whose requirements include the
            module (:func:`extra_providing`), else the module is named on its own.

    Returns:
        The error, to raise.
    """
    module = error.name or "a module"
    extra = extra or extra_providing(module)
    hint = install_hint(extra) if extra else f"install the package that provides {module}"
    return UsageError(f"{purpose} needs {module}, which is not installed: {hint}")


def _normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


__all__ = [
    "DISTRIBUTION",
    "extra_providing",
    "install_hint",
    "is_installed",
    "missing_module_error",
    "require",
]
