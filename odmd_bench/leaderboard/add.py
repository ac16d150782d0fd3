"""``leaderboard add``: a predictions CSV made into an entry, checked as ``check`` checks it."""

from __future__ import annotations

import datetime as _dt
import gzip
import hashlib
import io
import os
import re
import shlex
from collections.abc import Mapping, Sequence
from pathlib import Path

from odmd_bench.data.examples import Examples
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.evaluation.scoring import EvaluationResult
from odmd_bench.inputs.source import read_source
from odmd_bench.leaderboard.board import (
    load_board_data,
    name_clash,
    same_predictions,
    score_csv,
    score_entry,
)
from odmd_bench.leaderboard.entry import Entry
from odmd_bench.leaderboard.files import ENTRIES, discover, read_capped, read_entry, read_predictions_bytes
from odmd_bench.leaderboard.rules import MAX_PLUGIN_FILE_BYTES, method_id_problems, options_problems, show
from odmd_bench.leaderboard.specs import BoardSpec, board_spec, rounded
from odmd_bench.outputs import atomic_paths, temp_folder

#: The folder of an entry that holds its plug-in's source (``plugin.source``), as ``add`` writes it.
PLUGIN_FOLDER = "plugin"


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


def baseline_command(
    baseline: str, options: Mapping[str, object], benchmark: str, split: str, output: str = "predictions.csv"
) -> str:
    """The ``odmd-bench baseline`` command that runs ``baseline`` with ``options``.

    Example:
        >>> baseline_command("dbox", {"config": "p-z", "selection": "per-set"}, "odmd-v1", "test")
        'odmd-bench baseline dbox --config p-z --selection per-set --benchmark odmd-v1 --split test -o predictions.csv'
    """
    words = ["odmd-bench", "baseline", baseline]
    for k, v in options.items():
        text = ("true" if v else "false") if isinstance(v, bool) else str(v)
        words += [f"--{k.replace('_', '-')}", text]
    words += ["--benchmark", benchmark, "--split", split, "-o", output]
    return shlex.join(words)


def parse_options(pairs: Sequence[str]) -> dict[str, str | int | float | bool]:
    """``NAME=VALUE`` pairs as options: ``true``/``false`` as booleans, whole and decimal numbers as numbers.

    Raises:
        ValidationError: Naming every pair that is not ``NAME=VALUE`` or names an option twice.

    Example:
        >>> parse_options(["config=p-z", "steps=3", "scale=0.5", "robust=true"])
        {'config': 'p-z', 'steps': 3, 'scale': 0.5, 'robust': True}
    """
    out: dict[str, str | int | float | bool] = {}
    problems = []
    for pair in pairs:
        key, eq, text = pair.partition("=")
        key = key.strip().replace("-", "_")
        if not eq or not key:
            problems.append(f"option {show(pair)} is not NAME=VALUE")
            continue
        if key in out:
            problems.append(f"option {show(key)} is given twice")
            continue
        value: str | int | float | bool = text
        if text in ("true", "false"):
            value = text == "true"
        elif re.fullmatch(r"-?\d{1,15}", text):
            value = int(text)
        elif re.fullmatch(r"-?\d+\.\d*(e-?\d+)?", text):
            value = float(text)
        out[key] = value
    problems += options_problems(out)
    if problems:
        raise ValidationError("the options cannot be recorded", problems)
    return out


