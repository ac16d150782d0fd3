"""The options a method declares (its module's ``OPTIONS``), and how they are checked.

A method declares what a user may give it on the command line, and an entry record, as a
sequence of :class:`MethodOption`; :func:`declaration_problems` checks a declaration
against the method's functions when it is loaded, :meth:`MethodOption.convert` checks and
converts a given value, and :func:`format_value` writes one as the command line does.
"""

from __future__ import annotations

import inspect
import keyword
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
            if not takes(f, o.name):
                problems.append(f"{where}: {fname}() does not take it")
                continue
            p = _parameter(f, o.name)
            if p is not None and p.default is not p.empty and not _same(p.default, o.default):
                problems.append(f"{where}: its default {o.default!r} is not {fname}()'s, {p.default!r}")
    return problems


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


def takes(function: Callable[..., Any], keyword: str) -> bool:
    """Whether ``function`` takes ``keyword`` by name (or takes any keyword: ``**kwargs``)."""
    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return False
    return any(
        (p.name == keyword and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)) or p.kind is p.VAR_KEYWORD
        for p in parameters
    )
