"""Results reported in publications without predictions (``reported.yaml``): read and checked.

They are shown in a separate table, never re-scored, ranked or grouped. Values are kept
as written (text such as ``"4.5"``), so the table shows the precision the source gave.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from odmd_bench.data.registry import BENCHMARKS
from odmd_bench.documents import MAX_DOCUMENT_BYTES, DocumentError, load_document
from odmd_bench.errors import ValidationError
from odmd_bench.leaderboard.rules import show

REPORTED = "reported.yaml"
#: Fields every reported result must have, and those it may have.
REPORTED_FIELDS: tuple[str, ...] = ("method", "benchmark", "split", "sets", "all", "training_data", "source")
REPORTED_OPTIONAL: tuple[str, ...] = ("entry", "notes", "input")
#: What a method takes as its vision input (``input``; default ``detection``).
INPUTS: tuple[str, ...] = ("detection", "segmentation")
#: Longest text of a field, in characters.
MAX_TEXT = 300


@dataclass(frozen=True)
class ReportedResult:
    """One published result.

    Attributes:
        method, benchmark, split: what was reported.
        sets: ``{set: value as printed}`` in the benchmark's set order.
        all: the All value as printed.
        training_data, source: what it trained on; where it was printed.
        entry: the id of an entry that reproduces the method here, if any.
        notes: anything else.
        input: ``detection`` (boxes, as scored here) or ``segmentation`` (masks: not
            the input the entries get, so not comparable with them).
    """

    method: str
    benchmark: str
    split: str
    sets: Mapping[str, str]
    all: str
    training_data: str
    source: str
    entry: str | None = None
    notes: str | None = None
    input: str = field(default="detection")

    def to_dict(self) -> dict[str, object]:
        """The result as written into ``leaderboard.json``."""
        return {
            "method": self.method,
            "benchmark": self.benchmark,
            "split": self.split,
            "sets": dict(self.sets),
            "all": self.all,
            "training_data": self.training_data,
            "source": self.source,
            "entry": self.entry,
            "notes": self.notes,
            "input": self.input,
        }


def _number(value: object) -> bool:
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        return False
    try:
        float(str(value))
    except ValueError:
        return False
    return True


def _field_problems(item: Mapping[str, object], where: str) -> list[str]:
    """Unknown, missing and malformed text fields."""
    problems = []
    for k in item:
        if k not in REPORTED_FIELDS + REPORTED_OPTIONAL:
            problems.append(
                f"{where}: unknown field {show(k)}; expected {', '.join(REPORTED_FIELDS + REPORTED_OPTIONAL)}"
            )
    problems += [f"{where}: missing field {k!r}" for k in REPORTED_FIELDS if item.get(k) in (None, "")]
    for k in (*REPORTED_FIELDS, *REPORTED_OPTIONAL):
        v = item.get(k)
        if k not in ("sets", "all") and v is not None and (not isinstance(v, str) or len(v) > MAX_TEXT):
            problems.append(
                f"{where}: field {k!r} must be text of at most {MAX_TEXT} characters, got {show(v)}"
            )
    if item.get("input") not in (None, *INPUTS):
        problems.append(f"{where}: input must be one of {', '.join(INPUTS)}")
    return problems


def _value_problems(item: Mapping[str, object], where: str) -> list[str]:
    """The benchmark, and a number for each of its sets and for All."""
    bench = item.get("benchmark")
    if bench is not None and bench not in BENCHMARKS:
        return [f"{where}: unknown benchmark {show(bench)}"]
    values = item.get("sets")
    if not isinstance(values, dict):
        return [f"{where}: sets must map each set to its value"]
    problems = []
    if isinstance(bench, str) and sorted(map(str, values)) != sorted(BENCHMARKS[bench].sets):
        problems.append(f"{where}: sets must be exactly {', '.join(BENCHMARKS[bench].sets)}")
    for s, v in [*values.items(), ("all", item.get("all"))]:
        if not _number(v):
            problems.append(f"{where}: value of {show(s)} is not a number: {show(v)}")
    return problems


def _result(item: Mapping[str, object]) -> ReportedResult:
    text = {k: str(v) for k in (*REPORTED_FIELDS, *REPORTED_OPTIONAL) if (v := item.get(k)) is not None}
    values = item["sets"]
    sets = BENCHMARKS[text["benchmark"]].sets
    written = {str(s): str(v) for s, v in values.items()} if isinstance(values, dict) else {}
    return ReportedResult(
        method=text["method"],
        benchmark=text["benchmark"],
        split=text["split"],
        sets={s: written[s] for s in sets},
        all=text["all"],
        training_data=text["training_data"],
        source=text["source"],
        entry=text.get("entry"),
        notes=text.get("notes"),
        input=text.get("input", "detection"),
    )


def read_reported(root: str | os.PathLike[str]) -> list[ReportedResult]:
    """The results of ``ROOT/reported.yaml``, checked (an empty list when there is none).

    Raises:
        ValidationError: Naming every problem (the file is read with the bounded YAML reader).
    """
    path = Path(root) / REPORTED
    if not path.exists():
        return []
    try:
        if path.is_symlink():
            raise DocumentError("it is a symbolic link; links are not followed")
        with path.open("rb") as fh:  # at most the cap plus one byte, which load_document refuses
            data = load_document(fh.read(MAX_DOCUMENT_BYTES + 1), "yaml")
    except (OSError, DocumentError) as e:
        raise ValidationError(f"{path} cannot be read", [str(e)]) from None
    if data is None:
        return []
    if not isinstance(data, list):
        raise ValidationError(f"{path} cannot be used", ["it must hold a list of results"])
    problems = []
    out = []
    for i, item in enumerate(data):
        if not isinstance(item, dict):
            problems.append(f"result {i + 1}: must be a mapping")
            continue
        where = f"result {i + 1} ({show(item.get('method', '?'))})"
        found = _field_problems(item, where) + _value_problems(item, where)
        problems += found
        if not found:
            out.append(_result(item))
    if problems:
        raise ValidationError(f"{path} cannot be used", problems)
    return out