def _copy_plugin(source: Path, staged: Path, folder_name: str) -> None:
    """Copy the plug-in's source folder into the staged entry: plain ``.py`` files only.

    Links, special files, caches and other files are refused before anything is copied;
    :func:`~odmd_bench.leaderboard.files.read_entry` then applies the entry's rules to the copy.

    Raises:
        ValidationError: Naming every file that cannot be copied.
    """
    if source.is_symlink() or not source.is_dir():
        raise ValidationError(
            f"{source} cannot be the plug-in's source", ["it is not a folder (or is a link)"]
        )
    problems, files = [], []
    for path in sorted(source.rglob("*")):
        rel = path.relative_to(source)
        if "__pycache__" in rel.parts or any(part.startswith(".") for part in rel.parts):
            continue  # caches and hidden files (editor, VCS) are not the plug-in
        if path.is_symlink():
            problems.append(f"{rel} is a symbolic link; copy the file itself")
        elif path.is_dir():
            continue
        elif not path.is_file():
            problems.append(f"{rel} is not a regular file")
        elif path.suffix != ".py":
            problems.append(f"{rel} is not a .py file; a plug-in's source is plain Python files only")
        else:
            files.append(rel)
    if problems:
        raise ValidationError(f"{source} cannot be the plug-in's source", problems)
    for rel in files:
        target = staged / folder_name / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(read_capped(source / rel, MAX_PLUGIN_FILE_BYTES))


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
    benchmark: str,
    split: str,
    calibrated: bool,
    uses_test_labels: bool,
    selected_on: str,
    training_kind: str,
    command: str | None = None,
    baseline: str | None = None,
    options: Mapping[str, str | int | float | bool] | None = None,
    requirement: str | None = None,
    plugin_source: str | os.PathLike[str] | None = None,
    plugin_module: str | None = None,
    parameters: int | None = None,
    speed: Mapping[str, object] | None = None,
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
    do; only then are ``predictions.csv.gz`` and ``entry.yaml`` (and the plug-in's
    source folder) written. The entry records the predictions' SHA-256 and their scores,
    which ``check`` compares with a re-scoring.

    The command is ``command``, or, for a method run by ``odmd-bench baseline``, made
    from ``baseline`` and ``options`` (:func:`baseline_command`); ``options`` are recorded
    either way. A method not shipped here records how to get it: ``requirement``
    (``NAME==VERSION``) or ``plugin_source`` (its folder of ``.py`` files, copied into the
    entry as ``plugin/``) with ``plugin_module``.

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
    bad = method_id_problems(method)
    if (command is None) == (baseline is None):
        bad.append("give either the command that made the predictions or the baseline it ran (not both)")
    if requirement is not None and plugin_source is not None:
        bad.append("give either a pinned requirement or the plug-in's source folder, not both")
    if (plugin_source is None) != (plugin_module is None) and requirement is None:
        bad.append("a plug-in's source folder needs its module, and a module its source folder")
    if bad:
        raise ValidationError("the entry cannot be added", bad)
    if baseline is not None:
        command = baseline_command(baseline, options or {}, benchmark, split)
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
        "uses_test_labels": uses_test_labels,
        "selected_on": selected_on,
        "training_kind": training_kind,
        "sets_content_sha256": {s: str(ex.attrs["content_sha256"]) for s, ex in examples.items()},
        "predictions": "predictions.csv.gz",
        "predictions_sha256": hashlib.sha256(data).hexdigest(),
        "scores": {},  # filled in below, from the scoring of the staged entry
    }
    if notes:
        meta["notes"] = notes
    plugin: dict[str, str] = {}
    if requirement is not None:
        plugin["requirement"] = requirement
    if plugin_source is not None:
        plugin["source"] = PLUGIN_FOLDER
    if plugin_module is not None:
        plugin["module"] = plugin_module
    if plugin:
        meta["plugin"] = plugin
    if options:
        meta["options"] = dict(options)
    if parameters is not None:
        meta["parameters"] = parameters
    if speed is not None:
        meta["speed"] = dict(speed)
    with temp_folder() as tmp:  # a killed add's folder is removed by the next writer
        staged = tmp / method / spec.folder
        staged.mkdir(parents=True)
        (staged / "predictions.csv.gz").write_bytes(_gzip_bytes(data))
        if plugin_source is not None:
            _copy_plugin(Path(plugin_source), staged, PLUGIN_FOLDER)
        title = f"{predictions} cannot be added as {method}/{spec.folder}"
        try:
            result = score_csv(
                data,
                examples,
                key=f"{method}/{spec.folder}",
                file_name="predictions.csv.gz",
                benchmark=benchmark,
                split=split,
            )
            scores = {s: rounded(result.sets[s]["percent_error"]["mean"]) for s in result.sets}
            meta["scores"] = {**scores, "all": rounded(result.all_percent_error_mean)}
            (staged / "entry.yaml").write_text(
                yaml.safe_dump(meta, sort_keys=False, allow_unicode=True, width=100), encoding="utf-8"
            )
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
        names = sorted(p.relative_to(staged).as_posix() for p in staged.rglob("*") if p.is_file())
        for f in names:
            (folder / f).parent.mkdir(parents=True, exist_ok=True)
        with atomic_paths([folder / f for f in names]) as temps:  # all replaced, or none
            for f, part in zip(names, temps, strict=True):
                part.write_bytes((staged / f).read_bytes())
        _drop_old_plugin_files(folder, set(names))
    return read_entry(folder, root.parent)


def _drop_old_plugin_files(folder: Path, kept: set[str]) -> None:
    """Remove what a replaced entry's plug-in source held and the new entry does not (after it is written)."""
    old = folder / PLUGIN_FOLDER
    if not old.is_dir() or old.is_symlink():
        return
    for path in sorted(old.rglob("*"), reverse=True):  # files before their folders
        if path.relative_to(folder).as_posix() in kept:
            continue
        if path.is_dir() and not path.is_symlink():
            if not any(path.iterdir()):
                path.rmdir()
        else:
            path.unlink()
    if not any(old.iterdir()):
        old.rmdir()


def _fits_the_twin(
    data: bytes, spec: BoardSpec, result: EvaluationResult, data_dir: str | os.PathLike[str] | None
) -> str | None:
    """Why predictions without a benchmark column look made for the twin benchmark, if they do.

    ``odmd-v1`` and ``odmd-paper`` have the same sets and sizes, so ``--benchmark`` alone
    decides the board of such a file; the twin is compared when it is in the data folder.
    """
    from odmd_bench.evaluation.parse import parse_predictions
    from odmd_bench.evaluation.scoring import twin_fit

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
