"""``leaderboard check``: what differs between what the entries record and a fresh re-scoring.

Each entry records the SHA-256 of its predictions and its scores (written by ``add``);
``check`` re-scores every entry and names each recorded value that differs (entry, field,
recorded and recomputed value). The views (``LEADERBOARD.md``, ``leaderboard.json``) are
derived and not committed, so nothing else can differ. :func:`diff_json` and
:func:`diff_markdown` name differences between two texts precisely (JSON by field path,
markdown tables by table, row and column), for the audits' records and for anyone
comparing two builds.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from odmd_bench.errors import ValidationError
from odmd_bench.leaderboard.board import Board, Row
from odmd_bench.leaderboard.files import ENTRIES, JSON_FILE, MARKDOWN
from odmd_bench.leaderboard.render import build
from odmd_bench.leaderboard.specs import rounded

#: Longest value a difference line shows.
SHOWN_VALUE = 500


def _v(value: object) -> str:
    text = repr(value)
    return text if len(text) <= SHOWN_VALUE else text[: SHOWN_VALUE - 3] + "..."


def _json_label(node: object, i: int) -> str:
    if isinstance(node, dict):
        if "method" in node and isinstance(node["method"], str):
            return node["method"]
        if "benchmark" in node and "split" in node:
            return f"{node['benchmark']} {node['split']}"
    return str(i)


def _flatten(node: object, prefix: str = "") -> dict[str, object]:
    """``{path: leaf}``; list items are named by their method or benchmark when they have one."""
    out: dict[str, object] = {}
    if isinstance(node, dict):
        for k, v in node.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(node, list) and node and all(isinstance(x, dict) for x in node):
        for i, v in enumerate(node):
            out.update(_flatten(v, f"{prefix}[{_json_label(v, i)}]"))
    else:
        out[prefix] = node
    return out


def diff_json(committed: str, built: str, name: str = JSON_FILE, limit: int = 20) -> list[str]:
    """One line per field that differs: ``name: path: committed X, build writes Y``."""
    try:
        a = _flatten(json.loads(committed))
    except (ValueError, RecursionError) as e:
        why = "nested too deeply" if isinstance(e, RecursionError) else str(e)[:SHOWN_VALUE]
        return [f"{name}: not valid JSON ({why}); run `odmd-bench leaderboard build`"]
    b = _flatten(json.loads(built))
    out = []
    for k in [*a, *(k for k in b if k not in a)]:
        if k not in b:
            out.append(f"{name}: {k}: committed {_v(a[k])}, build does not write it")
        elif k not in a:
            out.append(f"{name}: {k}: missing, build writes {_v(b[k])}")
        elif a[k] != b[k] or type(a[k]) is not type(b[k]):
            out.append(f"{name}: {k}: committed {_v(a[k])}, build writes {_v(b[k])}")
    if len(out) > limit:
        out = [*out[:limit], f"{name}: ... and {len(out) - limit} more differences"]
    return out


def _table_context(lines: list[str], i: int) -> tuple[str, list[str]] | None:
    """(section title, header cells) of the table that line ``i`` is in, if any."""
    if not lines[i].startswith("|"):
        return None
    j = i
    while j > 0 and lines[j - 1].startswith("|"):
        j -= 1
    header = _cells(lines[j])
    title = ""
    for k in range(j - 1, -1, -1):
        if lines[k].startswith("#"):
            title = lines[k].lstrip("#").strip()
            break
    return title, header


def _cells(line: str) -> list[str]:
    return [c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]


def _row_key(lines: list[str], i: int) -> tuple[str, str, list[str]] | None:
    """(table title, row name, header) of a table's data row, or None for other lines."""
    ctx = _table_context(lines, i)
    if ctx is None:
        return None
    title, header = ctx
    cells = _cells(lines[i])
    if len(cells) != len(header) or cells == header or all(set(c) <= set("-: ") for c in cells):
        return None
    name = cells[1] if header[0] == "Group" and len(cells) > 1 else cells[0]
    return title, re.sub(r"^\[(.*)\]\(.*\)$", r"\1", name), header


