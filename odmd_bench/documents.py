"""Bounded reading of YAML and JSON documents: leaderboard metadata, generator configurations.

Entry metadata and ``reported.yaml`` come from pull requests, and configuration files
from anywhere, so a document is refused
before it can cost memory or time: at most :data:`MAX_DOCUMENT_BYTES` bytes, nesting
at most :data:`MAX_DEPTH` deep, and in YAML no anchors (``&a``), aliases (``*a``) or
merge keys (an alias "bomb" of 1 KB would otherwise expand to gigabytes). Only plain
YAML types are built (``yaml.SafeLoader``). Messages name the line and the problem;
they never echo the document's data.
"""

from __future__ import annotations

import json

import yaml

#: Largest metadata document read, in bytes (an entry.yaml is about 1.5 KB).
MAX_DOCUMENT_BYTES = 64 * 1024
#: Deepest nesting of mappings and lists (an entry needs 2, reported.yaml 3).
MAX_DEPTH = 8
#: Longest parser message kept in an error.
_MAX_MESSAGE = 160


class DocumentError(ValueError):
    """A document that cannot be used; the message says why, without its data."""


class _BoundedLoader(yaml.SafeLoader):
    """``SafeLoader`` that refuses anchors and aliases and limits the nesting.

    Unquoted dates and times stay text (``2026-13-01`` would otherwise fail inside the
    parser, and ``2026-11-25T10:00`` become a datetime): their readers check them.
    """

    yaml_implicit_resolvers = {
        first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:timestamp"]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: yaml.Node | None, index: object) -> yaml.Node | None:
        event = self.peek_event()
        line = event.start_mark.line + 1 if event.start_mark is not None else 0
        if isinstance(event, yaml.AliasEvent):
            raise DocumentError(f"line {line}: YAML aliases (*name) are not allowed")
        if getattr(event, "anchor", None) is not None:
            raise DocumentError(f"line {line}: YAML anchors (&name) are not allowed")
        nested = isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent))
        if nested:
            self._depth += 1
            if self._depth > MAX_DEPTH:
                raise DocumentError(f"line {line}: nested more than {MAX_DEPTH} levels deep")
        try:
            return super().compose_node(parent, index)  # type: ignore[arg-type]
        finally:
            if nested:
                self._depth -= 1


def _short(text: str) -> str:
    text = " ".join(text.split())
    return text if len(text) <= _MAX_MESSAGE else text[: _MAX_MESSAGE - 3] + "..."


def _yaml_message(e: yaml.YAMLError) -> str:
    if isinstance(e, yaml.MarkedYAMLError) and e.problem:
        mark = e.problem_mark
        where = f"line {mark.line + 1}: " if mark is not None else ""
        context = f"{e.context}, " if e.context else ""
        return where + _short(context + e.problem)
    return _short(str(e).split("\n", 1)[0]) or type(e).__name__


def _depth_of(value: object) -> int:
    """Nesting depth of lists and dicts, without recursion."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)):
            deepest = max(deepest, depth)
            stack.extend((child, depth + 1) for child in (node.values() if isinstance(node, dict) else node))
    return deepest


def load_document(data: bytes, kind: str) -> object:
    """Parse a bounded YAML (``kind="yaml"``) or JSON (``kind="json"``) document.

    Args:
        data: the document's bytes (UTF-8).
        kind: ``"yaml"`` or ``"json"``.

    Returns:
        The parsed value (``None`` for an empty YAML document).

    Raises:
        DocumentError: When it is too large, too deep, not UTF-8, malformed, or uses
            YAML anchors or aliases.
    """
    if len(data) > MAX_DOCUMENT_BYTES:
        raise DocumentError(f"{len(data)} bytes; at most {MAX_DOCUMENT_BYTES} are read")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise DocumentError(f"not UTF-8 text (byte {e.start})") from None
    if kind == "json":
        try:
            value = json.loads(text)
        except RecursionError:
            raise DocumentError(f"nested more than {MAX_DEPTH} levels deep") from None
        except ValueError as e:
            raise DocumentError(_short(str(e))) from None
        if _depth_of(value) > MAX_DEPTH:
            raise DocumentError(f"nested more than {MAX_DEPTH} levels deep")
        return value
    try:
        return yaml.load(text, Loader=_BoundedLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as e:
        raise DocumentError(_yaml_message(e)) from None
    except DocumentError:
        raise
    except (ValueError, TypeError, OverflowError) as e:  # a value its explicit tag cannot make
        raise DocumentError(f"a value cannot be read ({type(e).__name__}: {_short(str(e))})") from None
