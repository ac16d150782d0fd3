"""The uncertainty boards: entries with error bars, ranked by interval score.

A separate board per board of :data:`~odmd_bench.leaderboard.specs.BOARDS`, rather than
columns on it, because the two rank different things: the main board ranks the point
estimate (percent error) of every entry; this one ranks the error bars (the interval
score, Gneiting and Raftery 2007, in percent of depth) of the entries that give them,
and an entry's point depths may well rank differently from its intervals. Entries
without error bars are listed under it as such, never ranked there.

Its entries live apart, in ``leaderboard/uncertainty/<method>/<benchmark>-<split>/``,
with the same files and metadata as any entry (read by the same validator,
:func:`~odmd_bench.leaderboard.files.read_entry`, under the same safety rules) and
predictions that carry ``depth_lo``, ``depth_hi`` and ``level`` (and, for CRPS,
``depth_std``; docs/format.md, "Uncertainty"). Kept apart, they leave the main board and
its entries' predictions as they are: an uncertainty entry whose depths are a main
entry's (the same method, with its error bars) would be refused there as a copy. Here
it is shown beside that entry's name ("point depths of").

Rows are sorted by All of the interval score (the mean of the sets' means) and grouped
by the main board's rule (:func:`~odmd_bench.leaderboard.ranking.rank_groups`), on the
per-example interval scores. A row shows, per set and All, the coverage at the stated
level, the interval score and, where the entry gives ``depth_std``, the CRPS.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.errors import ValidationError
from odmd_bench.evaluation.result import EvaluationResult
from odmd_bench.leaderboard.board import Board, score_entry
from odmd_bench.leaderboard.entry import Entry
from odmd_bench.leaderboard.files import read_entry
from odmd_bench.leaderboard.ranking import Ranked, rank_groups
from odmd_bench.leaderboard.specs import SET_TITLES
from odmd_bench.leaderboard.specs import rounded as _r

#: The folder of the uncertainty entries in the leaderboard folder.
UNCERTAINTY = "uncertainty"


@dataclass(frozen=True)
class UncertaintyRow:
    """A ranked uncertainty entry: its result, its place, and the main entry whose depths it has."""

    entry: Entry
    result: EvaluationResult
    ranked: Ranked
    point_of: str | None


@dataclass(frozen=True)
class UncertaintyBoard:
    """The uncertainty rows of one board, and the board's entries without error bars."""

    board: Board
    rows: tuple[UncertaintyRow, ...]
    without: tuple[str, ...]


def discover(root: str | os.PathLike[str]) -> list[Path]:
    """Uncertainty entry folders ``root/uncertainty/<method>/<benchmark>-<split>/``, sorted (none: [])."""
    base = Path(root) / UNCERTAINTY
    if not base.is_dir():
        return []
    found: list[Path] = []
    for method in base.iterdir():
        if method.is_symlink():
            found.append(method)
        elif method.is_dir():
            found += [p for p in method.iterdir() if p.is_symlink() or p.is_dir()]
    return sorted(found)


def collect(
    root: str | os.PathLike[str], boards: Sequence[Board], *, n_resamples: int | None = None
) -> tuple[list[UncertaintyBoard], list[str]]:
    """Read, score and rank the uncertainty entries against the boards' data.

    Returns:
        ``(uncertainty boards, problems)``: one per board that has rows (its data is the
        board's, already loaded and verified), and one line per problem (an entry that
        fails validation, a board without entries, predictions without an interval).
    """
    root = Path(root)
    problems: list[str] = []
    entries: list[Entry] = []
    for folder in discover(root):
        try:
            entries.append(read_entry(folder, root.parent))
        except ValidationError as err:
            problems += [f"{UNCERTAINTY} {err.message}", *(f"  {p}" for p in err.problems)]
    out: list[UncertaintyBoard] = []
    for bd in boards:
        mine = [e for e in entries if (e.benchmark, e.split) == (bd.benchmark, bd.split)]
        if not mine:
            continue  # a board without uncertainty entries is not shown
        if not bd.rows:
            problems += [f"{UNCERTAINTY}/{e.key}: the board {bd.spec.key} has no entries" for e in mine]
            continue
        examples = bd.rows[0].result.examples
        scored: dict[str, tuple[Entry, EvaluationResult]] = {}
        for e in mine:
            try:
                result = score_entry(e, examples)
            except ValidationError as err:
                problems += [f"{UNCERTAINTY} {err.message}", *(f"  {p}" for p in err.problems)]
                continue
            if "coverage" not in next(iter(result.sets.values())):
                problems.append(
                    f"{UNCERTAINTY}/{e.key}: the predictions have no interval (columns depth_lo, depth_hi, level)"
                )
                continue
            scored[e.method] = (e, result)
        ranked = rank_groups(
            {m: r.errors("interval_score") for m, (_, r) in scored.items()}, n_resamples=n_resamples
        )
        rows = []
        matched: set[str] = set()
        for x in ranked:
            e, r = scored[x.key]
            twin = next((row for row in bd.rows if _same_depths(row.result, r, bd.sets)), None)
            if twin is not None:
                matched.add(twin.entry.method)
            rows.append(UncertaintyRow(e, r, x, None if twin is None else twin.entry.meta.name))
        without = tuple(row.entry.meta.name for row in bd.rows if row.entry.method not in matched)
        out.append(UncertaintyBoard(bd, tuple(rows), without))
    return out, problems


