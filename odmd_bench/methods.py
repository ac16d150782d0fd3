"""The depth-estimation methods, found as plug-ins.

A method is registered by any installed distribution under the entry-point group
``odmd_bench.methods``: the name is what ``odmd-bench baseline NAME`` takes, the value
a module (or any object) with two functions::

    predict(examples, **options) -> depths (N,)
    predict_report(examples, **options) -> (depths (N,), {fallback: count, ...})

A third-party package adds its method to the command line without touching this one,
by declaring in its own ``pyproject.toml``::

    [project.entry-points."odmd_bench.methods"]
    my-method = "my_package.my_method"

The library names no method itself. A method is imported only when it is loaded, so
that the optional modules one needs (torch, say) are imported for it alone, and a
missing one is a usage error naming the extra that installs it
(:func:`odmd_bench.extras.missing_module_error`).

Options (``weights=``, ``mode=``, ...) reach a method only if both its functions take
that keyword (:meth:`Method.accepts`).
"""

from __future__ import annotations

import contextlib
import inspect
import os
import sys
import traceback
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DepthRangeError, MethodError, OdmdError, UsageError
from odmd_bench.extras import is_installed, missing_module_error
from odmd_bench.inputs.bounds import MAX_ABS_DEPTH, depth_problems
from odmd_bench.inputs.problems import SHOWN

#: The entry-point group methods are registered under.
GROUP = "odmd_bench.methods"


@dataclass(frozen=True)
class Method:
    """A loaded method.

    Attributes:
        name: its registered name.
        target: where its entry point points (``module`` or ``module:attr``).
        source: the distribution that registers it, with its version.
        predict: ``predict(examples, **options) -> depths``.
        predict_report: ``predict_report(examples, **options) -> (depths, counts)``.
    """

    name: str
    target: str
    source: str
    predict: Callable[..., Any]
    predict_report: Callable[..., Any]

    def accepts(self, keyword: str) -> bool:
        """Whether ``predict`` and ``predict_report`` both take ``keyword`` by name."""
        return all(_takes(f, keyword) for f in (self.predict, self.predict_report))

    def run(self, examples: Examples, **options: Any) -> tuple[np.ndarray, dict[str, int | str]]:
        """Depths and the method's report for ``examples``, checked.

        The method sees ``examples.without_truth()``: the boxes, detections, camera and
        metadata, never the true depths or the generator's extras.

        Args:
            examples: the examples to estimate.
            **options: keywords for ``predict_report``; each must be accepted.

        Returns:
            ``(depths, report)``: (N,) float64 finite depths, and the report: integers
            (fallback counts; ``n``, where given, the number of examples) and strings
            (what the method says of its run, e.g. which weights it loaded).

        Raises:
            UsageError: an option the method does not take, or an optional module it
                needs is not installed (the message names the extra).
            MethodError: a plug-in (a method of another distribution) raised, or broke
                its promise of one finite depth per example and a report of counts.
            RuntimeError: the same from one of odmd-bench's own methods (a bug of
                odmd-bench).
            DepthRangeError: depths that are not finite or beyond
                :data:`~odmd_bench.inputs.bounds.MAX_ABS_DEPTH`: what the method was given
                (the examples' numbers, its options or weights) makes them; the message
                names the examples and the options.
        """
        refused = [k for k in options if not self.accepts(k)]
        if refused:
            raise UsageError(f"method {self.name!r} takes no option {', '.join(map(repr, refused))}")
        bug = f"method {self.name!r} ({self.target}, from {self.source})"
        broken = RuntimeError if self.is_own else MethodError
        try:
            depths, counts = self.predict_report(examples.without_truth(), **options)
        except ModuleNotFoundError as e:
            raise _missing(e, self.name) from None
        except (OdmdError, MemoryError):
            raise
        except Exception as e:
            if self.is_own:
                raise
            raise MethodError(f"{bug} failed: {_raised(e)}; a bug of that method, not of odmd-bench") from e
        try:
            depths = np.asarray(depths, dtype=np.float64)
            report = {str(k): v if isinstance(v, str) else int(v) for k, v in dict(counts).items()}
        except (TypeError, ValueError) as e:
            raise broken(f"{bug} returned what is not depths and a report of counts: {_raised(e)}") from None
        if depths.shape != (len(examples),):
            raise broken(f"{bug} returned shape {depths.shape} for {len(examples)} examples")
        if not self.is_own and not np.isfinite(depths).all():
            raise broken(f"{bug} returned {int((~np.isfinite(depths)).sum())} non-finite depths")
        out = depth_problems(depths)
        if out.any():
            where = np.flatnonzero(out)
            given = ", ".join(f"{k}={v}" for k, v in options.items()) or "none"
            raise DepthRangeError(
                f"method {self.name!r} gives depths that are not finite or beyond {MAX_ABS_DEPTH:.0e} m "
                f"for {where.size} of {len(examples)} examples",
                [
                    ", ".join(f"example {i}: {float(depths[i])!r}" for i in where[:SHOWN].tolist())
                    + (", ..." if where.size > SHOWN else ""),
                    f"what it was given makes them: the boxes and camera motion of those named, or its "
                    f"options ({given})",
                ],
                where=where.tolist(),
            )
        return depths, report

    @property
    def is_own(self) -> bool:
        """Whether odmd-bench's own distribution registers the method (its bugs are ours)."""
        return self.source.split(" ", 1)[0] == "odmd-bench"


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
            what = f"exited (SystemExit {e.code!r})" if isinstance(e, SystemExit) else f"failed: {_raised(e)}"
            raise MethodError(
                f"method {method.name!r} ({method.target}, from {method.source}) {what}; a bug of that "
                "method, not of odmd-bench"
            ) from None


