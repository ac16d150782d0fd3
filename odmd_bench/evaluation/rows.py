"""The rows of a predictions CSV: the checks of each row.

The streaming pass of :func:`~odmd_bench.evaluation.parse.parse_predictions`: records
(:func:`odmd_bench.inputs.records.records`) are read one at a time and kept as flat
arrays (about 30 bytes a row), never as a list of rows.
"""

from __future__ import annotations

import math
import re
from array import array
from collections.abc import Sequence

from odmd_bench.data.registry import BENCHMARKS, SPLITS
from odmd_bench.evaluation.kinds import MAX_ABS_DEPTH, NONFINITE, OUT_OF_RANGE, TOO_LARGE
from odmd_bench.inputs.problems import SHOWN, Problems, clip, closest, show

_INT = re.compile(r"[+-]?[0-9]+")
_FLOAT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_is_int, _is_float = _INT.fullmatch, _FLOAT.fullmatch
_NAN = float("nan")
_BENCHMARK_NAMES = tuple(sorted(BENCHMARKS))


class Rows:
    """Accumulates the rows of a file (the streaming pass of :func:`parse_predictions`)."""

    def __init__(self, cols: dict[str, int], width: int) -> None:
        self.cols, self.width = cols, width
        self.at = (cols["split"], cols["set"], cols["index"], cols["depth"], cols.get("benchmark", -1))
        self.fields, self.values = Problems(), Problems()
        self.split_tally: dict[str, list[int]] = {}
        self.bench_tally: dict[str, list[int]] = {}
        self.split_bad, self.bench_bad = Problems(), Problems()
        self.codes: dict[str, int] = {}
        self.code, self.line, self.index = array("i"), array("q"), array("q")
        self.depth, self.index_ok = array("d"), array("b")
        self.nonpositive: dict[int, list[tuple[int, str]]] = {}
        self.n = 0

    def add(self, line: int, cells: list[str]) -> None:
        """Check one row and keep what it holds (the hot loop: kept lean on purpose)."""
        self.n += 1
        if len(cells) != self.width:
            self.fields.add(
                "wrong number of fields",
                f"line {line} ({len(cells)} {'field' if len(cells) == 1 else 'fields'})",
                note=f"every row must have {self.width} like the header",
            )
            return
        i_split, i_set, i_index, i_depth, i_bench = self.at
        seen = self.split_tally.get(cells[i_split])
        if seen is None:
            _tally(self.split_tally, cells[i_split], line, SPLITS, self.split_bad, "split")
        else:
            seen[0] += 1
        if i_bench >= 0:
            seen = self.bench_tally.get(cells[i_bench])
            if seen is None:
                _tally(self.bench_tally, cells[i_bench], line, _BENCHMARK_NAMES, self.bench_bad, "benchmark")
            else:
                seen[0] += 1
        name, index_s, depth_s = cells[i_set], cells[i_index], cells[i_depth]
        code = self.codes.setdefault(name, len(self.codes))
        ok = len(index_s) <= 18 and (index_s.isdigit() and index_s.isascii() or _is_int(index_s) is not None)
        if ok:
            index = int(index_s)
        else:
            index = 0
            kind = "index out of range" if _is_int(index_s) else "index is not an integer"
            self.values.add(kind, f"line {line} ({show(index_s)})", at=line)
        depth = float(depth_s) if _is_float(depth_s) else _NAN
        if not -MAX_ABS_DEPTH <= depth <= MAX_ABS_DEPTH:  # NaN too
            depth = self._bad_depth(line, depth_s, depth)
        elif depth <= 0 and ok:
            shown = self.nonpositive.setdefault(code, [])
            if len(shown) < SHOWN:
                shown.append((line, f"line {line} ({name} {index}: {clip(depth_s, 40)})"))
        self.code.append(code)
        self.line.append(line)
        self.index.append(index)
        self.depth.append(depth)
        self.index_ok.append(ok)

    def _bad_depth(self, line: int, text: str, depth: float) -> float:
        """Record why a depth is refused; NaN stands for it from now on."""
        if depth == depth:  # a number, too large
            kind = TOO_LARGE if math.isinf(depth) else OUT_OF_RANGE
        elif _NONFINITE.fullmatch(text):
            kind = NONFINITE
        else:
            kind = "depth is not a number"
        self.values.add(kind, f"line {line} ({show(text)})", at=line)
        return float("nan")


def _tally(
    tally: dict[str, list[int]], value: str, line: int, valid: Sequence[str], bad: Problems, what: str
) -> None:
    seen = tally.get(value)
    if seen is not None:
        seen[0] += 1
    elif value in valid:
        tally[value] = [1, line]
    else:
        bad.add(
            f"unknown {what} in column {what!r}",
            f"line {line} ({show(value)}{closest(value, valid).replace('; ', ': ')})",
            note=f"expected one of {', '.join(valid)}",
        )
