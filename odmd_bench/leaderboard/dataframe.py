"""The leaderboard as a pandas DataFrame (pandas is imported only when asked for)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING

from odmd_bench.errors import UsageError
from odmd_bench.leaderboard.files import JSON_FILE, build_folder, find_root
from odmd_bench.leaderboard.specs import SET_TITLES

if TYPE_CHECKING:
    import pandas as pd

    from odmd_bench.leaderboard.render import Built

#: The columns before the sets' and after them (the sets' columns hold mean percent errors).
LEADING = ("benchmark", "split", "position", "group", "method", "name", "reported", "input")
TRAILING = ("all", "calibrated", "training_data", "date", "source")


def _records(data: dict[str, object], reported: bool) -> list[dict[str, object]]:
    out: list[dict[str, object]] = []
    boards = data.get("boards")
    for bd in boards if isinstance(boards, list) else []:
        for row in bd["rows"]:
            meta = row["metadata"]
            out.append(
                {
                    "benchmark": bd["benchmark"],
                    "split": bd["split"],
                    "position": row["position"],
                    "group": row["group"],
                    "method": row["method"],
                    "name": row["name"],
                    "reported": False,
                    "input": "detection",
                    **{s: m["percent_error"]["mean"] for s, m in row["sets"].items()},
                    "all": row["all"],
                    "calibrated": meta["calibrated"],
                    "training_data": meta["training_data"],
                    "date": meta["date"],
                    "source": row["entry"],
                }
            )
    results = data.get("reported")
    for r in results if reported and isinstance(results, list) else []:
        out.append(
            {
                "benchmark": r["benchmark"],
                "split": r["split"],
                "method": r.get("entry") or r["method"],
                "name": r["method"],
                "reported": True,
                "input": r.get("input", "detection"),
                **{s: float(v) for s, v in r["sets"].items()},
                "all": float(r["all"]),
                "training_data": r["training_data"],
                "source": r["source"],
            }
        )
    return out


def frame(source: str | os.PathLike[str] | Built | None = None, *, reported: bool = False) -> pd.DataFrame:
    """The leaderboard as a DataFrame: one row per entry and board, best first.

    Columns: ``benchmark``, ``split``, ``position``, ``group``, ``method``, ``name``,
    ``reported``, ``input``, one column per set (mean percent error; NaN on a board
    without that set), ``all``, ``calibrated``, ``training_data``, ``date`` and
    ``source`` (the entry's folder, or the publication of a reported result).

    Args:
        source: a folder holding a ``leaderboard.json`` written by ``odmd-bench leaderboard
            build`` (``-o DIR``), or a leaderboard folder, whose ``build/leaderboard.json``
            is read (default: the ``leaderboard/`` folder found from the current folder),
            or the result of :func:`~odmd_bench.leaderboard.build`.
        reported: also the results reported in papers (``reported`` true, no position
            or group; ``method`` is the id of the entry that reproduces it, if any).

    Raises:
        UsageError: When there is no readable ``leaderboard.json`` there (the views are
            not committed: ``odmd-bench leaderboard build`` writes it).
        ModuleNotFoundError: When pandas is not installed.

    Example:
        >>> import pathlib, tempfile
        >>> from odmd_bench.leaderboard.render import render_json
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (folder / "leaderboard.json").write_text(render_json([], []), encoding="utf-8")
        >>> frame(folder).columns[:4].tolist()  # a board without entries: no rows
        ['benchmark', 'split', 'position', 'group']
    """
    import pandas as pd

    from odmd_bench.leaderboard.render import Built

    if isinstance(source, Built):
        text = source.json_text
    else:
        here = "give the folder: frame('path/to/odmd-bench/leaderboard')"
        folder = Path(source if source is not None else find_root(otherwise=here))
        path = folder / JSON_FILE
        if not path.is_file() and (build_folder(folder) / JSON_FILE).is_file():
            path = build_folder(folder) / JSON_FILE
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as e:
            raise UsageError(
                f"{path} cannot be read ({e.strerror or e}); run `odmd-bench leaderboard build`"
            ) from None
    try:
        data = json.loads(text)
    except ValueError as e:
        raise UsageError(f"{JSON_FILE} is not valid JSON ({e}); run `odmd-bench leaderboard build`") from None
    records = _records(data if isinstance(data, dict) else {}, reported)
    sets = [s for s in SET_TITLES if any(s in r for r in records)]
    sets += sorted({k for r in records for k in r} - {*LEADING, *TRAILING, *sets})
    df = pd.DataFrame.from_records(records, columns=[*LEADING, *sets, *TRAILING])
    for col in ("position", "group"):
        df[col] = df[col].astype("Int64")
    return df
