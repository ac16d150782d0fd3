"""The rules of an entry's optional fields: ``plugin``, ``options``, ``parameters``, ``speed``.

Each takes the field's parsed value (None: absent) and returns one line per problem; the
fields themselves are :mod:`~odmd_bench.leaderboard.entry_fields`'.
"""

from __future__ import annotations

import re

from odmd_bench.leaderboard.entry_fields import (
    CONTROL,
    MAX_OPTION_CHARS,
    MAX_OPTIONS,
    MAX_PARAMETERS,
    OPTIONAL_FIELDS,
    PLUGIN_FIELDS,
    SPEED_FIELDS,
    SPEED_LENGTHS,
    show,
    unknown_fields,
)

# A pinned requirement: a PEP 508 distribution name, ``==`` and a PEP 440 version (no
# extras, URLs, markers or wildcards). packaging would parse all of PEP 508, but it is not
# a dependency, and this one shape is all an entry may give.
_REQUIREMENT = re.compile(
    r"([A-Za-z0-9](?:[A-Za-z0-9._-]{0,98}[A-Za-z0-9])?)==([0-9][0-9A-Za-z.+!_-]{0,60})(?<!\*)"
)
_MODULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*){0,9}")
_OPTION = re.compile(r"[a-z][a-z0-9_]{0,39}")
_FOLDER_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]{0,39}")


def plugin_problems(value: object) -> list[str]:
    """``plugin``: absent, or ``{requirement}`` / ``{source, module}`` (``module`` optional with a requirement).

    Where the source folder is and what it holds is checked with the entry's files
    (:func:`odmd_bench.leaderboard.files.read_entry`).
    """
    if value is None:
        return []
    if not isinstance(value, dict):
        return [f"plugin must be a mapping {OPTIONAL_FIELDS['plugin']}, got {show(value)}"]
    problems = unknown_fields("plugin", value, PLUGIN_FIELDS)
    for k in PLUGIN_FIELDS:
        v = value.get(k)
        if k in value and (not isinstance(v, str) or CONTROL.search(v) or "\n" in v):
            problems.append(f"plugin: {k} must be one line of text, got {show(v)}")
    given = [k for k in ("requirement", "source") if k in value]
    if len(given) != 1:
        problems.append("plugin must give exactly one of requirement (NAME==VERSION) and source (a folder)")
    requirement, source, module = (value.get(k) for k in PLUGIN_FIELDS)
    if isinstance(requirement, str) and not _REQUIREMENT.fullmatch(requirement):
        problems.append(
            f"plugin: requirement {show(requirement)} must be pinned as NAME==VERSION (== only; no "
            "extras, URL, marker or wildcard), so that everyone installs the same code"
        )
    if isinstance(source, str) and not _FOLDER_NAME.fullmatch(source):
        problems.append(
            f"plugin: source {show(source)} must be the name of a folder in the entry folder "
            "(letters, digits, '_', '-'; not a path)"
        )
    if "source" in value and "module" not in value:
        problems.append("plugin: a source needs module, the module in it that is the method")
    if isinstance(module, str) and not _MODULE.fullmatch(module):
        problems.append(f"plugin: module {show(module)} is not a dotted module name")
    return problems


def requirement_name(requirement: str) -> str | None:
    """The distribution name of a pinned requirement ``NAME==VERSION`` (None if it is not one)."""
    m = _REQUIREMENT.fullmatch(requirement)
    return m.group(1) if m else None


def options_problems(value: object) -> list[str]:
    """``options``: absent, or at most :data:`MAX_OPTIONS` ``name: value`` pairs.

    A name is lowercase letters, digits and ``_`` (the keyword the method takes); a value
    is one line of text (at most :data:`MAX_OPTION_CHARS` characters), a number or true/false.
    """
    if value is None:
        return []
    if not isinstance(value, dict):
        return [f"options must be a mapping {OPTIONAL_FIELDS['options']}, got {show(value)}"]
    problems = []
    if len(value) > MAX_OPTIONS:
        problems.append(f"options holds {len(value)} options; at most {MAX_OPTIONS} are allowed")
    for k, v in value.items():
        if not isinstance(k, str) or not _OPTION.fullmatch(k):
            problems.append(
                f"options: name {show(k)} must be lowercase letters, digits and '_' (the method's keyword)"
            )
        if isinstance(v, str):
            if len(v) > MAX_OPTION_CHARS or not v or CONTROL.search(v) or "\n" in v:
                problems.append(
                    f"options: the value of {show(k)} must be one line of 1 to {MAX_OPTION_CHARS} characters"
                )
        elif isinstance(v, float) and not abs(v) < float("inf"):
            problems.append(f"options: the value of {show(k)} must be a finite number")
        elif not isinstance(v, (bool, int, float)):
            problems.append(
                f"options: the value of {show(k)} must be text, a number or true/false, got {show(v)}"
            )
    return problems


def parameters_problems(value: object) -> list[str]:
    """``parameters``: absent, or a whole number from 0 to :data:`MAX_PARAMETERS`."""
    if value is None:
        return []
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_PARAMETERS:
        return [f"parameters must be {OPTIONAL_FIELDS['parameters']}, got {show(value)}"]
    return []


def speed_problems(value: object) -> list[str]:
    """``speed``: absent, or exactly the fields of :data:`SPEED_FIELDS`, each as described."""
    if value is None:
        return []
    if not isinstance(value, dict):
        return [f"speed must be a mapping {OPTIONAL_FIELDS['speed']}, got {show(value)}"]
    problems = unknown_fields("speed", value, SPEED_FIELDS)
    problems += [f"speed: missing field {k!r}: {what}" for k, what in SPEED_FIELDS.items() if k not in value]
    rate = value.get("examples_per_second")
    if "examples_per_second" in value and (
        isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate < float("inf")
    ):
        problems.append(f"speed: examples_per_second must be a number > 0, got {show(rate)}")
    for k, limit in SPEED_LENGTHS.items():
        v = value.get(k)
        if k not in value:
            continue
        if not isinstance(v, str) or not v.strip():
            problems.append(f"speed: field {k!r} must be text, got {show(v)}")
        elif len(v) > limit:
            problems.append(f"speed: field {k!r} is {len(v)} characters long; at most {limit} are allowed")
        elif CONTROL.search(v) or "\n" in v:
            problems.append(f"speed: field {k!r} must not hold line breaks or control characters")
    return problems
