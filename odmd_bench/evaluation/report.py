"""Formatting evaluation and comparison results for people and scripts.

Scoring returns data (:mod:`odmd_bench.evaluation.scoring`, :mod:`odmd_bench.evaluation.compare`); this
module only turns it into text: ``table`` (the layout of the paper's detailed tables:
one row per set with mean, median, min, max and std of percent error and of absolute
error, then ``All``), ``json`` (docs/format.md, "JSON output"), ``csv`` and ``markdown``. It also
writes the per-example CSV (:func:`write_per_example`), atomically.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Callable
from typing import Any

import numpy as np

from odmd_bench.errors import UsageError
from odmd_bench.evaluation.compare import Comparison, PairedDifference
from odmd_bench.evaluation.metrics import STATS
from odmd_bench.evaluation.result import PER_EXAMPLE_COLUMNS as PER_EXAMPLE_COLUMNS
from odmd_bench.evaluation.result import EvaluationResult
from odmd_bench.outputs import atomic_write

FORMATS: tuple[str, ...] = ("table", "json", "csv", "markdown")


def _check_format(fmt: str) -> None:
    if fmt not in FORMATS:
        raise UsageError(f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}")


def _pct(stat: str, v: float) -> str:
    # The paper prints the minimum percent error with 4 decimals, the rest with 2.
    return f"{v:.4f}" if stat == "min" else f"{v:.2f}"


def _header_line(result: EvaluationResult) -> str:
    prov = result.provenance
    return (
        f"{result.benchmark} {result.split}: {prov.get('predictions_file', '')} "
        f"(sha256 {str(prov.get('predictions_sha256', ''))[:12]}), odmd-bench {prov.get('version', '')}"
    )


def format_table(result: EvaluationResult) -> str:
    """The paper's layout as fixed-width text.

    Percent error in %, absolute error in metres. ``All`` is the mean of the listed
    sets' mean percent errors (the paper's "All Sets").
    """
    cells = {
        s: (
            [_pct(k, m["percent_error"][k]) for k in STATS],
            [f"{m['absolute_error'][k]:.4f}" for k in STATS],
        )
        for s, m in result.sets.items()
    }
    # Columns widen for huge errors (a method can be off by 10,000%) so they never merge.
    longest = max([len(c) for pct, ab in cells.values() for c in pct + ab], default=0)
    w = max(8, longest + 2)
    name_w = max([len("set"), len("All")] + [len(s) for s in result.sets])
    lines = [_header_line(result), ""]
    pct_block = "percent error (%)".center(5 * w)
    abs_block = "absolute error (m)".center(5 * w)
    lines.append((" " * (name_w + 7) + pct_block + "  " + abs_block).rstrip())
    head = f"{'set':<{name_w}} {'n':>6}" + "".join(f"{s:>{w}}" for s in STATS)
    head += "  " + "".join(f"{s:>{w}}" for s in STATS)
    lines.append(head)
    lines.append("-" * len(head))
    for s, m in result.sets.items():
        pct, ab = cells[s]
        row = f"{s:<{name_w}} {m['n']:>6}" + "".join(f"{c:>{w}}" for c in pct)
        row += "  " + "".join(f"{c:>{w}}" for c in ab)
        lines.append(row)
    lines.append("-" * len(head))
    n_all = sum(m["n"] for m in result.sets.values())
    lines.append(f"{'All':<{name_w}} {n_all:>6}{result.all_percent_error_mean:>{w}.2f}")
    lines.append("")
    lines.append(f"All = mean of the mean percent errors of {', '.join(result.sets)}")
    if result.uncertainty:
        lines += ["", *_uncertainty_table(result)]
    return "\n".join(lines) + "\n"


# --- uncertainty (only for files with the optional columns) ---------------------------


def _unc_columns(result: EvaluationResult) -> list[tuple[str, str, Callable[[dict[str, Any]], str]]]:
    """``(header, csv name, cell of a set's metrics)`` for the uncertainty scores present."""
    first = next(iter(result.sets.values()))
    cols: list[tuple[str, str, Callable[[dict[str, Any]], str]]] = []
    if "coverage" in first:
        cols += [
            ("coverage %", "coverage", lambda m: f"{100 * m['coverage']['observed']:.2f}"),
            ("- level", "coverage_error", lambda m: signed(100 * m["coverage"]["error"])),
            ("below %", "below", lambda m: f"{100 * m['coverage']['below']:.2f}"),
            ("above %", "above", lambda m: f"{100 * m['coverage']['above']:.2f}"),
            ("width %", "sharpness_mean", lambda m: f"{m['sharpness']['mean']:.2f}"),
            ("interval score %", "interval_score_mean", lambda m: f"{m['interval_score']['mean']:.2f}"),
        ]
    if "crps" in first:
        cols.append(("CRPS %", "crps_mean", lambda m: f"{m['crps']['mean']:.2f}"))
    return cols


def _unc_all(result: EvaluationResult) -> dict[str, str]:
    """The ``All`` row's cells of the uncertainty table, by csv name."""
    a = result.all_uncertainty
    out: dict[str, str] = {
        k: f"{a[k]:.2f}" for k in ("sharpness_mean", "interval_score_mean", "crps_mean") if k in a
    }
    if "coverage" in a:
        out["coverage"] = f"{100 * a['coverage']:.2f}"
        out["coverage_error"] = signed(100 * a["coverage_error"])
    return out


def _unc_title(result: EvaluationResult) -> str:
    first = next(iter(result.sets.values()))
    parts = []
    if "coverage" in first:
        parts.append(f"central {first['coverage']['level']:g} interval (depth_lo, depth_hi)")
    if "crps" in first:
        parts.append("normal N(depth, depth_std^2)")
    return "uncertainty: " + " and ".join(parts) + "; in % of the true depth"


def _uncertainty_table(result: EvaluationResult) -> list[str]:
    cols = _unc_columns(result)
    rows = [[s] + [cell(m) for _, _, cell in cols] for s, m in result.sets.items()]
    total = _unc_all(result)
    rows.append(["All"] + [total.get(key, "") for _, key, _ in cols])
    head = ["set"] + [h for h, _, _ in cols]
    widths = [max(len(head[i]), *(len(r[i]) for r in rows)) for i in range(len(head))]

    def line(cells: list[str]) -> str:
        return "  ".join(
            [f"{cells[0]:<{widths[0]}}"] + [f"{c:>{widths[i]}}" for i, c in enumerate(cells[1:], 1)]
        )

    out = [_unc_title(result), line(head), "-" * len(line(head))]
    out += [line(r) for r in rows[:-1]] + ["-" * len(line(head)), line(rows[-1])]
    out.append("All = mean over the sets; '- level': observed coverage minus the stated level (points)")
    return out


def format_markdown(result: EvaluationResult) -> str:
    """A GitHub-flavoured markdown table with the same rows and columns as the table."""
    cols = ["set", "n"] + [f"% {k}" for k in STATS] + [f"abs {k} (m)" for k in STATS]
    lines = [
        f"**{result.benchmark} {result.split}**, percent error (%) and absolute error (m)",
        "",
        "| " + " | ".join(cols) + " |",
        "| --- | " + " | ".join("---:" for _ in cols[1:]) + " |",
    ]
    for s, m in result.sets.items():
        cells = [s, str(m["n"])]
        cells += [_pct(k, m["percent_error"][k]) for k in STATS]
        cells += [f"{m['absolute_error'][k]:.4f}" for k in STATS]
        lines.append("| " + " | ".join(cells) + " |")
    n_all = sum(m["n"] for m in result.sets.values())
    cells = ["**All**", str(n_all), f"**{result.all_percent_error_mean:.2f}**"] + [""] * (len(cols) - 3)
    lines.append("| " + " | ".join(cells) + " |")
    if result.uncertainty:
        ucols = _unc_columns(result)
        lines += ["", f"**{_unc_title(result)}**", ""]
        lines.append("| set | " + " | ".join(h for h, _, _ in ucols) + " |")
        lines.append("| --- | " + " | ".join("---:" for _ in ucols) + " |")
        for s, m in result.sets.items():
            lines.append(f"| {s} | " + " | ".join(cell(m) for _, _, cell in ucols) + " |")
        total = _unc_all(result)
        lines.append("| **All** | " + " | ".join(total.get(key, "") for _, key, _ in ucols) + " |")
    return "\n".join(lines) + "\n"


def format_csv(result: EvaluationResult) -> str:
    """One row per set, then ``All``; numbers at full precision (``repr``)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    cols = ["benchmark", "split", "set", "n"]
    cols += [f"percent_error_{k}" for k in STATS] + [f"absolute_error_{k}" for k in STATS]
    extra = _csv_uncertainty(result)
    writer.writerow(cols + list(extra))
    for s, m in result.sets.items():
        row: list[Any] = [result.benchmark, result.split, s, m["n"]]
        row += [repr(m["percent_error"][k]) for k in STATS]
        row += [repr(m["absolute_error"][k]) for k in STATS]
        writer.writerow(row + [repr(get(m)) for get in extra.values()])
    n_all = sum(m["n"] for m in result.sets.values())
    a = result.all_uncertainty
    writer.writerow(
        [result.benchmark, result.split, "All", n_all, repr(result.all_percent_error_mean)]
        + [""] * (len(cols) - 5)
        + [repr(a[k]) if k in a else "" for k in extra]
    )
    return buf.getvalue()


def _csv_uncertainty(result: EvaluationResult) -> dict[str, Callable[[dict[str, Any]], float]]:
    """The csv's uncertainty columns (none without the optional columns): name -> a set's value."""
    if not result.uncertainty:
        return {}
    first = next(iter(result.sets.values()))
    out: dict[str, Callable[[dict[str, Any]], float]] = {}
    if "coverage" in first:
        out["level"] = lambda m: m["coverage"]["level"]
        out["coverage"] = lambda m: m["coverage"]["observed"]
        out["coverage_error"] = lambda m: m["coverage"]["error"]
        out["sharpness_mean"] = lambda m: m["sharpness"]["mean"]
        out["interval_score_mean"] = lambda m: m["interval_score"]["mean"]
    if "crps" in first:
        out["crps_mean"] = lambda m: m["crps"]["mean"]
    return out


def format_json(result: EvaluationResult) -> str:
    """The JSON object of docs/format.md, "JSON output": strict JSON, never ``NaN`` or ``Infinity``.

    Its keys are ``benchmark``, ``split``, ``sets``, ``all``, ``provenance``, plus ``warnings``.
    """
    return json.dumps(result.to_dict(), indent=2, allow_nan=False) + "\n"


_FORMATTERS: dict[str, Callable[[EvaluationResult], str]] = {
    "table": format_table,
    "json": format_json,
    "csv": format_csv,
    "markdown": format_markdown,
}


def format_result(result: EvaluationResult, fmt: str = "table") -> str:
    """``result`` as text in one of :data:`FORMATS`."""
    _check_format(fmt)
    return _FORMATTERS[fmt](result)


def per_example_rows(result: EvaluationResult) -> dict[str, np.ndarray]:
    """The per-example columns (:data:`PER_EXAMPLE_COLUMNS`); see :meth:`EvaluationResult.per_example`."""
    return result.per_example()


def format_per_example(result: EvaluationResult) -> str:
    """The per-example CSV text (see :func:`per_example_rows`); floats at full precision."""
    cols = per_example_rows(result)
    buf = io.StringIO()
    buf.write(",".join(cols) + "\n")
    ints = {"index", "n_detected", "covered"}
    as_text = [
        cols[c].tolist() if c in ints or c == "set" else [repr(float(v)) for v in cols[c]] for c in cols
    ]
    for row in zip(*as_text, strict=True):
        buf.write(",".join(str(v) for v in row) + "\n")
    return buf.getvalue()


def write_per_example(path: str | os.PathLike[str], result: EvaluationResult) -> None:
    """Write the per-example CSV atomically (no partial file on failure)."""
    text = format_per_example(result)
    with atomic_write(path, "w") as fh:
        fh.write(text)


# --- comparisons -----------------------------------------------------------------


def signed(x: float, decimals: int = 2) -> str:
    """``x`` with its sign, as the comparison table shows it; a value that rounds to 0 is ``+0.00``.

    Examples:
        >>> signed(-0.0), signed(-0.004), signed(1.234), signed(-1.236)
        ('+0.00', '+0.00', '+1.23', '-1.24')
    """
    text = f"{x:+.{decimals}f}"
    return f"{0.0:+.{decimals}f}" if float(text) == 0 else text


def _cmp_cells(name: str, d: PairedDifference) -> list[str]:
    return [
        name,
        str(d.n),
        f"{d.mean_a:.2f}",
        f"{d.mean_b:.2f}",
        signed(d.difference),
        f"[{signed(d.ci_low)}, {signed(d.ci_high)}]",
        f"{d.p_value:.4f}",
        d.verdict,
    ]


_CMP_COLS = ["set", "n", "A mean %", "B mean %", "A - B", "interval", "p", "verdict"]


def _cmp_note(c: Comparison) -> str:
    what = "mean percent error" if c.metric == "percent_error_mean" else "mean interval score (% of depth)"
    return (
        f"A - B of {what}; {c.confidence:.0%} paired bootstrap interval and sign-flip test "
        f"({c.n_resamples} resamples, seed {c.seed}); negative: A's error is lower"
    )


def format_comparison(c: Comparison, fmt: str = "table") -> str:
    """A comparison as text in one of :data:`FORMATS`."""
    _check_format(fmt)
    rows = [_cmp_cells(s, d) for s, d in c.sets.items()] + [_cmp_cells("All", c.all)]
    prov = c.provenance
    files = ""
    if prov.get("a") and prov.get("b"):
        files = f"A = {prov['a'].get('predictions_file')}, B = {prov['b'].get('predictions_file')}"
    if fmt == "json":
        return json.dumps(c.to_dict(), indent=2, allow_nan=False) + "\n"
    if fmt == "csv":
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(
            [
                "benchmark",
                "split",
                "set",
                "n",
                "mean_a",
                "mean_b",
                "difference",
                "ci_low",
                "ci_high",
                "p_value",
                "verdict",
            ]
        )
        for s, d in [*c.sets.items(), ("All", c.all)]:
            writer.writerow(
                [c.benchmark, c.split, s, d.n]
                + [repr(v) for v in (d.mean_a, d.mean_b, d.difference, d.ci_low, d.ci_high, d.p_value)]
                + [d.verdict]
            )
        return buf.getvalue()
    if fmt == "markdown":
        lines = [f"**{c.benchmark} {c.split}**: {files}", "", "| " + " | ".join(_CMP_COLS) + " |"]
        lines.append("| --- | " + " | ".join("---:" for _ in _CMP_COLS[1:-1]) + " | --- |")
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        lines += ["", _cmp_note(c)]
        return "\n".join(lines) + "\n"
    widths = [max(len(_CMP_COLS[i]), *(len(r[i]) for r in rows)) for i in range(len(_CMP_COLS))]

    def fmt_row(cells: list[str]) -> str:
        out = [f"{cells[0]:<{widths[0]}}"] + [f"{v:>{widths[i]}}" for i, v in enumerate(cells[1:-1], 1)]
        return "  ".join(out + [cells[-1]])

    lines = [f"{c.benchmark} {c.split}: {files}", "", fmt_row(_CMP_COLS)]
    lines.append("-" * len(lines[-1]))
    lines += [fmt_row(r) for r in rows[:-1]]
    lines.append("-" * len(lines[2]))
    lines.append(fmt_row(rows[-1]))
    lines += ["", _cmp_note(c)]
    return "\n".join(lines) + "\n"
