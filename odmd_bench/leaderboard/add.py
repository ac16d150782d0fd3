"""``leaderboard add``: a predictions CSV made into an entry, checked as ``check`` checks it."""

from __future__ import annotations

import datetime as _dt
import gzip
import io
import os
from pathlib import Path

from odmd_bench.data.atomic import atomic_paths, temp_folder
from odmd_bench.data.examples import Examples
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.evaluation.scoring import EvaluationResult
from odmd_bench.inputs.source import read_source
from odmd_bench.leaderboard.board import load_board_data, name_clash, same_predictions, score_entry
from odmd_bench.leaderboard.entry import Entry
from odmd_bench.leaderboard.files import ENTRIES, discover, read_entry, read_predictions_bytes
from odmd_bench.leaderboard.rules import method_id_problems
from odmd_bench.leaderboard.specs import BoardSpec, board_spec


def _gzip_bytes(data: bytes) -> bytes:
    buf = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0, compresslevel=9) as gz:
        gz.write(data)
    return buf.getvalue()


def _read_input(path: Path) -> bytes:
    """The CSV's bytes: read as an entry's file is, then decompressed once, as ``evaluate`` does."""
    title = f"{path} cannot be added"
    try:
        raw = read_predictions_bytes(path)
    except ValidationError as e:
        raise ValidationError(title, e.problems) from None
    return read_source(raw, name=str(path), title=title)[0]


def _board_problems(
    root: Path, spec: BoardSpec, entry: Entry, result: EvaluationResult, examples: dict[str, Examples]
) -> list[str]:
    """What ``build`` would refuse of ``entry`` beside the board's other entries.

    Its name (:func:`~odmd_bench.leaderboard.board.name_clash`) or its predictions on
    every set (a copy) being another entry's. An entry that cannot be read or scored is
    passed over here: ``check`` names its problem.
    """
    if not (root / ENTRIES).is_dir():
        return []
    found = []
    for folder in discover(root):
        if folder.name != spec.folder or folder.parent.name == entry.method:
            continue
        try:
            other = read_entry(folder, root.parent)
            if other.meta.name == entry.meta.name:
                found.append(name_clash(spec, entry, other))
            if same_predictions(result, score_entry(other, examples), spec.sets):
                found.append(
                    f"its predictions are those of {other.key} on every set of {spec.key}; "
                    "a copy is not a new result"
                )
        except (ValidationError, OSError):
            continue
    return found


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
        ValidationError: When the predictions or the metadata are not acceptable, or
            the predictions are another entry's of the board on every set (nothing is
            written).
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
    with temp_folder() as tmp:  # a killed add's folder is removed by the next writer
        staged = tmp / method / spec.folder
        staged.mkdir(parents=True)
        (staged / "predictions.csv.gz").write_bytes(_gzip_bytes(data))
        (staged / "entry.yaml").write_text(
            yaml.safe_dump(meta, sort_keys=False, allow_unicode=True, width=100), encoding="utf-8"
        )
        title = f"{predictions} cannot be added as {method}/{spec.folder}"
        try:
            entry = read_entry(staged, root.parent)
            result = score_entry(entry, examples)
        except ValidationError as e:  # named by the file the user gave, not the staged copy
            raise ValidationError(title, e.problems or [e.message]) from None
        refused = _board_problems(root, spec, entry, result, examples)
        if refused:
            raise ValidationError(title, refused)
        misfit = _fits_the_twin(data, spec, result, data_dir)
        if misfit:
            raise ValidationError(title, [misfit])
        folder.mkdir(parents=True, exist_ok=True)
        names = ("predictions.csv.gz", "entry.yaml")
        with atomic_paths([folder / f for f in names]) as temps:  # both replaced, or neither
            for f, part in zip(names, temps, strict=True):
                part.write_bytes((staged / f).read_bytes())
    return read_entry(folder, root.parent)


def _fits_the_twin(
    data: bytes, spec: BoardSpec, result: EvaluationResult, data_dir: str | os.PathLike[str] | None
) -> str | None:
    """Why predictions without a benchmark column look made for the twin benchmark, if they do.

    ``odmd-v1`` and ``odmd-paper`` have the same sets and sizes, so ``--benchmark`` alone
    decides the board of such a file; the twin is compared when it is in the data folder.
    """
    from odmd_bench.evaluation.parse import parse_predictions
    from odmd_bench.evaluation.twin import twin_fit

    if parse_predictions(data, benchmark=spec.benchmark, strict=False).benchmark_column:
        return None  # the column says which, and agrees with --benchmark (checked)
    fit = twin_fit(result, data_dir)
    if fit is None or not fit.far_better:
        return None
    return (
        f"its depths {fit.describe()}: they look made for {fit.twin}, so add them with "
        f"--benchmark {fit.twin}; if {spec.benchmark} is right, give the file a benchmark "
        f"column saying {spec.benchmark}"
    )
