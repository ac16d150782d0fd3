"""The generated texts: ``LEADERBOARD.md`` and ``leaderboard.json`` (derived, never committed).

:func:`build` computes them (nothing is written; :func:`~odmd_bench.leaderboard.output.write`
writes them). Every function here is pure given the boards.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from odmd_bench.data.registry import BENCHMARKS
from odmd_bench.errors import ValidationError
from odmd_bench.evaluation.compare import PairedDifference
from odmd_bench.leaderboard.board import Board, Row, collect
from odmd_bench.leaderboard.files import ENTRIES
from odmd_bench.leaderboard.ranking import RANK_CONFIDENCE, RANK_SEED, resamples, rule
from odmd_bench.leaderboard.reported import ReportedResult, read_reported
from odmd_bench.leaderboard.specs import JSON_DECIMALS, SET_TITLES
from odmd_bench.leaderboard.specs import rounded as _r
from odmd_bench.leaderboard.uncertainty import UncertaintyBoard
from odmd_bench.leaderboard.uncertainty import collect as collect_uncertainty
from odmd_bench.leaderboard.uncertainty import render_markdown as uncertainty_markdown
from odmd_bench.leaderboard.uncertainty import to_json as uncertainty_json


@dataclass(frozen=True)
class Built:
    """What :func:`build` computes: the boards, the reported results and the two texts."""

    boards: tuple[Board, ...]
    reported: tuple[ReportedResult, ...]
    markdown: str
    json_text: str
    #: ``{method: its latest recorded audit}`` (:func:`~odmd_bench.leaderboard.audit_files.shown`).
    audits: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    #: The uncertainty boards (:mod:`~odmd_bench.leaderboard.uncertainty`).
    uncertainty: tuple[UncertaintyBoard, ...] = ()


def build(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    n_resamples: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> Built:
    """Everything ``leaderboard build`` writes, computed (nothing is written).

    ``progress`` is called with a line per board (see :func:`~odmd_bench.leaderboard.board.collect`).

    Raises:
        ValidationError: Naming every problem with the entries (metadata, data,
            predictions) and with ``reported.yaml``.
    """
    from odmd_bench.leaderboard.audit_files import audit_problems, read_audits, shown

    n = resamples(n_resamples)
    boards, problems = collect(root, data_dir, original, n_resamples=n, progress=progress)
    recorded, found = read_audits(root)
    problems += found + audit_problems(recorded, boards)
    audits = shown(recorded)
    uncertain, found = collect_uncertainty(root, boards, n_resamples=n)
    problems += found
    reported: list[ReportedResult] = []
    try:
        reported = read_reported(root)
    except ValidationError as e:
        problems += [e.message, *(f"  {p}" for p in e.problems)]
    if problems:
        raise ValidationError("the leaderboard cannot be built", problems)
    return Built(
        boards=tuple(boards),
        reported=tuple(reported),
        markdown=render_markdown(boards, reported, n_resamples=n, audits=audits, uncertainty=uncertain),
        json_text=render_json(boards, reported, n_resamples=n, audits=audits, uncertainty=uncertain),
        audits=audits,
        uncertainty=tuple(uncertain),
    )


def _diff_dict(d: PairedDifference | None, a: str, b: str) -> dict[str, object] | None:
    """The evaluator's comparison of ``a`` (the leader) and ``b`` (this row): ``a - b``."""
    if d is None:
        return None
    return {
        "a": a,
        "b": b,
        "difference_a_minus_b": _r(d.difference),
        "ci_low": _r(d.ci_low),
        "ci_high": _r(d.ci_high),
        "p_value": _r(d.p_value),
        "verdict": d.verdict,
    }


