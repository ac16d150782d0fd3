"""What the site shows: the board built from the entries (``leaderboard.json``), each entry re-scored beside it.

The board is built from the committed entries as ``leaderboard build`` builds it (the
views are not committed), and every number printed comes from its ``leaderboard.json``.
An entry whose recorded SHA-256 or scores differ from its re-scoring (what ``leaderboard
check`` fails on) stops the site. The method pages use the entries' re-scored results
(the per-example errors: the figures, the paired comparisons); a statistic that differs
from the JSON, or an entry missing from it, stops the site: it never shows numbers the
board does not hold.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from odmd_bench.errors import ValidationError
from odmd_bench.evaluation.compare import PairedDifference, compare_pairs
from odmd_bench.evaluation.scoring import EvaluationResult
from odmd_bench.leaderboard.entry import Entry
from odmd_bench.leaderboard.files import ENTRIES, JSON_FILE, discover, read_entry
from odmd_bench.leaderboard.ranking import RANK_CONFIDENCE, RANK_SEED, resamples
from odmd_bench.leaderboard.render import JSON_DECIMALS
from odmd_bench.leaderboard.rules import SELECTED_ON, TRAINING_KINDS
from odmd_bench.leaderboard.specs import BoardSpec, board_spec

#: The method every row is also compared with, where its board has it.
REFERENCE_METHOD = "box-ls"
#: The facets a view can be filtered by, and their values, in the order the controls list them.
FACETS: dict[str, tuple[str, ...]] = {
    "calibrated": ("yes", "no"),
    "input": ("boxes", "masks"),
    "training": TRAINING_KINDS,
    "selected_on": tuple(v for v in SELECTED_ON if v != "test"),  # test is refused (rules)
    "selection": ("overall", "per-set"),
}


def facets(meta: Mapping[str, Any]) -> dict[str, str]:
    """An entry's facet values, from what its metadata declares.

    - ``calibrated``: ``yes`` or ``no``;
    - ``input``: ``boxes`` (every board scores box tracks; ``masks`` is kept for boards to come);
    - ``training``: the declared ``training_kind`` (none, generator, real, other);
    - ``selected_on``: the declared ``selected_on`` (val or nothing);
    - ``selection``: ``per-set`` when the entry's ``options`` select a checkpoint per set
      (``selection: per-set``), else ``overall``.

    Examples:
        >>> facets({"calibrated": True, "training_kind": "none", "selected_on": "val",
        ...         "options": {"selection": "per-set"}})
        {'calibrated': 'yes', 'input': 'boxes', 'training': 'none', 'selected_on': 'val', 'selection': 'per-set'}
    """
    options = meta.get("options") or {}
    return {
        "calibrated": "yes" if meta.get("calibrated") is True else "no",
        "input": "boxes",
        "training": str(meta.get("training_kind", "")),
        "selected_on": str(meta.get("selected_on", "")),
        "selection": "per-set" if options.get("selection") == "per-set" else "overall",
    }


@dataclass(frozen=True)
class Versus:
    """A paired comparison of this row (B) with another method (A) on All, as ``compare`` gives it.

    ``src`` is its path in ``leaderboard.json`` when the JSON holds it (the group leader's).
    """

    method: str
    name: str
    role: str
    difference: float
    ci_low: float
    ci_high: float
    p_value: float
    verdict: str
    src: str = ""


@dataclass
class SiteRow:
    """A row of a board: its ``leaderboard.json`` object, its entry and its re-scored result."""

    spec: BoardSpec
    data: dict[str, Any]
    entry: Entry
    result: EvaluationResult
    versus: list[Versus] = field(default_factory=list)

    @property
    def method(self) -> str:
        """The method id."""
        return str(self.data["method"])

    @property
    def board(self) -> str:
        """The board id, ``BENCHMARK-SPLIT``."""
        return self.spec.folder

    @property
    def src(self) -> str:
        """The path prefix of this row's numbers in ``leaderboard.json``: ``BOARD-ID/METHOD``."""
        return f"{self.board}/{self.method}"

    @property
    def facets(self) -> dict[str, str]:
        """The row's facet values."""
        return facets(self.data["metadata"])


@dataclass
class SiteBoard:
    """A board: its spec, its ``leaderboard.json`` object and its rows in board order."""

    spec: BoardSpec
    data: dict[str, Any]
    rows: list[SiteRow]

    @property
    def id(self) -> str:
        """``BENCHMARK-SPLIT``."""
        return self.spec.folder


@dataclass
class SiteData:
    """Everything the pages show."""

    json_text: str
    data: dict[str, Any]
    boards: list[SiteBoard]
    n_resamples: int


def _mismatches(row: dict[str, Any], result: EvaluationResult) -> list[str]:
    """Where the re-scored result differs from the row of leaderboard.json (rounded as it is)."""

    def same(a: object, b: float) -> bool:
        return isinstance(a, (int, float)) and a == round(float(b), JSON_DECIMALS)

    out = []
    if not same(row.get("all"), result.all_percent_error_mean):
        out.append("all")
    if list(row.get("sets", {})) != list(result.sets):
        return [*out, "sets"]
    for s, stats in row["sets"].items():
        if stats.get("n") != int(result.sets[s]["n"]):
            out.append(f"sets.{s}.n")
        for kind in ("percent_error", "absolute_error"):
            for k, v in stats.get(kind, {}).items():
                if not same(v, result.sets[s][kind][k]):
                    out.append(f"sets.{s}.{kind}.{k}")
    return out


def _entries(root: Path) -> tuple[dict[str, Entry], list[str]]:
    entries: dict[str, Entry] = {}
    problems: list[str] = []
    for folder in discover(root):
        try:
            e = read_entry(folder, root.parent)
        except ValidationError as err:
            problems += [f"{err.message}: {p}" for p in err.problems] or [err.message]
            continue
        entries[f"{ENTRIES}/{e.key}"] = e
    return entries, problems


def _versus(board: SiteBoard, n_resamples: int) -> None:
    """Each row against the board's best row and against :data:`REFERENCE_METHOD`.

    A comparison ``leaderboard.json`` holds (a row against its group leader) is read from
    it; the others are computed as ``compare`` computes them, with the rank groups'
    settings.
    """
    rows = board.rows
    by_method = {r.method: r for r in rows}
    wanted: list[tuple[SiteRow, SiteRow, str]] = []
    for r in rows:
        seen = {r.method}
        for other, role in (
            (rows[0], "the board's best"),
            (by_method.get(REFERENCE_METHOD), "the reference"),
        ):
            if other is not None and other.method not in seen:
                seen.add(other.method)
                wanted.append((other, r, role))
    from_json = {}
    for r in rows:
        vs = r.data.get("versus_group_leader")
        if vs is not None:
            from_json[(vs["a"], vs["b"])] = vs
    todo = [(o.method, r.method) for o, r, _ in wanted if (o.method, r.method) not in from_json]
    errors = {r.method: r.result.percent_errors() for r in rows}
    done = compare_pairs(errors, todo, n_resamples=n_resamples, seed=RANK_SEED, confidence=RANK_CONFIDENCE)
    for other, r, role in wanted:
        name = str(other.data["name"])
        key = (other.method, r.method)
        if key in from_json:
            j = from_json[key]
            r.versus.append(
                Versus(
                    other.method,
                    name,
                    role,
                    j["difference_a_minus_b"],
                    j["ci_low"],
                    j["ci_high"],
                    j["p_value"],
                    j["verdict"],
                    src=f"{r.src}/versus_group_leader",
                )
            )
        else:
            d: PairedDifference = done[key].all
            r.versus.append(
                Versus(other.method, name, role, d.difference, d.ci_low, d.ci_high, d.p_value, d.verdict)
            )


def load_site_data(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    n_resamples: int | None = None,
) -> SiteData:
    """Build the board from the entries under ``root`` and re-score every entry it lists.

    Raises:
        ValidationError: Naming every entry that cannot be read or scored, whose recorded
            SHA-256 or scores differ from its re-scoring (``leaderboard check``'s
            differences), or that is missing from the built JSON or differs from it.
    """
    from odmd_bench.leaderboard.diff import entry_differences
    from odmd_bench.leaderboard.render import build

    root = Path(root)
    built = build(root, data_dir, original, n_resamples=n_resamples)
    differ = entry_differences(list(built.boards))
    if differ:
        raise ValidationError(
            "the site cannot be built: entries differ from their re-scoring (leaderboard check fails)", differ
        )
    json_text = built.json_text
    data = json.loads(json_text)
    listed = [(b, r) for b in data["boards"] for r in b["rows"]]
    scored = {f"{ENTRIES}/{row.entry.key}": row.result for bd in built.boards for row in bd.rows}
    entries, problems = _entries(root)
    named = {r.get("entry") for _, r in listed}
    problems += [
        f"{key}: is not in {JSON_FILE}; run `odmd-bench leaderboard build`"
        for key in entries
        if key not in named
    ]
    boards = []
    for jb in data["boards"]:
        spec = board_spec(jb["benchmark"], jb["split"])
        board = SiteBoard(spec, jb, [])
        boards.append(board)
        for jr in jb["rows"]:
            entry, result = entries.get(jr.get("entry")), scored.get(jr.get("entry"))
            if entry is None or result is None:
                problems.append(
                    f"{JSON_FILE}: {spec.key} row {jr.get('method')!r}: its entry {jr.get('entry')} is missing"
                )
                continue
            wrong = _mismatches(jr, result)
            if wrong:
                problems.append(
                    f"{entry.key}: re-scored, it differs from {JSON_FILE} in {', '.join(wrong[:5])}"
                    f"{' ...' if len(wrong) > 5 else ''}; run `odmd-bench leaderboard build`"
                )
                continue
            board.rows.append(SiteRow(spec, jr, entry, result))
    if problems:
        raise ValidationError("the site cannot be built: the board and its entries disagree", problems)
    n = resamples(n_resamples)
    for board in boards:
        if board.rows:
            _versus(board, n)
    return SiteData(json_text=json_text, data=data, boards=boards, n_resamples=n)
