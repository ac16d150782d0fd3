"""The command that records a method's run: ``odmd-bench baseline NAME --option VALUE ...``, written and read.

A leaderboard entry records the command that made its predictions (its ``command``) and,
since the field exists, the option values apart (its ``options``): :func:`format_command`
writes the command, :func:`parse_command` reads it back, and :func:`recorded_options`
takes an entry's values from both, checking that they agree. Nothing here loads a method.
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping

from odmd_bench.methods.options import format_value


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