def diff_markdown(committed: str, built: str, name: str = MARKDOWN, limit: int = 20) -> list[str]:
    """One line per difference between the committed and the built Markdown.

    Table rows are matched by table and row name (the method), so a changed cell is named
    by table, row and column even when rows moved.
    """
    import difflib

    old, new = committed.splitlines(), built.splitlines()
    out = []
    sm = difflib.SequenceMatcher(a=old, b=new, autojunk=False)
    for tag, i1, i2, j1, j2 in sm.get_opcodes():
        if tag == "equal":
            continue
        old_rows = {k[:2]: (i, k[2]) for i in range(i1, i2) if (k := _row_key(old, i))}
        new_rows = {k[:2]: (j, k[2]) for j in range(j1, j2) if (k := _row_key(new, j))}
        matched = {k for k in old_rows if k in new_rows and old_rows[k][1] == new_rows[k][1]}
        for (title, row), (i, header) in old_rows.items():
            if (title, row) not in matched:
                continue
            j = new_rows[(title, row)][0]
            for col, x, y in zip(header, _cells(old[i]), _cells(new[j]), strict=True):
                if x != y:
                    out.append(
                        f"{name} line {i + 1}: table '{title}', row '{row}', column '{col}': "
                        f"committed {_v(x)}, build writes {_v(y)}"
                    )
        rest_old = [i for i in range(i1, i2) if (k := _row_key(old, i)) is None or k[:2] not in matched]
        rest_new = [j for j in range(j1, j2) if (k := _row_key(new, j)) is None or k[:2] not in matched]
        if len(rest_old) == len(rest_new):  # lines changed in place
            for i, j in zip(rest_old, rest_new, strict=True):
                out.append(f"{name} line {i + 1}: committed {_v(old[i])}, build writes {_v(new[j])}")
            continue
        for i in rest_old:
            out.append(f"{name} line {i + 1}: committed {_v(old[i])}, build does not write it")
        for j in rest_new:
            out.append(f"{name} line {i1 + 1}: missing, build writes {_v(new[j])}")
    if len(out) > limit:
        out = [*out[:limit], f"{name}: ... and {len(out) - limit} more differences"]
    return out


def recorded_scores(row: Row) -> dict[str, float]:
    """The ``scores`` ``add`` records for a scored entry: each set's mean percent error and ``all``.

    Rounded as ``leaderboard.json`` keeps floats (:data:`~odmd_bench.leaderboard.specs.JSON_DECIMALS`).
    """
    res = row.result
    out = {s: rounded(res.sets[s]["percent_error"]["mean"]) for s in res.sets}
    out["all"] = rounded(res.all_percent_error_mean)
    return out


def entry_differences(boards: list[Board]) -> list[str]:
    """Where an entry's recorded ``predictions_sha256`` or ``scores`` differ from its re-scoring.

    One line per field: ``entries/M/B/entry.yaml: scores.camera: recorded X, re-scored Y``.
    """
    out = []
    for bd in boards:
        for row in bd.rows:
            meta = row.entry.meta
            where = f"{ENTRIES}/{row.entry.key}/" + next(
                (n for n in ("entry.yaml", "entry.json") if (row.entry.folder / n).is_file()), "entry.yaml"
            )
            sha = str(row.result.provenance["predictions_sha256"])
            if meta.predictions_sha256 != sha:
                out.append(
                    f"{where}: predictions_sha256: recorded {meta.predictions_sha256[:16]}..., the "
                    f"predictions file {meta.predictions} has {sha[:16]}... (a changed prediction)"
                )
            fresh = recorded_scores(row)
            for k in [*fresh, *(k for k in meta.scores if k not in fresh)]:
                if k not in meta.scores:
                    out.append(f"{where}: scores.{k}: missing, re-scored {fresh[k]!r}")
                elif k not in fresh:
                    out.append(f"{where}: scores.{k}: recorded {meta.scores[k]!r}, not a set of the board")
                elif rounded(meta.scores[k]) != fresh[k]:
                    out.append(f"{where}: scores.{k}: recorded {meta.scores[k]!r}, re-scored {fresh[k]!r}")
    return out


@dataclass(frozen=True)
class CheckReport:
    """What :func:`check_report` found; both empty when the leaderboard is right.

    Attributes:
        invalid: problems of the input: an entry (metadata, data hashes, predictions) or
            ``reported.yaml`` that is invalid, so that nothing can be built (the command
            exits 2).
        differences: the committed files that differ from what ``build`` writes now
            (the gate failed: the command exits 1).
    """

    invalid: list[str] = field(default_factory=list)
    differences: list[str] = field(default_factory=list)


def check(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    n_resamples: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[str]:
    """Everything that is wrong with the leaderboard folder, one line each (empty: all good).

    The lines of :func:`check_report`, the invalid input first.
    """
    report = check_report(root, data_dir, original, n_resamples=n_resamples, progress=progress)
    return report.invalid + report.differences


def check_report(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    n_resamples: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> CheckReport:
    """What is wrong with the leaderboard folder: invalid input apart from differences.

    Every entry is read, validated and re-scored, and the board is built as ``build``
    builds it (rank groups, the recorded audits, ``reported.yaml``); problems there are
    invalid input. Then each entry's recorded ``predictions_sha256`` and ``scores`` are
    compared with the re-scoring (:func:`entry_differences`): a changed prediction or a
    changed number is a difference.

    Args:
        root: the leaderboard folder.
        data_dir: the data folder (default: the package's).
        original: the original release's folder, imported from when a set is missing.
        n_resamples: resamples of the rank groups' comparison (default: the board's).
        progress: called with one line per board once it is scored.
    """
    try:
        built = build(Path(root), data_dir, original, n_resamples=n_resamples, progress=progress)
    except ValidationError as e:
        return CheckReport(invalid=e.problems or [e.message])
    return CheckReport(differences=entry_differences(list(built.boards)))
