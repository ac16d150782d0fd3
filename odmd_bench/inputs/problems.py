"""Problems found while validating input, grouped by kind, counted and located.

Every stage of the evaluation pipeline (:mod:`~odmd_bench.evaluation.parse`,
:mod:`~odmd_bench.evaluation.coverage`, :mod:`~odmd_bench.evaluation.arrays`) adds to one
:class:`Problems`, so that a file with several faults is refused once, naming them all;
the sequences reader (:mod:`odmd_bench.predict.sequences`) reports the same way.
Texts are bounded: a value is shown by :func:`show` (at most 40 characters), a line of a
report by :data:`MAX_LINE_CHARS`, and a report by :data:`MAX_KINDS` kinds, so a 100 KB
garbage line is never echoed.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import Any

import numpy as np

from odmd_bench.errors import ValidationError

#: How many offending lines (or examples) a problem shows.
SHOWN = 5
#: The longest line a report holds; longer ones are cut with "...".
MAX_LINE_CHARS = 400
#: The most kinds of problem a report lists; the rest are counted in one line.
MAX_KINDS = 20


def clip(text: str, limit: int = MAX_LINE_CHARS) -> str:
    """``text`` cut to ``limit`` characters, ending in ``...`` when cut."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def show(value: str, limit: int = 40) -> str:
    """``repr`` of a value from the file, cut to ``limit`` characters."""
    return repr(value if len(value) <= limit else value[:limit] + "...")


def closest(value: str, choices: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the choice closest to ``value``, or ``""``."""
    folded = {c.lower(): c for c in choices}
    key = value.strip().lower()[:100]
    if key in folded:
        return f"; did you mean {folded[key]!r}?"
    match = difflib.get_close_matches(key, list(folded), n=1, cutoff=0.6)
    return f"; did you mean {folded[match[0]]!r}?" if match else ""


def plural(n: int, word: str) -> str:
    """``"1 row"``, ``"2 rows"``."""
    return f"{n} {word if n == 1 else word + 's'}"


class Problems:
    """Problems grouped by kind, each with a count and the first few occurrences.

    Args:
        unit: what a count counts (``"row"`` in a file, ``"value"`` in arrays).
    """

    def __init__(self, unit: str = "row") -> None:
        self.unit = unit
        self._shown: dict[str, list[str]] = {}
        self._counts: dict[str, int] = {}
        self._notes: dict[str, str] = {}
        self._first: dict[str, int] = {}

    def add(
        self, kind: str, where: str | None = None, note: str = "", count: int = 1, at: int | None = None
    ) -> None:
        """Count ``count`` occurrences of ``kind``; ``where`` locates the first of them.

        ``at`` (a line number) orders kinds in :meth:`by_line`.
        """
        if kind not in self._counts and at is not None:
            self._first[kind] = at
        self._counts[kind] = self._counts.get(kind, 0) + count
        shown = self._shown.setdefault(kind, [])
        if where is not None and len(shown) < SHOWN:
            shown.append(where)
        if note and kind not in self._notes:
            self._notes[kind] = note

    def add_lines(self, kind: str, mask: np.ndarray, lines: np.ndarray, cells: Any = None) -> None:
        """Count every row where ``mask`` is True as ``kind``, the first few as ``line L (cell)``.

        Args:
            kind: the kind of problem.
            mask: (M,) bool, one per row.
            lines: (M,) int, each row's line in the file.
            cells: (M,) the values shown beside the lines, or None.
        """
        hit = np.flatnonzero(mask)
        for i in hit[:SHOWN]:
            where = f"line {int(lines[i])}"
            if cells is not None:
                where += f" ({show(str(cells[i]))})"
            self.add(kind, where)
        if hit.size > SHOWN:
            self.add(kind, count=int(hit.size - SHOWN))

    def _take(self, other: Problems, kind: str) -> None:
        shown = other._shown.get(kind, [])
        note = other._notes.get(kind, "")
        for where in shown:
            self.add(kind, where, note, at=other._first.get(kind))
        if other._counts[kind] > len(shown) or not shown:
            self.add(kind, None, note, count=other._counts[kind] - len(shown), at=other._first.get(kind))

    def extend(self, other: Problems) -> None:
        """Add every problem of ``other`` (its kinds after this one's)."""
        for kind in other._counts:
            self._take(other, kind)

    @staticmethod
    def by_line(*parts: Problems) -> Problems:
        """``parts`` merged, kinds in the order of the line each first occurs on."""
        kinds = [(p._first.get(k, 0), i, j, k) for i, p in enumerate(parts) for j, k in enumerate(p._counts)]
        merged = Problems(parts[0].unit if parts else "row")
        for _, i, _, k in sorted(kinds):
            merged._take(parts[i], k)
        return merged

    def copy(self) -> Problems:
        """An independent copy (a later stage adds to it without changing the first)."""
        new = Problems(self.unit)
        new._shown = {k: list(v) for k, v in self._shown.items()}
        new._counts = dict(self._counts)
        new._notes = dict(self._notes)
        new._first = dict(self._first)
        return new

    def __bool__(self) -> bool:
        return bool(self._counts)

    def lines(self) -> list[str]:
        """One line per kind: the kind, its count, where, and a note; bounded in length."""
        out = []
        for kind, shown in self._shown.items():
            n = self._counts[kind]
            line = kind
            if shown:
                more = f", ... ({n - len(shown)} more)" if n > len(shown) else ""
                line += f" ({plural(n, self.unit)}): " + ", ".join(shown) + more
            if kind in self._notes:
                line += f"; {self._notes[kind]}"
            out.append(clip(line))
        if len(out) > MAX_KINDS:
            out = out[:MAX_KINDS] + [f"... and {len(out) - MAX_KINDS} more kinds of problem"]
        return out

    def error(self, name: str) -> ValidationError:
        """The error naming every problem, titled ``"NAME cannot be scored: k problems found"``."""
        lines = self.lines()
        return ValidationError(
            f"{clip(name, 300)} cannot be scored: {plural(len(lines), 'problem')} found", lines
        )
