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
"""

from __future__ import annotations

import contextlib
import inspect
import keyword
import math
import os
import shlex
import sys
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
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

#: The types an option may have; a :class:`~pathlib.Path` is a file (on the command line,
#: one that exists).
OPTION_TYPES: tuple[type, ...] = (str, int, float, bool, Path)

_TRUE = ("true", "yes", "1")
_FALSE = ("false", "no", "0")


@dataclass(frozen=True)
class MethodOption:
    """An option a method declares (its module's ``OPTIONS``), given as ``--NAME VALUE``.

    Attributes:
        name: the keyword both ``predict`` and ``predict_report`` take
            (``weights_sha256``); on the command line ``--weights-sha256``.
        type: one of :data:`OPTION_TYPES`: ``str``, ``int``, ``float``, ``bool``
            (written ``true`` or ``false``) or :class:`pathlib.Path` (a file).
        default: what the method uses when the option is not given, the same as its
            functions' default; ``None`` where the method decides (``help`` says how).
        help: one or two sentences for ``--help`` and ``--list``.
        choices: the values it accepts, where they are a fixed few (``str`` only).
        metavar: how ``--help`` names the value (default: the choices, or the type).

    Example:
        >>> MethodOption("mode", str, "full", "Which model.", choices=("full", "scale")).flag
        '--mode'
    """

    name: str
    type: type = str
    default: Any = None
    help: str = ""
    choices: tuple[str, ...] = field(default=())
    metavar: str | None = None

    @property
    def flag(self) -> str:
        """How the command line spells it: ``--weights-sha256``."""
        return "--" + self.name.replace("_", "-")

    def convert(self, value: object) -> Any:
        """``value`` (as given: text from a command line or YAML, or the type itself) as the type.

        Raises:
            ValueError: a value that is not of the type or not one of the choices, in words.
        """
        t = self.type
        if t is bool:
            if isinstance(value, bool):
                out: Any = value
            elif isinstance(value, str) and value.lower() in (*_TRUE, *_FALSE):
                out = value.lower() in _TRUE
            else:
                raise ValueError(f"{value!r} is not true or false")
        elif t is int:
            if isinstance(value, bool) or not isinstance(value, int | str):
                raise ValueError(f"{value!r} is not a whole number")
            try:
                out = int(value)
            except ValueError:
                raise ValueError(f"{value!r} is not a whole number") from None
        elif t is float:
            if isinstance(value, bool) or not isinstance(value, int | float | str):
                raise ValueError(f"{value!r} is not a number")
            try:
                out = float(value)
            except ValueError:
                raise ValueError(f"{value!r} is not a number") from None
            if not math.isfinite(out):
                raise ValueError(f"{value!r} is not a finite number")
        elif t is Path:
            if not isinstance(value, str | os.PathLike) or not str(value):
                raise ValueError(f"{value!r} is not a file path")
            out = Path(value)
        else:
            if not isinstance(value, str):
                raise ValueError(f"{value!r} is not text")
            out = value
        if self.choices and out not in self.choices:
            raise ValueError(f"{value!r} is not one of {', '.join(self.choices)}")
        return out

    def describe(self) -> str:
        """One line for ``--list``: ``--mode full|scale (default full): help``."""
        what = self.metavar or ("|".join(self.choices) if self.choices else _TYPE_NAMES[self.type])
        default = "" if self.default is None else f" (default {format_value(self.default)})"
        return f"{self.flag} {what}{default}: {self.help}".rstrip(": ")


_TYPE_NAMES: dict[type, str] = {str: "TEXT", int: "INTEGER", float: "FLOAT", bool: "true|false", Path: "FILE"}


def format_value(value: object) -> str:
    """An option's value as the command line writes it (``true``, ``0.5``, a path)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


@dataclass(frozen=True)
class Method:
    """A loaded method.

    Attributes:
        name: its registered name.
        target: where its entry point points (``module`` or ``module:attr``).
        source: the distribution that registers it, with its version.
        predict: ``predict(examples, **options) -> depths``.
        predict_report: ``predict_report(examples, **options) -> (depths, counts)``.
        options: the options its module declares (``OPTIONS``), in their order.
        spread: ``predict_spread(examples, **options) -> (N,)``, or None.
    """

    name: str
    target: str
    source: str
    predict: Callable[..., Any]
    predict_report: Callable[..., Any]
    options: tuple[MethodOption, ...] = ()
    spread: Callable[..., Any] | None = None

    def option(self, name: str) -> MethodOption | None:
        """The declared option ``name`` (a keyword, ``weights_sha256``), or ``None``."""
        return next((o for o in self.options if o.name == name), None)

    def values(
        self, given: Mapping[str, object], spell: Callable[[str], str] | None = None
    ) -> dict[str, Any]:
        """``given`` checked against the declared options and converted to their types.

        What an entry records (its ``options``) or a command line gives is text or a
        YAML scalar; this is what :meth:`run` is then given.

        Args:
            given: option name (keyword) -> value.
            spell: how an option is named in a message (default: its ``--flag``).

        Returns:
            The values by name, in the order of the declaration.

        Raises:
            UsageError: every option that is not declared, and every value that is not
                of its type or not one of its choices (named), at once.

        Example:
            >>> load("robust").values({"mode": "scale"})
            {'mode': 'scale'}
        """
        name_of = spell or (lambda k: "--" + k.replace("_", "-"))
        problems = []
        declared = ", ".join(o.flag for o in self.options) or "none"
        for k in given:
            if self.option(k) is None:
                problems.append(
                    f"{name_of(k)}: method {self.name!r} declares no such option (it declares: {declared})"
                )
        out = {}
        for o in self.options:
            if o.name in given:
                try:
                    out[o.name] = o.convert(given[o.name])
                except ValueError as e:
                    problems.append(f"{name_of(o.name)}: {e}")
        if len(problems) == 1:
            raise UsageError(problems[0])
        if problems:
            raise UsageError(f"options that method {self.name!r} cannot take", problems)
        return out

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
    return _imported(name, ep.value, _source(ep), ep.value.partition(":")[0], ep.load)


def _imported(name: str, target: str, source: str, module: str, load: Callable[[], Any]) -> Method:
    """The :class:`Method` that ``load()`` imports (``module``: what a missing import names)."""
    try:
        obj = load()
    except ModuleNotFoundError as e:
        raise _missing(e, name, module) from None
    except Exception as e:
        raise UsageError(
            f"method {name!r} ({target}, from {source}) cannot be loaded: {type(e).__name__}: {e}"
        ) from None
    missing = [f for f in ("predict", "predict_report") if not callable(getattr(obj, f, None))]
    if missing:
        raise UsageError(
            f"method {name!r} ({target}, from {source}) is not usable: it has no "
            + " and no ".join(f"{f}()" for f in missing)
        )
    return _method(name, target, source, obj)


def _method(name: str, target: str, source: str, obj: Any) -> Method:
    """The :class:`Method` of a loaded module (or object) with both functions, its ``OPTIONS`` checked."""
    declared = getattr(obj, "OPTIONS", ())
    functions = (obj.predict, obj.predict_report)
    problems = declaration_problems(declared, functions)
    if problems:
        raise UsageError(f"method {name!r} ({target}, from {source}) is not usable: its OPTIONS", problems)
    spread = getattr(obj, "predict_spread", None)
    return Method(
        name,
        target,
        source,
        obj.predict,
        obj.predict_report,
        tuple(declared),
        spread if callable(spread) else None,
    )


def declaration_problems(declared: object, functions: Sequence[Callable[..., Any]]) -> list[str]:
    """What is wrong with a method's ``OPTIONS`` for its ``functions`` (empty: nothing).

    Each must be a :class:`MethodOption` with a unique name that is a Python keyword
    argument, a type of :data:`OPTION_TYPES`, choices only for ``str`` (its default one of
    them), a default of its type; both functions must take it, and where a function
    gives it a default, the declared default must be that one (so that ``--help`` tells
    the truth).
    """
    if isinstance(declared, str | bytes) or not isinstance(declared, Sequence):
        return [f"OPTIONS is a {type(declared).__name__}, not a sequence of odmd_bench.methods.MethodOption"]
    problems = []
    seen: set[str] = set()
    for i, o in enumerate(declared):
        if not isinstance(o, MethodOption):
            problems.append(f"OPTIONS[{i}] is a {type(o).__name__}, not an odmd_bench.methods.MethodOption")
            continue
        where = f"option {o.name!r}"
        if not isinstance(o.name, str) or not o.name.isidentifier() or keyword.iskeyword(o.name):
            problems.append(f"{where}: its name is not a Python keyword argument")
            continue
        if o.name in seen:
            problems.append(f"{where} is declared twice")
        seen.add(o.name)
        if o.type not in OPTION_TYPES:
            problems.append(f"{where}: type {o.type!r} is not one of str, int, float, bool, pathlib.Path")
            continue
        if o.choices and (o.type is not str or not all(isinstance(c, str) for c in o.choices)):
            problems.append(f"{where}: choices are for a str option, and are str")
        elif o.default is not None:
            try:
                if o.convert(o.default) != o.default or type(o.default) is not o.type:
                    raise ValueError(f"{o.default!r} is not a {o.type.__name__}")
            except ValueError as e:
                problems.append(f"{where}: its default {e}")
        for f in dict.fromkeys(functions):  # predict may be predict_report itself
            fname = getattr(f, "__name__", "its function")
            if not _takes(f, o.name):
                problems.append(f"{where}: {fname}() does not take it")
                continue
            p = _parameter(f, o.name)
            if p is not None and p.default is not p.empty and not _same(p.default, o.default):
                problems.append(f"{where}: its default {o.default!r} is not {fname}()'s, {p.default!r}")
    return problems


def format_command(
    name: str,
    options: Mapping[str, object],
    benchmark: str | None = None,
    split: str | None = None,
    output: str | None = None,
) -> str:
    """The ``odmd-bench baseline NAME --option VALUE ...`` command that runs a method.

    What a leaderboard entry records as its ``command``; the inverse of
    :func:`parse_command`. Options (keywords, ``weights_sha256``) come in the order
    given, then ``--benchmark``, ``--split`` and ``-o`` where given.

    Example:
        >>> format_command("dbox", {"config": "p-z", "selection": "per-set"}, "odmd-v1", "test", "predictions.csv")
        'odmd-bench baseline dbox --config p-z --selection per-set --benchmark odmd-v1 --split test -o predictions.csv'
    """
    words = ["odmd-bench", "baseline", name]
    for k, v in options.items():
        words += ["--" + k.replace("_", "-"), format_value(v)]
    for flag, value in (("--benchmark", benchmark), ("--split", split), ("-o", output)):
        if value is not None:
            words += [flag, value]
    return shlex.join(words)


#: ``odmd-bench baseline``'s own options that take a value (not the method's).
BASELINE_OPTIONS: tuple[str, ...] = ("--benchmark", "--split", "-o", "--output", "--data-dir", "--interval")


def parse_command(command: str) -> tuple[str, dict[str, str], dict[str, str]]:
    """The method, its options and the command's own options of an ``odmd-bench baseline NAME ...``.

    The inverse of :func:`format_command`, for a command as an entry records it: a note
    in parentheses at its end is dropped; options are written ``--opt VALUE`` or
    ``--opt=VALUE``. Nothing is loaded: :meth:`Method.values` checks the options.

    Returns:
        ``(NAME, {option keyword: value}, {own option: value})``, e.g.
        ``("dbox", {"weights_sha256": "ab.."}, {"--benchmark": "odmd-v1"})``.

    Raises:
        ValueError: what makes it not such a command, in words.

    Example:
        >>> parse_command("odmd-bench baseline robust --mode scale --split test -o p.csv")
        ('robust', {'mode': 'scale'}, {'--split': 'test', '-o': 'p.csv'})
    """
    try:
        words = shlex.split(command)
    except ValueError as e:
        raise ValueError(f"the command cannot be read as words ({e})") from None
    for i, w in enumerate(words):
        if w.startswith("("):
            words = words[:i]
            break
    if words[:2] != ["odmd-bench", "baseline"]:
        shown = " ".join(words[:2]) or "nothing"
        raise ValueError(f"the command is not `odmd-bench baseline NAME ...` (it starts with {shown!r})")
    names: list[str] = []
    options: dict[str, str] = {}
    own: dict[str, str] = {}
    rest = words[2:]
    i = 0
    while i < len(rest):
        word = rest[i]
        i += 1
        if not word.startswith("-") or word == "-":
            names.append(word)
            continue
        flag, eq, value = word.partition("=")
        if not eq:
            if i >= len(rest):
                raise ValueError(f"the command gives {flag} no value")
            value = rest[i]
            i += 1
        if flag in BASELINE_OPTIONS:
            target, key = own, flag
        elif flag.startswith("--") and flag[2:].replace("-", "_").isidentifier():
            target, key = options, flag[2:].replace("-", "_")
        else:
            raise ValueError(f"the command has an option that is not --NAME: {flag}")
        if key in target:
            raise ValueError(f"the command gives {flag} twice")
        target[key] = value
    if len(names) != 1:
        raise ValueError(f"the command names {len(names)} methods; `odmd-bench baseline` takes one")
    return names[0], options, own


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
    return _imported(name, module, source, module, lambda: importlib.import_module(module))


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


def recorded_options(
    command: str, options: Mapping[str, object] | None = None
) -> tuple[str, dict[str, object]]:
    """The method and the option values a leaderboard entry records (its ``command``, its ``options``).

    An entry that records ``options`` (option keyword -> a YAML scalar) has them; one
    that does not (the entries made before the field) has those of its command. Where
    both are recorded they must agree: the command is what a reader re-runs. Nothing is
    loaded; :meth:`Method.values` checks and converts the values for ``run``.

    Returns:
        ``(NAME, {option keyword: value})``.

    Raises:
        ValueError: the command is not an ``odmd-bench baseline NAME ...`` one, or it
            gives other options or values than ``options``, in words.

    Example:
        >>> recorded_options("odmd-bench baseline robust --mode scale --split test", {"mode": "scale"})
        ('robust', {'mode': 'scale'})
    """
    name, given, _own = parse_command(command)
    if options is None:
        return name, dict(given)
    written = {k: format_value(v) for k, v in options.items()}
    if written != given:
        differ = sorted(k for k in {*written, *given} if written.get(k) != given.get(k))
        raise ValueError(
            "its options and its command disagree on "
            + ", ".join(
                f"{k} (options: {written.get(k, 'not given')}, command: {given.get(k, 'not given')})"
                for k in differ
            )
        )
    return name, dict(options)


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


def _same(a: object, b: object) -> bool:
    """``a == b`` as one truth (an array's elementwise answer, or an error, is ``False``)."""
    try:
        return bool(a == b)
    except Exception:  # an array of several values, or a comparison that raises
        return False


def _parameter(function: Callable[..., Any], keyword: str) -> inspect.Parameter | None:
    try:
        return inspect.signature(function).parameters.get(keyword)
    except (TypeError, ValueError):
        return None


def _takes(function: Callable[..., Any], keyword: str) -> bool:
    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return False
    return any(
        (p.name == keyword and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)) or p.kind is p.VAR_KEYWORD
        for p in parameters
    )


def declaring(name: str) -> list[str]:
    """The registered methods that declare option ``name`` (a keyword; those that load), sorted."""
    out = []
    for n in names():
        try:
            if load(n).option(name) is not None:
                out.append(n)
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
