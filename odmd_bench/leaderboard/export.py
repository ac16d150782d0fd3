"""The board as files other leaderboards read (``odmd-bench leaderboard export``).

Two formats, both made from a :class:`~odmd_bench.leaderboard.render.Built` in memory (never
from the generated ``leaderboard.json``):

- ``hf-eval-results``: Hugging Face's evaluation results, the YAML list a model repository
  keeps in ``.eval_results/*.yaml`` (https://huggingface.co/docs/hub/eval-results): one item
  per board and per set, ``dataset: {id, task_id}``, ``value``, ``date``, ``source`` and
  ``notes``. One folder per method, ``METHOD/.eval_results/odmd-bench.yaml``, to copy into
  that method's model repository; results printed in papers under ``reported/``.
- ``json``: ``results.json``, one record per entry and board, and one per result printed in
  a paper, each with its provenance: ``rescored`` (this package re-scored the committed
  predictions: their SHA-256, the sets' content hashes, the command that made them) or
  ``reported`` (the values as printed, never re-scored or ranked).

The numbers are those of ``leaderboard.json`` (:func:`~odmd_bench.leaderboard.specs.rounded`),
mean percent errors (lower is better). The YAML is written by PyYAML, the JSON by ``json``.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from odmd_bench._version import __version__
from odmd_bench.errors import UsageError
from odmd_bench.leaderboard.files import ENTRIES
from odmd_bench.leaderboard.render import Built
from odmd_bench.leaderboard.specs import rounded
from odmd_bench.outputs import atomic_paths, ensure_folder
from odmd_bench.project import repository_url

#: The formats ``export`` writes.
FORMATS: tuple[str, ...] = ("hf-eval-results", "json")

#: The Hub dataset the results name (``dataset.id``): the benchmark as it would be registered
#: there. Results show on a Hub leaderboard only once such a benchmark dataset exists; another
#: id is given with ``--hf-dataset``.
HF_DATASET = "odmd-bench/odmd"

#: The file each method's folder holds (``.eval_results/`` of its model repository).
HF_FILE = ".eval_results/odmd-bench.yaml"

#: The plain JSON file.
JSON_FILE = "results.json"

#: What every value is.
METRIC = "mean percent error"

#: The format of ``results.json`` (bumped when a field changes meaning).
JSON_SCHEMA = "odmd-bench results 1"


def _board_id(benchmark: str, split: str) -> str:
    return f"{benchmark}-{split}"


def records(built: Built) -> list[dict[str, Any]]:
    """One record per entry and board, then one per reported result, as ``results.json`` holds them.

    A record: ``method``, ``name``, ``benchmark``, ``split``, ``board``, ``metric``,
    ``lower_is_better``, ``all``, ``sets`` (``{set: value}``), ``n`` (examples per set,
    null for reported results), ``position`` and ``group`` (null for reported results) and
    ``provenance``.
    """
    out: list[dict[str, Any]] = []
    repo = repository_url()
    for board in built.boards:
        for pos, row in enumerate(board.rows, 1):
            res, meta = row.result, row.entry.meta
            out.append(
                {
                    "method": row.entry.method,
                    "name": meta.name,
                    "benchmark": board.benchmark,
                    "split": board.split,
                    "board": _board_id(board.benchmark, board.split),
                    "metric": METRIC,
                    "lower_is_better": True,
                    "all": rounded(res.all_percent_error_mean),
                    "sets": {s: rounded(m["percent_error"]["mean"]) for s, m in res.sets.items()},
                    "n": {s: int(m["n"]) for s, m in res.sets.items()},
                    "position": pos,
                    "group": row.group,
                    "provenance": {
                        "kind": "rescored",
                        "by": f"odmd-bench {__version__}",
                        "entry": f"{ENTRIES}/{row.entry.key}",
                        "entry_url": f"{repo}/tree/main/leaderboard/{ENTRIES}/{row.entry.key}",
                        "predictions_file": row.entry.predictions.name,
                        "predictions_sha256": res.provenance["predictions_sha256"],
                        "sets_content_sha256": dict(board.sets_content_sha256),
                        "data_version": board.data_version,
                        "command": meta.command,
                        "code": meta.code,
                        "paper": meta.paper,
                        "training_data": meta.training_data,
                        "calibrated": meta.calibrated,
                        "date": meta.date,
                    },
                }
            )
    for r in built.reported:
        out.append(
            {
                "method": r.method,
                "name": r.method,
                "benchmark": r.benchmark,
                "split": r.split,
                "board": _board_id(r.benchmark, r.split),
                "metric": METRIC,
                "lower_is_better": True,
                "all": float(r.all),
                "sets": {s: float(v) for s, v in r.sets.items()},
                "n": None,
                "position": None,
                "group": None,
                "provenance": {
                    "kind": "reported",
                    "source": r.source,
                    "as_printed": {"all": r.all, "sets": dict(r.sets)},
                    "training_data": r.training_data,
                    "input": r.input,
                    "entry": r.entry,
                    "notes": r.notes,
                },
            }
        )
    return out


def json_text(built: Built) -> str:
    """``results.json``: ``{"schema", "odmd_bench", "repository", "results": records(built)}``."""
    doc = {
        "schema": JSON_SCHEMA,
        "odmd_bench": __version__,
        "repository": repository_url(),
        "results": records(built),
    }
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


def _slug(text: str) -> str:
    """A folder name for a reported method (``DBox_p^1M`` -> ``dbox_p-1m``)."""
    return re.sub(r"[^a-z0-9_.]+", "-", text.lower()).strip("-.") or "method"


def hf_items(record: Mapping[str, Any], dataset: str) -> list[dict[str, Any]]:
    """The ``.eval_results`` items of one record: All, then each set.

    ``task_id`` is the board (``odmd-v1-test``) for All and ``BOARD-SET`` for a set.
    """
    prov = record["provenance"]
    if prov["kind"] == "rescored":
        source: dict[str, Any] | None = {
            "url": prov["entry_url"],
            "name": "odmd-bench leaderboard (re-scored)",
        }
        how = (
            f"re-scored by odmd-bench from committed predictions (SHA-256 {prov['predictions_sha256']}); "
            f"rank group {record['group']}"
        )
        date: str | None = prov["date"]
    else:
        source, date = None, None
        how = f"reported in {prov['source']}, not re-scored here"
    tasks = [("", "All (mean of the sets' mean percent errors)", record["all"])]
    tasks += [(f"-{s}", f"{s} set", v) for s, v in record["sets"].items()]
    items = []
    for suffix, what, value in tasks:
        item: dict[str, Any] = {
            "dataset": {"id": dataset, "task_id": record["board"] + suffix},
            "value": value,
        }
        if date is not None:
            item["date"] = date
        if source is not None:
            item["source"] = dict(source)
        item["notes"] = f"{record['name']}: {what}, {METRIC} (lower is better); {how}"
        items.append(item)
    return items


def hf_files(built: Built, dataset: str = HF_DATASET) -> dict[str, str]:
    """``{relative path: YAML}``, each file a list of :func:`hf_items`.

    ``METHOD/.eval_results/odmd-bench.yaml`` per entry's method, ``reported/SLUG/...`` per
    method printed in a paper.
    """
    import yaml

    by_folder: dict[str, list[dict[str, Any]]] = {}
    for record in records(built):
        folder = (
            record["method"]
            if record["provenance"]["kind"] == "rescored"
            else f"reported/{_slug(record['method'])}"
        )
        by_folder.setdefault(folder, []).extend(hf_items(record, dataset))
    return {
        f"{folder}/{HF_FILE}": yaml.safe_dump(items, sort_keys=False, allow_unicode=True, width=1000)
        for folder, items in sorted(by_folder.items())
    }


def export_files(built: Built, fmt: str, *, hf_dataset: str = HF_DATASET) -> dict[str, str]:
    """The files of one format, ``{path relative to the output folder: text}``.

    Raises:
        UsageError: an unknown format (the formats are named).
    """
    if fmt == "json":
        return {JSON_FILE: json_text(built)}
    if fmt == "hf-eval-results":
        return hf_files(built, hf_dataset)
    raise UsageError(f"unknown export format {fmt!r}; expected one of {', '.join(FORMATS)}")


def write_export(files: Mapping[str, str], out: str | os.PathLike[str]) -> list[Path]:
    """Write the files under the folder ``out``, all or none (:func:`~odmd_bench.outputs.atomic.atomic_paths`)."""
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{folder} is a file; give a folder for the export")
    paths = [folder / rel for rel in files]
    for p in paths:
        ensure_folder(p.parent)
    with atomic_paths(paths) as temps:
        for tmp, text in zip(temps, files.values(), strict=True):
            tmp.write_text(text, encoding="utf-8")
    return paths


__all__ = [
    "FORMATS",
    "HF_DATASET",
    "HF_FILE",
    "JSON_FILE",
    "JSON_SCHEMA",
    "METRIC",
    "export_files",
    "hf_files",
    "hf_items",
    "json_text",
    "records",
    "write_export",
]
