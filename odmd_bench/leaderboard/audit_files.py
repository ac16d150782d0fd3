"""Recorded audits, ``leaderboard/audits/<seed>.json``: writing, reading, checking against the board.

``leaderboard audit --seed N --record`` writes :func:`~odmd_bench.leaderboard.audit.audit`'s
result here. ``build`` shows, for each audited entry, the fresh mean beside the committed
one (:func:`shown`), and refuses an audit file that is malformed or no longer describes
the board (:func:`audit_problems`: an entry gone, or its predictions changed since);
``check --audits`` re-runs each file (:func:`~odmd_bench.leaderboard.audit_check.rerun_audits`).
Nothing here runs a method.
"""

from __future__ import annotations

import json
import os
import re
import shlex
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from odmd_bench.leaderboard.specs import rounded
from odmd_bench.outputs import atomic_texts

if TYPE_CHECKING:
    from odmd_bench.leaderboard.board import Board
    from odmd_bench.leaderboard.entry import Entry

#: The folder of recorded audits, in the leaderboard folder.
AUDITS = "audits"
#: Largest audit file read (one of the current board is about 20 KB).
MAX_AUDIT_BYTES = 1 << 20
_NAME = re.compile(r"(0|[1-9][0-9]{0,15})\.json")
#: The fields of an audit file, and of each of its entries.
_TOP = (
    "generated_by",
    "seed",
    "benchmark",
    "split",
    "date",
    "repeats",
    "sets",
    "fresh_seeds",
    "test",
    "entries",
)
_ENTRY = (
    "method",
    "name",
    "command",
    "predictions_csv_sha256",
    "runnable",
    "reason",
    "sets",
    "generated_mean",
    "flagged",
)
_TEST = ("committed", "fresh", "fresh_interval", "difference", "p", "p_adjusted")


def audit_path(root: str | os.PathLike[str], seed: int) -> Path:
    """``ROOT/audits/<seed>.json``."""
    return Path(root) / AUDITS / f"{seed}.json"


def audit_json(result: Mapping[str, Any]) -> str:
    """The audit's JSON text, as ``--format json`` prints it and ``--record`` writes it."""
    return json.dumps(result, indent=2, ensure_ascii=False) + "\n"


def record(root: str | os.PathLike[str], result: Mapping[str, Any]) -> Path:
    """Write ``result`` to :func:`audit_path` (atomically) and return the path."""
    from odmd_bench.outputs import ensure_folder

    path = audit_path(root, int(result["seed"]))
    ensure_folder(path.parent)
    with atomic_texts([(path, audit_json(result))]):
        pass
    return path


def read_audits(root: str | os.PathLike[str]) -> tuple[list[dict[str, Any]], list[str]]:
    """Every recorded audit that is well formed, by seed, and one line per problem found.

    A file is refused when its name is not ``<seed>.json``, it is a symbolic link or not a
    regular file, larger than :data:`MAX_AUDIT_BYTES`, not JSON, or its fields are not
    those ``leaderboard audit`` writes (the seed the same as the name's).
    """
    from odmd_bench.leaderboard.files import read_capped

    folder = Path(root) / AUDITS
    if not folder.exists():
        return [], []
    where = f"{AUDITS}/"
    if folder.is_symlink() or not folder.is_dir():
        return [], [f"{where}: must be a folder (not a link) of audit files"]
    found, problems = [], []
    for path in sorted(folder.iterdir(), key=lambda p: p.name):
        name = f"{where}{path.name}"
        if path.name.startswith("."):
            continue
        if not _NAME.fullmatch(path.name):
            problems.append(
                f"{name}: an audit file is named <seed>.json (written by `leaderboard audit --record`)"
            )
            continue
        if path.is_symlink() or not path.is_file():
            problems.append(f"{name}: not a regular file (links are not followed)")
            continue
        try:
            data = read_capped(path, MAX_AUDIT_BYTES)
        except OSError as e:
            problems.append(f"{name}: cannot be read ({e.strerror or e})")
            continue
        if len(data) > MAX_AUDIT_BYTES:
            problems.append(f"{name}: larger than {MAX_AUDIT_BYTES:,} bytes")
            continue
        try:
            doc = json.loads(data.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError) as e:
            problems.append(f"{name}: not valid JSON ({str(e)[:200]})")
            continue
        wrong = shape_problems(doc, int(path.name[: -len(".json")]))
        if wrong:
            problems += [f"{name}: {w}" for w in wrong]
            continue
        found.append(doc)
    return found, problems


