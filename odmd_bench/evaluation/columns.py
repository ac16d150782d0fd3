"""The predictions format's columns: the header check and single-valued columns."""

from __future__ import annotations

import difflib
import re

from odmd_bench.evaluation.uncertainty import UNCERTAINTY_COLUMNS, header_problems
from odmd_bench.inputs.formats import SEQUENCE_COLUMNS
from odmd_bench.inputs.problems import Problems, closest, plural, show

#: Columns every predictions file must have.
REQUIRED_COLUMNS: tuple[str, ...] = ("split", "set", "index", "depth")
#: Columns that are read when present; any other column is ignored. The uncertainty
#: columns (:data:`~odmd_bench.evaluation.uncertainty.UNCERTAINTY_COLUMNS`) are read too.
OPTIONAL_COLUMNS: tuple[str, ...] = ("benchmark",)
_KNOWN = REQUIRED_COLUMNS + OPTIONAL_COLUMNS + UNCERTAINTY_COLUMNS
#: Header cells a message lists at most.
_HEADER_SHOWN = 12


def _misspelt(name: str, column: str) -> bool:
    """Whether header cell ``name`` is ``column`` written otherwise (case, ``_``, a typo or two).

    Example:
        >>> [_misspelt(h, "benchmark") for h in ("Benchmark", "bench_mark", "benchmrk", "benchmark_notes")]
        [True, True, True, False]
    """
    folded = re.sub(r"[^0-9a-z]", "", name.lower())
    if folded == column:
        return True
    return (
        abs(len(folded) - len(column)) <= 2 and difflib.SequenceMatcher(None, folded, column).ratio() >= 0.85
    )


def check_header(header: list[str], problems: Problems) -> dict[str, int] | None:
    """Column positions by name, or None (with ``problems`` added) when the header is wrong."""
    cols: dict[str, int] = {}
    trailing = len(header) - len("".join("x" if h else " " for h in header).rstrip())
    if trailing:
        # Spreadsheets write empty columns as trailing commas: not columns of the format.
        header = header[: len(header) - trailing]
    for i, name in enumerate(header):
        if name in cols:
            problems.add(f"column {show(name)} appears more than once in the header")
        else:
            cols[name] = i
    for c in OPTIONAL_COLUMNS + UNCERTAINTY_COLUMNS:
        if c not in cols:
            for h in header:
                if h not in _KNOWN and _misspelt(h, c):
                    problems.add(
                        f"column {show(h)} looks like the optional column {c!r} misspelt, whose "
                        f"values would then be ignored: name it {c} (or rename it, if it is something else)"
                    )
    header_problems(cols, problems)
    missing = [c for c in REQUIRED_COLUMNS if c not in cols]
    if not missing:
        return None if problems else cols
    spare = [h for h in header if h not in _KNOWN][:100]
    for c in missing:
        near = closest(c, spare)
        found = near[len("; did you mean ") : -1] if near else ""
        problems.add(f"missing column {c!r}" + (f" (the header has {found}: misspelt?)" if found else ""))
    if len(header) == 1:
        for sep, name in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")):
            if sep in header[0]:
                problems.add(f"the header {show(header[0])} seems to use {name} as separator; use commas")
                break
    if {"sequence", "observation"} <= set(cols) and set(SEQUENCE_COLUMNS) <= set(cols):
        problems.add(
            "this is a sequences file (boxes and camera motion for `odmd-bench predict`), not "
            "predictions: estimate its depths with `odmd-bench predict FILE --method NAME "
            "--image-size W H` (it prints their error where the file gives true depths); "
            "evaluate scores predictions for a benchmark's sets"
        )
    listed = ", ".join(show(h) for h in header[:_HEADER_SHOWN])
    if len(header) > _HEADER_SHOWN:
        listed += f", ... ({len(header) - _HEADER_SHOWN} more)"
    problems.add(
        f"the header is {listed}; expected the columns {', '.join(REQUIRED_COLUMNS)} "
        f"(optional: {', '.join(OPTIONAL_COLUMNS)}; others are ignored)"
    )
    return None


def single_value(tally: dict[str, list[int]], problems: Problems, what: str) -> str | None:
    """The one valid value of a column, or None (a problem added when there are several).

    Args:
        tally: ``{value: [rows, first line]}`` of the valid values, in order of appearance.
        problems: where a file holding several values is reported.
        what: ``"split"`` or ``"benchmark"``.
    """
    if len(tally) > 1:
        parts = [f"{v} ({plural(n, 'row')}, first on line {first})" for v, (n, first) in tally.items()]
        problems.add(f"a file holds one {what}, this one has {len(tally)}: {', '.join(parts)}")
        return None
    return next(iter(tally), None)