def _json_row(
    board: Board, pos: int, row: Row, previous_leader: str, audit: Mapping[str, Any] | None = None
) -> dict[str, object]:
    res = row.result
    return {
        "position": pos,
        "group": row.group,
        "method": row.entry.method,
        "name": row.entry.meta.name,
        "all": _r(res.all_percent_error_mean),
        "sets": {
            s: {
                "n": int(m["n"]),
                **{err: {k: _r(v) for k, v in m[err].items()} for err in ("percent_error", "absolute_error")},
            }
            for s, m in res.sets.items()
        },
        "group_leader": row.leader,
        "versus_group_leader": _diff_dict(row.versus_leader, row.leader, row.entry.method),
        "versus_previous_group_leader": _diff_dict(row.versus_previous, previous_leader, row.entry.method),
        "warnings": list(res.warnings),
        "audit": dict(audit) if audit is not None else None,
        "entry": f"{ENTRIES}/{row.entry.key}",
        "predictions_file": row.entry.predictions.name,
        "predictions_csv_sha256": res.provenance["predictions_sha256"],
        "predictions_rows": res.provenance["predictions_rows"],
        "metadata": row.entry.meta.to_dict(),
    }


def render_json(
    boards: Sequence[Board],
    reported: Sequence[ReportedResult],
    *,
    n_resamples: int | None = None,
    audits: Mapping[str, Mapping[str, Any]] | None = None,
    uncertainty: Sequence[UncertaintyBoard] = (),
) -> str:
    """``leaderboard.json``: every board's rows with all metrics, metadata and provenance.

    A row of the audited board (odmd-v1 test) has ``audit``: its latest recorded
    fresh-seed audit (:func:`~odmd_bench.leaderboard.audit_files.shown`), else null.
    """
    out_boards = []
    for bd in boards:
        rows, previous_leader = [], ""
        for pos, row in enumerate(bd.rows, 1):
            if row.versus_previous is not None:
                previous_leader = next(r.leader for r in bd.rows if r.group == row.group - 1)
            rows.append(_json_row(bd, pos, row, previous_leader, _audit_of(bd, row, audits)))
        out_boards.append(
            {
                "benchmark": bd.benchmark,
                "split": bd.split,
                "data_version": bd.data_version if bd.rows else None,
                "sets": list(bd.sets),
                "sets_content_sha256": bd.sets_content_sha256,
                "rows": rows,
            }
        )
    out = {
        "generated_by": "odmd-bench leaderboard build",
        "metric": "percent_error (|Z - Z_hat| / Z * 100); all = mean of the sets' mean percent errors",
        "float_decimals": JSON_DECIMALS,
        "rank_groups": {
            "rule": rule(n_resamples),
            "n_resamples": resamples(n_resamples),
            "seed": RANK_SEED,
            "confidence": RANK_CONFIDENCE,
        },
        "boards": out_boards,
        "reported": [r.to_dict() for r in reported],
    }
    if uncertainty:
        out["uncertainty"] = uncertainty_json(uncertainty)
    return json.dumps(out, indent=2, sort_keys=False, ensure_ascii=False) + "\n"


def _audit_of(
    bd: Board, row: Row, audits: Mapping[str, Mapping[str, Any]] | None
) -> Mapping[str, Any] | None:
    """The audit shown for ``row`` (audits are of the odmd-v1 test board only)."""
    if not audits or (bd.benchmark, bd.split) != ("odmd-v1", "test"):
        return None
    return audits.get(row.entry.method)