def _number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def shape_problems(doc: object, seed: int) -> list[str]:
    """What is wrong with the fields of an audit document (empty: nothing)."""
    if not isinstance(doc, dict):
        return ["must hold a JSON object"]
    problems = []
    missing = [k for k in _TOP if k not in doc]
    unknown = [k for k in doc if k not in _TOP]
    if missing:
        problems.append(f"missing field(s) {', '.join(missing)}")
    if unknown:
        problems.append(f"unknown field(s) {', '.join(map(str, unknown))[:200]}")
    if problems:
        return problems
    if doc["seed"] != seed or isinstance(doc["seed"], bool):
        problems.append(f"seed {doc['seed']!r} is not the file name's, {seed}")
    if doc["benchmark"] != "odmd-v1" or doc["split"] != "test":
        problems.append("an audit is of the odmd-v1 test board")
    if not isinstance(doc["date"], str) or not re.fullmatch(r"\d{4}-\d{2}-\d{2}", doc["date"]):
        problems.append("date must be YYYY-MM-DD")
    if isinstance(doc["repeats"], bool) or not isinstance(doc["repeats"], int) or doc["repeats"] < 1:
        problems.append("repeats must be a positive integer")
    if (
        not isinstance(doc["sets"], dict)
        or not doc["sets"]
        or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in doc["sets"].values())
    ):
        problems.append("sets must map each set to its size")
    if not isinstance(doc["test"], dict) or not isinstance(doc["test"].get("level"), float):
        problems.append("test must describe the test, its level included")
    if not isinstance(doc["entries"], list):
        return [*problems, "entries must be a list"]
    sets = list(doc["sets"]) if isinstance(doc["sets"], dict) else []
    seen: set[str] = set()
    for i, e in enumerate(doc["entries"]):
        label = e.get("method") if isinstance(e, dict) and isinstance(e.get("method"), str) else f"#{i + 1}"
        problems += [f"entry {label}: {p}" for p in _entry_problems(e, sets)]
        if label in seen:
            problems.append(f"entry {label}: listed twice")
        seen.add(str(label))
    return problems


def _entry_problems(e: object, sets: list[str]) -> list[str]:
    if not isinstance(e, dict):
        return ["must be an object"]
    missing = [k for k in _ENTRY if k not in e]
    unknown = [k for k in e if k not in _ENTRY]
    if "all" in e and "generated_mean" not in e:
        return [
            "field `all` is that of an older odmd-bench (now `generated_mean`, the mean over the generated "
            "sets, not the board's All): record the audit again (odmd-bench leaderboard audit --seed N --record)"
        ]
    if missing or unknown:
        return [f"fields {', '.join(_ENTRY)} expected"]
    if not all(isinstance(e[k], str) for k in ("method", "name", "command", "predictions_csv_sha256")):
        return ["method, name, command and predictions_csv_sha256 must be text"]
    if e["runnable"] is False:
        ok = (
            isinstance(e["reason"], str)
            and e["sets"] == {}
            and e["generated_mean"] is None
            and e["flagged"] is None
        )
        return [] if ok else ["an entry not re-run has a reason, and no sets, generated_mean or flag"]
    if e["runnable"] is not True or e["reason"] is not None or not isinstance(e["flagged"], bool):
        return ["runnable must be true or false; a re-run entry has no reason and a flag"]
    if not isinstance(e["sets"], dict) or sorted(e["sets"]) != sorted(sets):
        return [f"sets must be {', '.join(sets)}"]
    tests = [*e["sets"].values(), e["generated_mean"]]
    for t in tests:
        if not isinstance(t, dict) or not all(k in t for k in _TEST):
            return [f"each test has {', '.join(_TEST)}"]
        interval = t["fresh_interval"]
        if not all(_number(t[k]) for k in _TEST if k != "fresh_interval") or not (
            isinstance(interval, list) and len(interval) == 2 and all(map(_number, interval))
        ):
            return ["a test's values must be numbers"]
    return []


def command_method(command: str) -> str:
    """The NAME of an ``odmd-bench baseline NAME ...`` command, its options not read.

    Raises:
        ValueError: the command is not one, in words.

    Example:
        >>> command_method("odmd-bench baseline my-method --mode x -o p.csv")
        'my-method'
    """
    try:
        words = shlex.split(command)
    except ValueError as e:
        raise ValueError(f"its command cannot be read as words ({e})") from None
    if words[:2] != ["odmd-bench", "baseline"] or len(words) < 3 or words[2].startswith("-"):
        shown = " ".join(words[:2]) or "nothing"
        raise ValueError(f"its command is not `odmd-bench baseline NAME ...` (it starts with {shown!r})")
    return words[2]


