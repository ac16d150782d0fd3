"""What a method's report says, sorted: fallbacks, repairs, other counts and notes.

A method's ``predict_report`` returns counts and strings. Only some counts are
fallbacks (an example the method could not solve, given a stand-in depth): those its
module declares in ``FALLBACKS``. A module may declare ``REPAIRS`` (examples whose input
it changed before solving, e.g. ``dbox-guard``'s wrong starts); any other count (a
plug-in's own keys, parallax's ``no_lateral_motion``) is shown as counted, and the
strings (which weights ran) as they are. ``odmd-bench predict`` and ``odmd-bench
baseline`` print one line from :func:`report_line`.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import Any


def declared(method: Any, name: str) -> tuple[str, ...]:
    """A tuple a method declares: its attribute ``name``, else its ``predict``'s module's."""
    value = getattr(method, name, None)
    if value is None:
        module = inspect.getmodule(getattr(method, "predict", method))
        value = getattr(module, name, None)
    return tuple(str(v) for v in value) if isinstance(value, tuple | list) else ()


def report_line(method: Any, report: Mapping[str, int | str], skip: Mapping[str, Any] | None = None) -> str:
    """``fallbacks: K N, ...; repairs: ...; counted: ...; NOTE VALUE; ...`` for a report.

    Args:
        method: the loaded method (its ``FALLBACKS`` and ``REPAIRS``).
        report: what its ``predict_report`` returned (``n`` is left out, and zero counts).
        skip: notes (strings) said elsewhere, left out.
    """
    fallbacks, repairs = declared(method, "FALLBACKS"), declared(method, "REPAIRS")
    parts: dict[str, list[str]] = {"fallbacks": [], "repairs": [], "counted": []}
    notes = []
    for key, value in report.items():
        if isinstance(value, str):
            if skip is None or key not in skip:
                notes.append(f"{key} {value}")
        elif key != "n" and value:
            kind = "fallbacks" if key in fallbacks else "repairs" if key in repairs else "counted"
            parts[kind].append(f"{key} {value}")
    line = f"fallbacks: {', '.join(parts['fallbacks']) or 'none'}"
    for kind in ("repairs", "counted"):
        if parts[kind]:
            line += f"; {kind}: {', '.join(parts[kind])}"
    return line + "".join(f"; {n}" for n in notes)


__all__ = ["declared", "report_line"]
