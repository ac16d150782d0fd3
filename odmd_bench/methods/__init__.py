"""The depth-estimation methods, found as plug-ins.

A method is registered by any installed distribution under the entry-point group
``odmd_bench.methods``: the name is what ``odmd-bench baseline NAME`` takes, the value
a module (or any object) with two functions::

    predict(examples, **options) -> depths (N,)
    predict_report(examples, **options) -> (depths (N,), {fallback: count, ...})

and, optionally, a third::

    predict_spread(examples, **options) -> spreads (N,)

its own relative uncertainty per example (positive, unitless), which
:mod:`odmd_bench.predict.intervals` turns into val-calibrated error bars; a method without it
gets intervals of one relative width per set.

A third-party package adds its method to the command line without touching this one,
by declaring in its own ``pyproject.toml``::

    [project.entry-points."odmd_bench.methods"]
    my-method = "my_package.my_method"

The library names no method itself. A method is imported only when it is loaded, so
that the optional modules one needs (torch, say) are imported for it alone, and a
missing one is a usage error naming the extra that installs it
(:func:`odmd_bench.extras.missing_module_error`).

Options (``weights=``, ``mode=``, ...) reach a method only if both its functions take
that keyword (:meth:`Method.accepts`). The options a user may give on the command line
(``odmd-bench baseline NAME --mode scale``, ``odmd-bench predict``) and record in a
leaderboard entry are those the module declares in ``OPTIONS``, a sequence of
:class:`MethodOption` (name, type, default, help, choices)::

    from odmd_bench.methods import MethodOption

    OPTIONS = (MethodOption("scale", float, 1.0, "Multiply every depth by this."),)

    def predict_report(examples, scale=1.0): ...

A declaration is checked when the method is loaded (each name taken by both functions,
its default theirs); :meth:`Method.values` checks and converts given values against it,
and :func:`format_command` / :func:`parse_command` write and read the
``odmd-bench baseline NAME --option VALUE ...`` command that records them.

This module finds the methods (their entry points, :func:`names`, :func:`load`) and
answers which of them declare an option; its rooms hold the rest:
:mod:`~odmd_bench.methods.options` (declaring and checking options),
:mod:`~odmd_bench.methods.method` (a loaded method and its checked run),
:mod:`~odmd_bench.methods.contained` (a run contained, for commands that run many),
:mod:`~odmd_bench.methods.loading` (a module made a method),
:mod:`~odmd_bench.methods.command` (the recorded command) and
:mod:`~odmd_bench.methods.failures` (a failure in words). Their public names are imported
from here (``from odmd_bench.methods import MethodOption``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import metadata
from typing import Any

from odmd_bench.errors import UsageError
from odmd_bench.methods.command import format_command, parse_command, recorded_options
from odmd_bench.methods.contained import output_to_stderr, run_contained
from odmd_bench.methods.loading import imported, load_module
from odmd_bench.methods.method import Method
from odmd_bench.methods.options import OPTION_TYPES, MethodOption, declaration_problems, format_value

#: The entry-point group methods are registered under.
GROUP = "odmd_bench.methods"


def names() -> list[str]:
    """The registered methods' names, sorted."""
    return sorted({ep.name for ep in _entry_points()})


def load(name: str) -> Method:
    """The method registered as ``name``.

    Args:
        name: a registered name (:func:`names`).

    Returns:
        The loaded method.

    Raises:
        UsageError: no method, or more than one, is registered as ``name``; its module
            cannot be imported (a missing optional module names the extra to install);
            it lacks ``predict`` or ``predict_report``.
    """
    found = [ep for ep in _entry_points() if ep.name == name]
    if not found:
        from odmd_bench.inputs.problems import closest

        known = ", ".join(names()) or "none"
        raise UsageError(
            f"no method {name!r} is registered{closest(name, names())} (group {GROUP}); registered: {known}"
        )
    if len(found) > 1:
        raise UsageError(
            f"method {name!r} is registered more than once; uninstall all but one",
            [f"{ep.value} (from {_source(ep)})" for ep in found],
        )
    ep = found[0]
    return imported(name, ep.value, _source(ep), ep.value.partition(":")[0], ep.load)


def own_names() -> list[str]:
    """The names of the methods odmd-bench itself registers (shipped in this repository), from metadata only."""
    return sorted({ep.name for ep in _entry_points() if _source(ep).split(" ", 1)[0] == "odmd-bench"})


def accepting(keyword: str) -> list[str]:
    """The registered methods that take option ``keyword`` (those that load), sorted."""
    return _loading_where(lambda method: method.accepts(keyword))


def check_options(method: Method, options: Mapping[str, Any], spell: Callable[[str], str] = str) -> None:
    """Refuse every option ``method`` does not declare, naming the methods that declare each.

    The command line's check: an option is given to a method on the command line only
    where the method declares it (:attr:`Method.options`).

    Args:
        method: the method to run.
        options: keyword -> value; keywords only, the values are not looked at.
        spell: how an option is written for the user (``lambda k: "--" + k``).

    Raises:
        UsageError: one problem per refused option.
    """
    problems = []
    for name in options:
        if method.option(name) is None:
            taking = declaring(name)
            who = f"{', '.join(taking)} only" if taking else "no registered method"
            problems.append(f"{spell(name)} applies to {who}, not to {method.name!r}")
    if len(problems) == 1:
        raise UsageError(problems[0])
    if problems:
        raise UsageError(f"options that {method.name!r} does not take", problems)


def _entry_points() -> list[metadata.EntryPoint]:
    return list(metadata.entry_points(group=GROUP))


def _source(ep: metadata.EntryPoint) -> str:
    dist = getattr(ep, "dist", None)
    return f"{dist.metadata['Name']} {dist.version}" if dist is not None else "an unknown distribution"


def declaring(name: str) -> list[str]:
    """The registered methods that declare option ``name`` (a keyword; those that load), sorted."""
    return _loading_where(lambda method: method.option(name) is not None)


def _loading_where(holds: Callable[[Method], bool]) -> list[str]:
    """The names, sorted, of the registered methods that load and of which ``holds`` is true."""
    out = []
    for name in names():
        try:
            if holds(load(name)):
                out.append(name)
        except UsageError:
            continue
    return out


__all__ = [
    "GROUP",
    "OPTION_TYPES",
    "Method",
    "MethodOption",
    "accepting",
    "check_options",
    "declaration_problems",
    "declaring",
    "format_command",
    "format_value",
    "load",
    "load_module",
    "names",
    "output_to_stderr",
    "own_names",
    "parse_command",
    "recorded_options",
    "run_contained",
]
