"""How the fresh-seed audit re-runs an entry: its method, its recorded options, the run.

An entry is re-run when its ``command`` is ``odmd-bench baseline NAME ...`` of an installed
method (:func:`parse_command`) or it records a plug-in and its ``options``
(:func:`resolve_target`); :func:`rerun` runs it, contained, on the fresh sets.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import OdmdError, UsageError
from odmd_bench.leaderboard.audit_files import command_method
from odmd_bench.leaderboard.entry import Entry

if TYPE_CHECKING:
    from odmd_bench.methods import Method

#: The board audited: its generated sets are drawn afresh.
BENCHMARK = "odmd-v1"
SPLIT = "test"
#: How an entry's command names the user's copy of the original release.
RELEASE_PLACEHOLDER = "ODMD/"
#: The method options of a command the audit re-runs where an entry records no ``options``.
_METHOD_OPTIONS = ("--weights", "--weights-sha256", "--config", "--selection", "--mode")


@dataclass(frozen=True)
class Target:
    """An entry and how it is re-run.

    Attributes:
        entry: the entry.
        name: the method its command runs ("" when it cannot be re-run).
        options: the method's recorded options (``weights`` resolved to a path).
        reason: why it cannot be re-run, or None; ``failed: ...`` where the method failed.
        method: the loaded method (None when it cannot be re-run).
    """

    entry: Entry
    name: str = ""
    options: dict[str, Any] = field(default_factory=dict)
    reason: str | None = None
    method: Method | None = None


def parse_command(command: str, benchmark: str = BENCHMARK) -> tuple[str, dict[str, str]]:
    """The method and options of an ``odmd-bench baseline NAME ...`` command.

    A note in parentheses at the end of the command is dropped. Options are written
    ``--opt VALUE`` or ``--opt=VALUE``; ``-o``, ``--output`` and ``--data-dir`` are
    dropped (the audit writes nothing and draws its own sets).

    Returns:
        ``(NAME, {option: value})``, options by their keyword (``weights_sha256``).

    Raises:
        ValueError: the reason the command cannot be re-run, in words.

    Example:
        >>> parse_command("odmd-bench baseline dbox --config p-z --split test -o p.csv")
        ('dbox', {'config': 'p-z'})
    """
    from odmd_bench.methods import parse_command as read_command

    name, options, own = read_command(command)  # (its words read as every recorded command is)
    unknown = [o for o in options if "--" + o.replace("_", "-") not in _METHOD_OPTIONS]
    if unknown:
        raise ValueError(
            f"its command has an option the audit does not know: --{unknown[0].replace('_', '-')}"
        )
    if own.get("--benchmark", "odmd-v1") != benchmark:
        raise ValueError(f"its command runs on benchmark {own['--benchmark']}, not {benchmark}")
    if own.get("--split", "test") != SPLIT:
        raise ValueError(f"its command runs on split {own['--split']}, not {SPLIT}")
    return name, options


def resolve_target(entry: Entry, repo: Path, original: str | os.PathLike[str] | None = None) -> Target:
    """How ``entry`` is re-run, or why it cannot be.

    The method is the entry's ``plugin`` where it has one (``{source, module}``: the
    module loaded from the entry folder; ``{requirement: NAME==VERSION}``: that version
    must be installed, nothing is installed here), else the method its command names. Its
    options are the entry's recorded ``options``, else those of its command
    (:func:`parse_command`). A relative ``weights`` path is resolved in the repository
    (``repo``), or, written ``ODMD/...``, in the original release's folder ``original``.
    A plug-in that exits, raises or prints while it loads is contained: the reason says so.
    """
    from odmd_bench import methods

    plugin = getattr(entry.meta, "plugin", None)
    recorded = getattr(entry.meta, "options", None)
    try:
        if recorded is not None:
            name, given = command_method(entry.meta.command), dict(recorded)
        else:
            name, given = parse_command(entry.meta.command, entry.benchmark)
    except ValueError as e:
        if recorded is None or plugin is None or "module" not in plugin:
            return Target(entry, reason=str(e))
        # a plug-in named by its module, run with its recorded options: the command is not needed
        name, given = entry.method, dict(recorded)
    options: dict[str, Any] = dict(given)
    try:
        with methods.output_to_stderr():
            method = _load_method(entry, name, plugin)
    except UsageError as e:
        return Target(entry, reason=f"method {name!r} cannot be loaded: {e.message}")
    except (KeyboardInterrupt, OdmdError):
        raise
    except BaseException as e:  # a plug-in's import ran sys.exit, ran out of memory, ...
        return Target(entry, reason=f"failed: loading method {name!r} raised {type(e).__name__}: {e}"[:500])
    if isinstance(method, str):
        return Target(entry, reason=method)
    refused = [k for k in options if not method.accepts(k)]
    if refused:
        return Target(entry, reason=f"method {name!r} takes no option {', '.join(refused)}")
    if isinstance(options.get("weights"), str):
        text = options["weights"]
        if text.startswith(RELEASE_PLACEHOLDER):
            if original is None:
                return Target(
                    entry,
                    reason=f"its weights {text} are a file of the original release: give --original "
                    "(or set ODMD_ORIGINAL)",
                )
            path = Path(original) / text[len(RELEASE_PLACEHOLDER) :]
        else:
            path = Path(text) if Path(text).is_absolute() else repo / text
        if not path.is_file():
            return Target(entry, reason=f"its weights are not found: {path}")
        options["weights"] = path
    return Target(entry, name=name, options=options, method=method)


def _load_method(entry: Entry, name: str, plugin: Mapping[str, str] | None) -> Any:
    """The method of ``entry`` (a :class:`~odmd_bench.methods.Method`), or why it cannot be loaded (text)."""
    from importlib import metadata

    from odmd_bench import methods

    if plugin is None:
        return methods.load(name)
    if "requirement" in plugin:
        dist, _, version = plugin["requirement"].partition("==")
        try:
            installed = metadata.version(dist)
        except metadata.PackageNotFoundError:
            return f"its plug-in is not installed here (pip install {plugin['requirement']})"
        if installed != version:
            return (
                f"its plug-in {dist} {installed} is installed here, the entry needs {plugin['requirement']}"
            )
        if "module" not in plugin:
            return methods.load(name)
        return methods.load_module(name, plugin["module"], f"{dist} {installed}")
    folder = entry.folder / plugin["source"]
    if not folder.is_dir() or folder.is_symlink():
        return f"its plug-in source {plugin['source']}/ is not a folder in the entry folder"
    return methods.load_module(name, plugin["module"], f"the plug-in source of entry {entry.key}", folder)


def rerun(target: Target, fresh: Mapping[str, Sequence[Examples]]) -> dict[str, np.ndarray]:
    """Per-example percent errors of ``target`` on each fresh set, its repeats concatenated.

    Each call is contained (:func:`~odmd_bench.methods.run_contained`): its standard
    output goes to standard error, and a plug-in that exits or raises anything becomes
    a :class:`~odmd_bench.errors.MethodError`. The method gets its own read-only copy of
    each set (:meth:`~odmd_bench.data.examples.Examples.without_truth`), so it cannot change
    the sets the next entry is run on.

    Raises:
        OdmdError: the method refused to run or failed (a missing module, weights failing
            their hash, a plug-in's exception); :func:`audit` records it as the reason.
    """
    from odmd_bench import methods
    from odmd_bench.evaluation.metrics import percent_error

    method = target.method if target.method is not None else methods.load(target.name)
    out = {}
    for name, draws in fresh.items():
        parts = [
            percent_error(ex.depth, methods.run_contained(method, ex, **target.options)[0]) for ex in draws
        ]
        out[name] = np.concatenate(parts)
    return out


__all__ = ["BENCHMARK", "RELEASE_PLACEHOLDER", "SPLIT", "Target", "parse_command", "rerun", "resolve_target"]