def shipped(entry: Entry) -> str | None:
    """The method an entry runs when it is one shipped in this repository (registered by odmd-bench), else None.

    Read from the installed metadata alone: nothing is imported (plain ``check`` uses it).
    """
    from odmd_bench import methods

    if getattr(entry.meta, "plugin", None) is not None:
        return None
    try:
        name = command_method(entry.meta.command)
    except ValueError:
        return None
    return name if name in methods.own_names() else None


def audit_problems(audits: Sequence[Mapping[str, Any]], boards: Sequence[Board]) -> list[str]:
    """Where a recorded audit no longer describes the board: an entry gone, or scored otherwise.

    Each audited entry must be on the board with the predictions it was audited with
    (their SHA-256) and the same committed means; otherwise the audit is stale: record
    a new one (``leaderboard audit --seed N --record``) or remove the file. An entry of a
    method shipped in this repository must have been re-run: "not re-run" there means
    the audit was recorded where it could not run (torch missing, say). Entries of the
    board that no audit lists are not a problem: they are not audited yet.
    """
    board = next((b for b in boards if (b.benchmark, b.split) == ("odmd-v1", "test")), None)
    rows = {r.entry.method: r for r in board.rows} if board is not None else {}
    problems = []
    for doc in audits:
        name = f"{AUDITS}/{doc['seed']}.json"
        fix = f"record it again (odmd-bench leaderboard audit --seed {doc['seed']} --record) or remove it"
        for e in doc["entries"]:
            row = rows.get(e["method"])
            if row is None:
                problems.append(f"{name}: entry {e['method']} is not on the odmd-v1 test board; {fix}")
                continue
            if row.result.provenance["predictions_sha256"] != e["predictions_csv_sha256"]:
                problems.append(f"{name}: entry {e['method']}'s predictions changed since the audit; {fix}")
                continue
            method = shipped(row.entry)
            if not e["runnable"] and method is not None:
                problems.append(
                    f"{name}: entry {e['method']} runs {method}, a method shipped in this repository, but the "
                    f"audit says it was not re-run ({e['reason']}): an audit recorded where it could not run "
                    f"(torch missing, no --original, ...); {fix.replace('record it again', 'record it again where it runs')}"
                )
                continue
            for s, t in e["sets"].items():
                now = rounded(row.result.sets[s]["percent_error"]["mean"]) if s in row.result.sets else None
                if now != t["committed"]:
                    problems.append(
                        f"{name}: entry {e['method']}, {s}: committed {t['committed']}, the board has {now}"
                    )
    return problems


def shown(audits: Sequence[Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """``{method: what the board shows}``: each entry's latest audit (by date, then seed).

    Returns:
        Per audited method: ``seed``, ``file``, ``date``, ``runnable``, ``reason``, ``sets``
        (those drawn afresh), ``test`` (the committed mean over them), ``fresh`` and
        ``fresh_interval``, ``difference``, ``p``, ``p_adjusted`` (of that mean), the
        smallest adjusted p-value of the entry's tests (sets and mean), ``flagged`` (when
        that is at most ``level``) and ``level``.
    """
    out: dict[str, dict[str, Any]] = {}
    for doc in sorted(audits, key=lambda d: (d["date"], d["seed"])):
        for e in doc["entries"]:
            t = e["generated_mean"] or {}
            out[e["method"]] = {
                "seed": doc["seed"],
                "file": f"{AUDITS}/{doc['seed']}.json",
                "date": doc["date"],
                "runnable": e["runnable"],
                "reason": e["reason"],
                "sets": list(doc["sets"]),
                "test": t.get("committed"),
                "fresh": t.get("fresh"),
                "fresh_interval": t.get("fresh_interval"),
                "difference": t.get("difference"),
                "p": t.get("p"),
                "p_adjusted": t.get("p_adjusted"),
                "p_adjusted_smallest": min(
                    (x["p_adjusted"] for x in [*e["sets"].values(), t] if x), default=None
                ),
                "flagged": e["flagged"],
                "level": doc["test"]["level"],
            }
    return out


__all__ = [
    "AUDITS",
    "command_method",
    "shipped",
    "MAX_AUDIT_BYTES",
    "audit_path",
    "audit_problems",
    "read_audits",
    "record",
    "rounded",
    "shape_problems",
    "shown",
]