def _raised(e: BaseException) -> str:
    """``Type: message (raised at file:line, in function)``, the last frame of the trace."""
    frames = traceback.extract_tb(e.__traceback__)
    where = f" (raised at {frames[-1].filename}:{frames[-1].lineno}, in {frames[-1].name})" if frames else ""
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text[:300]}{where}"


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
    try:
        obj = ep.load()
    except ModuleNotFoundError as e:
        raise _missing(e, name, ep.value.partition(":")[0]) from None
    except Exception as e:
        raise UsageError(
            f"method {name!r} ({ep.value}, from {_source(ep)}) cannot be loaded: {type(e).__name__}: {e}"
        ) from None
    missing = [f for f in ("predict", "predict_report") if not callable(getattr(obj, f, None))]
    if missing:
        raise UsageError(
            f"method {name!r} ({ep.value}, from {_source(ep)}) is not usable: it has no "
            + " and no ".join(f"{f}()" for f in missing)
        )
    return Method(name, ep.value, _source(ep), obj.predict, obj.predict_report)


def own_names() -> list[str]:
    """The names of the methods odmd-bench itself registers (shipped in this repository), from metadata only."""
    return sorted({ep.name for ep in _entry_points() if _source(ep).split(" ", 1)[0] == "odmd-bench"})


def load_module(name: str, module: str, source: str, folder: Path | None = None) -> Method:
    """Method ``name`` from the module ``module`` (not an entry point): a pinned plug-in's, or one kept as source.

    Args:
        name: what messages call it.
        module: the dotted module that has ``predict`` and ``predict_report``.
        source: where it comes from, in words (shown in its errors).
        folder: a folder of plain ``.py`` files to import ``module`` from (an entry's
            plug-in source); it is put first on ``sys.path`` and stays there, so that the
            module's own later imports work. Its top package must not be one already
            imported or installed elsewhere.

    Raises:
        UsageError: the module cannot be imported or lacks the two functions.
    """
    import importlib
    import importlib.util

    top = module.split(".", 1)[0]
    if folder is not None:
        loaded = sys.modules.get(top)
        where = Path(getattr(loaded, "__file__", None) or "") if loaded is not None else None
        found = importlib.util.find_spec(top) if loaded is None else None
        other = where if where is not None else (Path(found.origin) if found and found.origin else None)
        if (loaded is not None or found is not None) and (
            other is None or folder.resolve() not in other.resolve().parents
        ):
            raise UsageError(
                f"method {name!r}: its module {top} is already {'imported' if loaded else 'installed'} from elsewhere ({other})"
            )
        if str(folder) not in sys.path:
            sys.path.insert(0, str(folder))
    try:
        obj = importlib.import_module(module)
    except ModuleNotFoundError as e:
        raise _missing(e, name, module) from None
    except Exception as e:
        raise UsageError(
            f"method {name!r} ({module}, from {source}) cannot be loaded: {type(e).__name__}: {e}"
        ) from None
    missing = [f for f in ("predict", "predict_report") if not callable(getattr(obj, f, None))]
    if missing:
        raise UsageError(
            f"method {name!r} ({module}, from {source}) is not usable: it has no "
            + " and no ".join(f"{f}()" for f in missing)
        )
    return Method(name, module, source, obj.predict, obj.predict_report)


def accepting(keyword: str) -> list[str]:
    """The registered methods that take option ``keyword`` (those that load), sorted."""
    taking = []
    for name in names():
        try:
            if load(name).accepts(keyword):
                taking.append(name)
        except UsageError:
            continue
    return taking


def check_options(method: Method, options: Mapping[str, Any], spell: Callable[[str], str] = str) -> None:
    """Refuse every option ``method`` does not take, naming the methods that take each.

    Args:
        method: the method to run.
        options: keyword -> value; keywords only, the values are not looked at.
        spell: how an option is written for the user (``lambda k: "--" + k``).

    Raises:
        UsageError: one problem per refused option.
    """
    problems = []
    for keyword in options:
        if not method.accepts(keyword):
            taking = accepting(keyword)
            who = f"{', '.join(taking)} only" if taking else "no registered method"
            problems.append(f"{spell(keyword)} applies to {who}, not to {method.name!r}")
    if len(problems) == 1:
        raise UsageError(problems[0])
    if problems:
        raise UsageError(f"options that {method.name!r} does not take", problems)


def _entry_points() -> list[metadata.EntryPoint]:
    return list(metadata.entry_points(group=GROUP))


def _source(ep: metadata.EntryPoint) -> str:
    dist = getattr(ep, "dist", None)
    return f"{dist.metadata['Name']} {dist.version}" if dist is not None else "an unknown distribution"


def _missing(error: ModuleNotFoundError, name: str, target: str = "") -> Exception:
    """The error to raise for a failed import of method ``name``'s module.

    A module that is not installed becomes a usage error naming what provides it; a module
    that is installed but failed to import is a bug, returned as it is to be re-raised.
    """
    missing = error.name or ""
    if target and (target + ".").startswith(missing + "."):
        return UsageError(f"method {name!r} is not available: its module {target} is not installed")
    if missing and not is_installed(missing):
        return missing_module_error(error, f"method {name!r}")
    return error


def _takes(function: Callable[..., Any], keyword: str) -> bool:
    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return False
    return any(
        (p.name == keyword and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)) or p.kind is p.VAR_KEYWORD
        for p in parameters
    )


__all__ = [
    "GROUP",
    "Method",
    "accepting",
    "check_options",
    "load",
    "load_module",
    "names",
    "output_to_stderr",
    "own_names",
    "run_contained",
]
