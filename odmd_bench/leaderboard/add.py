"""``leaderboard add``: a predictions CSV made into an entry, checked as ``check`` checks it."""

from __future__ import annotations

import datetime as _dt
import gzip
import io
import os
import tempfile
from pathlib import Path

from odmd_bench.data.atomic import atomic_write
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.leaderboard.board import load_board_data, score_entry
from odmd_bench.leaderboard.entry import Entry
from odmd_bench.leaderboard.files import ENTRIES, read_entry, read_predictions_bytes
from odmd_bench.leaderboard.rules import method_id_problems
from odmd_bench.leaderboard.specs import board_spec


def _gzip_bytes(data: bytes) -> bytes:
    buf = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0, compresslevel=9) as gz:
        gz.write(data)
    return buf.getvalue()


def _read_input(path: Path) -> bytes:
    try:
        return read_predictions_bytes(path)
    except ValidationError as e:
        raise ValidationError(f"{path} cannot be added", e.problems) from None


def add_entry(
    root: str | os.PathLike[str],
    predictions: str | os.PathLike[str],
    *,
    method: str,
    name: str,
    description: str,
    paper: str,
    code: str,
    training_data: str,
    command: str,
    benchmark: str,
    split: str,
    calibrated: bool,
    date: str | None = None,
    notes: str | None = None,
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    replace: bool = False,
) -> Entry:
    """Make an entry folder from a predictions CSV.

    The entry is staged in a temporary folder and read back by
    :func:`~odmd_bench.leaderboard.files.read_entry` and scored by
    :func:`~odmd_bench.leaderboard.board.score_entry`, exactly as ``build`` and ``check``
    do; only then are ``predictions.csv.gz`` and ``entry.yaml`` written.

    Raises:
        ValidationError: When the predictions or the metadata are not acceptable
            (nothing is written).
        UsageError: When there is no board for ``benchmark`` ``split``, the entry exists
            and ``replace`` is false, or its folder is a symbolic link.
    """
    import yaml

    root = Path(root)
    spec = board_spec(benchmark, split)
    bad_id = method_id_problems(method)
    if bad_id:
        raise ValidationError("the entry cannot be added", bad_id)
    folder = root / ENTRIES / method / spec.folder
    if any(p.is_symlink() for p in (folder.parent, folder)):
        raise UsageError(f"{folder} (or its method folder) is a symbolic link; entries hold plain folders")
    if folder.exists() and not replace:
        raise UsageError(f"{folder} already exists; pass --replace to overwrite it")
    data = _read_input(Path(predictions))
    examples = load_board_data(benchmark, split, data_dir, original)
    meta: dict[str, object] = {
        "method": method,
        "name": name,
        "description": description,
        "paper": paper,
        "code": code,
        "training_data": training_data,
        "command": command,
        "date": date or _dt.date.today().isoformat(),
        "benchmark": benchmark,
        "split": split,
        "calibrated": calibrated,
        "sets_content_sha256": {s: str(ex.attrs["content_sha256"]) for s, ex in examples.items()},
        "predictions": "predictions.csv.gz",
    }
    if notes:
        meta["notes"] = notes
    with tempfile.TemporaryDirectory(prefix="odmd-leaderboard-add-") as tmp:
        staged = Path(tmp) / method / spec.folder
        staged.mkdir(parents=True)
        (staged / "predictions.csv.gz").write_bytes(_gzip_bytes(data))
        (staged / "entry.yaml").write_text(
            yaml.safe_dump(meta, sort_keys=False, allow_unicode=True, width=100), encoding="utf-8"
        )
        try:
            entry = read_entry(staged, root.parent)
            score_entry(entry, examples)
        except ValidationError as e:  # named by the file the user gave, not the staged copy
            raise ValidationError(
                f"{predictions} cannot be added as {method}/{spec.folder}", e.problems or [e.message]
            ) from None
        folder.mkdir(parents=True, exist_ok=True)
        for f in ("predictions.csv.gz", "entry.yaml"):
            with atomic_write(folder / f, "wb") as fh:
                fh.write((staged / f).read_bytes())
    return read_entry(folder, root.parent)