def _audit_markdown(bd: Board, audits: Mapping[str, Mapping[str, Any]] | None) -> list[str]:
    """The board's fresh-seed audit table (README "Is a method tuned on the test set?"), if any."""
    shown = [(row, a) for row in bd.rows if (a := _audit_of(bd, row, audits)) is not None]
    if not shown:
        return []
    sets = ", ".join(SET_TITLES.get(s, s) for s in shown[0][1]["sets"])
    lines = [
        f"### {bd.spec.key}: fresh-seed audit",
        "",
        f"Each entry re-run on fresh draws of the generated sets ({sets}) by `odmd-bench leaderboard "
        "audit`: **Test** is the mean of the committed means of those sets, **Fresh** the same on the "
        "fresh draws with its 95% bootstrap interval. **Flagged**: on one of those sets or their mean, the "
        "test score is better than the fresh one by more than chance allows (one-sided permutation "
        "test, Holm-corrected over the audit's entries and tests, level "
        f"{shown[0][1]['level']}: flagged when the smallest adjusted p is at most that; see "
        "leaderboard/README.md). Entries not listed are not audited yet.",
        "",
    ]
    head = ["Method", "Test", "Fresh", "95% interval", "Fresh - test", "Smallest p (Holm)", "Flagged", "Seed"]
    lines += _table_head(head, range(1, 6))
    for row, a in shown:
        method = _cell(row.entry.meta.name)
        seed = f"[{a['seed']}]({a['file']})"
        if not a["runnable"]:
            lines.append(f"| {method} | - | - | - | - | - | not re-run: {_cell(a['reason'])} | {seed} |")
            continue
        lo, hi = a["fresh_interval"]
        cells = [
            method,
            _fmt(a["test"]),
            _fmt(a["fresh"]),
            f"[{_fmt(lo)}, {_fmt(hi)}]",
            f"{a['difference']:+.2f}".replace("-0.00", "+0.00"),
            f"{a['p_adjusted_smallest']:.3f}"
            if a["p_adjusted_smallest"] >= 0.001
            else f"{a['p_adjusted_smallest']:.1e}",
            "**yes**" if a["flagged"] else "no",
            seed,
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return [*lines, ""]


def _cell(text: str) -> str:
    """``text`` as one table cell of plain text: no column break, link, image or HTML tag."""
    text = str(text).replace("\\", "\\\\").replace("|", "\\|").replace("\n", " ")
    return text.replace("[", "\\[").replace("]", "\\]").replace("<", "&lt;").replace(">", "&gt;")


def format_number(x: float, decimals: int = 2) -> str:
    """``x`` as every table of the board prints it: ``decimals`` digits, never ``-0.00``.

    Shared by ``LEADERBOARD.md`` and the web site.

    Examples:
        >>> format_number(2.994531), format_number(-0.001), format_number(0.0141151, 4)
        ('2.99', '0.00', '0.0141')
    """
    s = f"{x:.{decimals}f}"
    return s[1:] if s.startswith("-") and not s.strip("-0.") else s


def format_difference(difference: float, ci_low: float, ci_high: float) -> str:
    """A comparison of a row B with a method A, ``A - B`` as the evaluator reports it, shown as ``B - A [low, high]``.

    Examples:
        >>> format_difference(-0.5, -0.75, -0.25)
        '+0.50 [+0.25, +0.75]'
    """
    diff, lo, hi = (-v + 0.0 for v in (difference, ci_high, ci_low))  # + 0.0: no -0
    return f"{diff:+.2f} [{lo:+.2f}, {hi:+.2f}]".replace("-0.00", "+0.00")


def _fmt(x: float) -> str:
    return format_number(x)


def _table_head(head: Sequence[str], numeric: range) -> list[str]:
    """A markdown table's header and alignment lines; columns in ``numeric`` align right."""
    align = "|".join(" ---: " if i in numeric else " --- " for i in range(len(head)))
    return ["| " + " | ".join(head) + " |", f"|{align}|"]


def _empty(bd: Board) -> str:
    return (
        "No entries yet. Add one with `odmd-bench leaderboard add PREDS.csv "
        f"--benchmark {bd.benchmark} --split {bd.split} ...` (see leaderboard/README.md)."
    )


def _vs_cell(row: Row) -> str:
    vs = row.versus_leader
    if vs is None:
        return "best" if row.group == 1 else "group best"
    # The evaluator reports leader - row; the table shows row - leader.
    return format_difference(vs.difference, vs.ci_low, vs.ci_high)


def _board_markdown(bd: Board, audits: Mapping[str, Mapping[str, Any]] | None = None) -> list[str]:
    desc = BENCHMARKS[bd.benchmark].description
    if not bd.rows:
        return [f"## {bd.spec.key}", "", f"Data: {desc}.", "", _empty(bd), ""]
    hashes = ", ".join(f"{s} `{h[:12]}`" for s, h in bd.sets_content_sha256.items())
    lines = [
        f"## {bd.spec.key}",
        "",
        f"Data: {desc}. Version: {bd.data_version}; content SHA-256 {hashes}.",
        "",
    ]
    head = ["Group", "Method", *[SET_TITLES.get(s, s) for s in bd.sets], "All", "vs group best"]
    head += ["Calibrated", "Trained on", "Data", "Date"]
    lines += _table_head(head, range(2, 3 + len(bd.sets)))
    for row in bd.rows:
        res, meta = row.result, row.entry.meta
        cells = [
            str(row.group),
            f"[{_cell(meta.name)}]({ENTRIES}/{row.entry.key}/)",
            *[_fmt(res.sets[s]["percent_error"]["mean"]) for s in bd.sets],
            f"**{_fmt(res.all_percent_error_mean)}**",
            _vs_cell(row),
            "yes" if meta.calibrated else "no",
            _cell(meta.training_data),
            f"{bd.benchmark} ({bd.data_version})",
            meta.date,
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return [*lines, "", *_audit_markdown(bd, audits)]


def _reported_markdown(boards: Sequence[Board], reported: Sequence[ReportedResult]) -> list[str]:
    rescored = {(r.entry.method, bd.benchmark, bd.split): r for bd in boards for r in bd.rows}
    lines = [
        "## Reported in papers (not reproducible here)",
        "",
        "**These numbers are copied from publications, not computed here**: no predictions are "
        "available, so they are not re-scored, take no group and are not comparable by the paired "
        "test. Where an entry above reproduces the method, its re-scored All is shown beside.",
        "",
    ]
    for bench, split in sorted({(r.benchmark, r.split) for r in reported}):
        rows = [r for r in reported if (r.benchmark, r.split) == (bench, split)]
        inputs = any(r.input != "detection" for r in rows)
        sets = BENCHMARKS[bench].sets
        head = ["Method", *(["Input"] if inputs else []), *[SET_TITLES.get(s, s) for s in sets], "All"]
        head += ["Trained on", "Source", "Re-scored here"]
        lines += [f"### {bench} {split} (reported)", ""]
        if inputs:
            lines += [
                "**Input**: *segmentation* methods take the original ODMS segmentation masks, not the "
                "boxes the entries above are scored on; their numbers are not comparable with the entries.",
                "",
            ]
        first = 2 if inputs else 1
        lines += _table_head(head, range(first, first + len(sets) + 1))
        for r in rows:
            here = "-"
            if r.entry:
                match = rescored.get((r.entry, bench, split))
                here = (
                    f"{match.entry.meta.name}: {_fmt(match.result.all_percent_error_mean)}"
                    if match is not None
                    else f"no entry {r.entry} yet"
                )
            cells = [_cell(r.method), *([r.input] if inputs else []), *[_cell(r.sets[s]) for s in sets]]
            cells += [_cell(r.all), _cell(r.training_data), _cell(r.source), _cell(here)]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def render_markdown(
    boards: Sequence[Board],
    reported: Sequence[ReportedResult],
    *,
    n_resamples: int | None = None,
    audits: Mapping[str, Mapping[str, Any]] | None = None,
    uncertainty: Sequence[UncertaintyBoard] = (),
) -> str:
    """``LEADERBOARD.md``: one ranked table per board, the uncertainty boards, then the reported table."""
    lines = [
        "<!-- Generated by `odmd-bench leaderboard build` from leaderboard/entries/; not committed: "
        "build it again rather than edit it. -->",
        "",
        "# Leaderboard",
        "",
        "Mean percent error `|Z - Z_hat| / Z * 100` per test set (lower is better); **All** is the mean of "
        "the four sets' means (the paper's \"All Sets\"). Every number is recomputed from the committed "
        "predictions by the package's evaluator, on sets whose content SHA-256 each entry records; the "
        "full statistics are in `leaderboard.json`.",
        "",
        f"**Group**: methods that cannot be told apart share a group. {rule(n_resamples)} "
        "**vs group best** is that difference of All (this row minus the group's best row) with its 95% "
        "bootstrap interval. **Calibrated**: uses the camera intrinsics.",
        "",
    ]
    for bd in boards:
        lines += _board_markdown(bd, audits)
    lines += uncertainty_markdown(uncertainty)
    if reported:
        lines += _reported_markdown(boards, reported)
    return "\n".join(lines).rstrip("\n") + "\n"
