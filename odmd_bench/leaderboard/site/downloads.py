"""The site's downloads: ``leaderboard.json``, a CSV per board, and the files given beside them.

The files (:func:`download_files`) and the lines of the index's Downloads list
(:func:`downloads_list`); the pages are :mod:`~odmd_bench.leaderboard.site.pages`'.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping

from odmd_bench.leaderboard.files import JSON_FILE
from odmd_bench.leaderboard.site.data import FACETS, SiteBoard, SiteData


def board_csv(board: SiteBoard) -> bytes:
    """One board as CSV, a line per entry; the numbers as leaderboard.json writes them."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    sets = list(board.spec.sets)
    w.writerow(
        [
            "position",
            "group",
            "method",
            "name",
            *sets,
            "all",
            *FACETS,
            "parameters",
            "examples_per_second",
            "date",
        ]
    )
    for r in board.rows:
        meta = r.data["metadata"]
        speed = meta.get("speed")
        w.writerow(
            [
                r.data["position"],
                r.data["group"],
                r.method,
                r.data["name"],
                *(json.dumps(r.data["sets"][s]["percent_error"]["mean"]) for s in sets),
                json.dumps(r.data["all"]),
                *(r.facets[f] for f in FACETS),
                meta.get("parameters", ""),
                "" if speed is None else json.dumps(speed["examples_per_second"]),
                meta["date"],
            ]
        )
    return buf.getvalue().encode("utf-8")


def download_files(site: SiteData, extra: Mapping[str, tuple[bytes, str]] | None = None) -> dict[str, bytes]:
    """``{downloads/NAME: bytes}``: leaderboard.json, a CSV per board with entries, and ``extra``'s files.

    Args:
        site: the board.
        extra: further files, ``{file name: (bytes, what it is)}`` (the Croissant descriptions).
    """
    files = {f"downloads/{JSON_FILE}": site.json_text.encode("utf-8")}
    files.update({f"downloads/{b.id}.csv": board_csv(b) for b in site.boards if b.rows})
    files.update({f"downloads/{name}": data for name, (data, _) in (extra or {}).items()})
    return files


def downloads_list(
    site: SiteData, extra: Mapping[str, tuple[bytes, str]] | None = None
) -> list[tuple[str, str, str]]:
    """The Downloads list of the index: ``(link, its text, what follows it)`` per line.

    The files of :func:`download_files`, then the pages of results not ranked here.
    """
    lines = [(f"downloads/{JSON_FILE}", JSON_FILE, ": every board, every statistic, with provenance")]
    lines += [
        (f"downloads/{b.id}.csv", f"{b.id}.csv", f": the {b.spec.key} table") for b in site.boards if b.rows
    ]
    lines += [(f"downloads/{name}", name, f": {what}") for name, (_, what) in (extra or {}).items()]
    lines.append(("reported.html", "Results reported in papers", " (not re-scored)"))
    if site.data.get("uncertainty"):
        lines.append(("uncertainty.html", "Uncertainty", ": error bars ranked by interval score"))
    return lines