#: Depths the same as a main entry's to this relative tolerance are "its point depths": a
#: float32 network run on another processor changes the last bits (about 1e-7).
_SAME_RTOL = 1e-5


def _same_depths(a: EvaluationResult, b: EvaluationResult, sets: tuple[str, ...]) -> bool:
    return all(np.allclose(a.predictions[s], b.predictions[s], rtol=_SAME_RTOL, atol=0.0) for s in sets)


def _pct(x: float) -> str:
    return f"{100 * x:.1f}"


def render_markdown(boards: Sequence[UncertaintyBoard]) -> list[str]:
    """The LEADERBOARD.md section: one table per board with uncertainty entries."""
    if not boards:
        return []
    lines = [
        "## Uncertainty",
        "",
        "Entries that give error bars (docs/uncertainty.md), ranked by the **interval score** (Gneiting and "
        "Raftery 2007) in percent of the true depth, lower is better: the interval's width plus 2 / (1 - level) "
        "times every miss. **Coverage**: the share of test examples inside the stated interval (an honest 90% "
        "interval covers about 90%). **CRPS** of the stated normal, in percent of depth. Groups as above, on "
        "per-example interval scores. Entries without error bars are listed below each table, not ranked; "
        "a board none of whose entries gives error bars is not shown.",
        "",
    ]
    for ub in boards:
        bd = ub.board
        titles = [SET_TITLES.get(s, s) for s in bd.sets]
        head = [
            "Group",
            "Method",
            "Level",
            *[f"{t} cov. / IS" for t in titles],
            "All cov.",
            "All IS",
            "All CRPS",
            "Point depths of",
        ]
        lines += [f"### {bd.spec.key}", ""]
        lines.append("| " + " | ".join(head) + " |")
        lines.append("| --- | --- | " + " | ".join("---:" for _ in head[2:-1]) + " | --- |")
        for row in ub.rows:
            r, a = row.result, row.result.all_uncertainty
            level = r.sets[bd.sets[0]]["coverage"]["level"]
            cells = [str(row.ranked.group), row.entry.meta.name, f"{level:g}"]
            cells += [
                f"{_pct(r.sets[s]['coverage']['observed'])} / {r.sets[s]['interval_score']['mean']:.2f}"
                for s in bd.sets
            ]
            cells += [_pct(a["coverage"]), f"**{a['interval_score_mean']:.2f}**"]
            cells += [f"{a['crps_mean']:.2f}" if "crps_mean" in a else "-", row.point_of or "-"]
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        lines += ["", "Without error bars (not ranked here): " + (", ".join(ub.without) or "none") + ".", ""]
    return lines


def to_json(boards: Sequence[UncertaintyBoard]) -> list[dict[str, Any]]:
    """The ``uncertainty`` list of leaderboard.json: per board, the ranked rows and the entries without."""
    out = []
    for ub in boards:
        rows = []
        for pos, row in enumerate(ub.rows, 1):
            r = row.result
            rows.append(
                {
                    "position": pos,
                    "group": row.ranked.group,
                    "group_leader": row.ranked.leader,
                    "method": row.entry.method,
                    "name": row.entry.meta.name,
                    "point_depths_of": row.point_of,
                    "all": {k: _r(v) for k, v in r.all_uncertainty.items()},
                    "sets": {
                        s: {
                            k: {kk: _r(vv) for kk, vv in m[k].items()}
                            for k in ("coverage", "sharpness", "interval_score", "crps")
                            if k in m
                        }
                        for s, m in r.sets.items()
                    },
                    "entry": f"{UNCERTAINTY}/{row.entry.key}",
                    "predictions_csv_sha256": r.provenance["predictions_sha256"],
                    "metadata": row.entry.meta.to_dict(),
                }
            )
        out.append(
            {
                "benchmark": ub.board.benchmark,
                "split": ub.board.split,
                "rows": rows,
                "without_uncertainty": list(ub.without),
            }
        )
    return out
