"""The leaderboard: entries re-scored by the evaluator, rank groups, table, JSON, plot.

The leaderboard folder (``leaderboard/`` in the repository) holds::

    entries/<method>/<benchmark>-<split>/entry.yaml   metadata (or entry.json)
    entries/<method>/<benchmark>-<split>/predictions.csv.gz   the predictions (or .csv)
    reported.yaml      results reported in papers without predictions (never ranked)
    LEADERBOARD.md     generated: the tables
    leaderboard.json   generated: every number, with full provenance
    leaderboard.png    generated: the plot (needs matplotlib; not checked)

:func:`build` reads every entry, checks its metadata (:func:`read_entry`), loads the
sets it was made for once per benchmark and split, checks that their content SHA-256
is the one the entry records, validates and scores its predictions with the
evaluator's :func:`~odmd_bench.evaluate.read_predictions` and
:func:`~odmd_bench.evaluate.score`, and forms rank groups (:func:`rank_groups`) with
the evaluator's paired comparison :func:`~odmd_bench.compare.compare_errors`.
:func:`check` does the same and compares the result with the committed files,
naming each file, row and field that differs. Nothing here prints.

Rank groups (the exact rule): on each benchmark and split, rows are sorted by ``All``
(the mean of the sets' mean percent errors; ties broken by method id). The first row
leads group 1. Walking down the sorted rows, each row is compared with the leader of
the current group by ``compare_errors`` on per-example percent errors (``RANK_RESAMPLES``
paired bootstrap resamples and sign flips, seed ``RANK_SEED``, confidence
``RANK_CONFIDENCE``, stratified by set for ``All``). If the verdict on ``All`` is "not
distinguishable" the row joins that group; otherwise it leads the next group. So group
numbers never decrease down the table, every member of a group is indistinguishable
from its group's best row (not necessarily from every other member), and a row that
starts a new group is distinguishably worse than the previous group's best.
"""

from __future__ import annotations

import datetime as _dt
import gzip
import json
import os
import re
import tempfile
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.benchmarks import BENCHMARKS, SPLITS, get_benchmark, set_file
from odmd_bench.compare import TIE, PairedDifference, compare_errors
from odmd_bench.errors import DataError, OdmdError, UsageError, ValidationError
from odmd_bench.examples import Examples
from odmd_bench.io import atomic_write

#: Metadata files an entry folder may hold (exactly one of them).
ENTRY_FILES: tuple[str, ...] = ("entry.yaml", "entry.json")
#: Fields every entry must have: name -> what is expected.
REQUIRED_FIELDS: dict[str, str] = {
    "method": "the method's id (lowercase letters, digits, '.', '_', '-'), the same as its folder",
    "name": "the name shown in the table",
    "description": "one or two sentences",
    "paper": "an http(s) link, or 'none'",
    "code": "an http(s) link, or a path in this repository",
    "training_data": "what it was trained or tuned on ('none' for analytical methods)",
    "command": "the exact command that produced the predictions",
    "date": "when the predictions were made, YYYY-MM-DD",
    "benchmark": f"one of {', '.join(BENCHMARKS)}",
    "split": f"one of {', '.join(SPLITS)}",
    "sets_content_sha256": "{set: SHA-256 of the set's content} for every set the predictions were made for",
    "calibrated": "true if the method uses the camera intrinsics, else false",
    "predictions": "the predictions file in the entry folder (.csv or .csv.gz)",
}
#: Fields an entry may have.
OPTIONAL_FIELDS: dict[str, str] = {"notes": "anything else a reader should know"}

#: Settings of the paired comparison that forms rank groups.
RANK_RESAMPLES = 2000
RANK_SEED = 0
RANK_CONFIDENCE = 0.95

#: Generated files, relative to the leaderboard folder.
MARKDOWN = "LEADERBOARD.md"
JSON_FILE = "leaderboard.json"
PLOT = "leaderboard.png"
REPORTED = "reported.yaml"
ENTRIES = "entries"

#: Decompressed predictions larger than this are refused (a CSV of 12,000 rows is ~0.6 MB).
MAX_PREDICTIONS_BYTES = 64 * 2**20
#: Decimals kept for floats in leaderboard.json, so that the file does not depend on the
#: last bit of a sum (which may differ between numpy builds).
JSON_DECIMALS = 6

_METHOD_ID = re.compile(r"[a-z0-9][a-z0-9._-]*")
_SHA256 = re.compile(r"[0-9a-f]{64}")
_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")
_SET_TITLES = {
    "normal": "Normal",
    "camera": "Camera",
    "object": "Object",
    "robot": "Robot",
    "perturb": "Perturb",
    "driving": "Driving",
}


# ----------------------------------------------------------------------------- entries


@dataclass(frozen=True)
class Entry:
    """One method's predictions on one benchmark and split, with their metadata.

    Attributes:
        folder: the entry folder.
        key: ``<method>/<benchmark>-<split>``, how messages name the entry.
        meta: the metadata as written (``date`` as ``YYYY-MM-DD``).
        predictions: the predictions file.
    """

    folder: Path
    key: str
    meta: dict[str, Any]
    predictions: Path

    @property
    def method(self) -> str:
        return str(self.meta["method"])

    @property
    def benchmark(self) -> str:
        return str(self.meta["benchmark"])

    @property
    def split(self) -> str:
        return str(self.meta["split"])


def find_root(start: str | os.PathLike[str] | None = None) -> Path:
    """The ``leaderboard`` folder in ``start`` (default: the current folder) or a parent.

    Raises
    ------
    UsageError
        When there is none; pass ``--root``.
    """
    here = Path(start if start is not None else Path.cwd()).resolve()
    for folder in (here, *here.parents):
        if (folder / "leaderboard" / ENTRIES).is_dir():
            return folder / "leaderboard"
        if folder.name == "leaderboard" and (folder / ENTRIES).is_dir():
            return folder
    raise UsageError(
        f"no leaderboard folder (one holding {ENTRIES}/) in {here} or its parents; "
        "run from the repository or pass --root"
    )


def discover(root: str | os.PathLike[str]) -> list[Path]:
    """Entry folders ``root/entries/<method>/<benchmark>-<split>/``, sorted."""
    base = Path(root) / ENTRIES
    if not base.is_dir():
        raise UsageError(f"{root} has no {ENTRIES}/ folder; is it a leaderboard folder?")
    return sorted(p for m in base.iterdir() if m.is_dir() for p in m.iterdir() if p.is_dir())


def _load_meta(folder: Path) -> tuple[dict[str, Any] | None, list[str]]:
    import yaml

    found = [folder / n for n in ENTRY_FILES if (folder / n).is_file()]
    if not found:
        return None, [f"no metadata file: expected one of {', '.join(ENTRY_FILES)}"]
    if len(found) > 1:
        return None, [f"two metadata files ({', '.join(p.name for p in found)}); keep one"]
    path = found[0]
    try:
        text = path.read_text(encoding="utf-8")
        data = json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (OSError, UnicodeDecodeError, ValueError, yaml.YAMLError) as e:
        return None, [f"{path.name} cannot be read: {str(e).splitlines()[0] if str(e) else e}"]
    if not isinstance(data, dict):
        return None, [f"{path.name} must hold a mapping of fields, not {type(data).__name__}"]
    return data, []


def _is_url(value: str) -> bool:
    return re.fullmatch(r"https?://\S+", value) is not None


def read_entry(folder: str | os.PathLike[str], repo_root: str | os.PathLike[str] | None = None) -> Entry:
    """Read and check an entry's metadata (not its predictions' content).

    Parameters
    ----------
    folder : the entry folder ``<root>/entries/<method>/<benchmark>-<split>``
    repo_root : where repository paths in ``code`` are resolved (default: the folder
        holding the leaderboard folder)

    Raises
    ------
    ValidationError
        Naming every missing, unknown or malformed field at once.
    """
    folder = Path(folder)
    key = f"{folder.parent.name}/{folder.name}"
    repo = Path(repo_root) if repo_root is not None else folder.parents[2].parent
    meta, problems = _load_meta(folder)
    if meta is None:
        raise ValidationError(f"entry {key}: metadata cannot be used", problems)
    unknown = [k for k in meta if k not in REQUIRED_FIELDS and k not in OPTIONAL_FIELDS]
    for k in unknown:
        problems.append(
            f"unknown field {k!r}; the fields are {', '.join(REQUIRED_FIELDS)} (optional: {', '.join(OPTIONAL_FIELDS)})"
        )
    for k, what in REQUIRED_FIELDS.items():
        if k not in meta or meta[k] is None or (isinstance(meta[k], str) and not meta[k].strip()):
            problems.append(f"missing field {k!r}: {what}")
    text_fields = [k for k in REQUIRED_FIELDS if k not in ("date", "sets_content_sha256", "calibrated")]
    for k in [*text_fields, *OPTIONAL_FIELDS]:
        if k in meta and meta[k] is not None and not isinstance(meta[k], str):
            problems.append(f"field {k!r} must be text, got {meta[k]!r}")
    good = dict(meta)

    method = meta.get("method")
    if isinstance(method, str) and method:
        if not _METHOD_ID.fullmatch(method):
            problems.append(f"method {method!r} must be lowercase letters, digits, '.', '_' or '-'")
        elif method != folder.parent.name:
            problems.append(f"method {method!r} does not match its folder entries/{folder.parent.name}/")
    bench = meta.get("benchmark") if isinstance(meta.get("benchmark"), str) else None
    split = meta.get("split") if isinstance(meta.get("split"), str) else None
    if isinstance(bench, str) and bench and bench not in BENCHMARKS:
        problems.append(f"unknown benchmark {bench!r}; expected one of {', '.join(BENCHMARKS)}")
    if isinstance(split, str) and split and split not in SPLITS:
        problems.append(f"unknown split {split!r}; expected one of {', '.join(SPLITS)}")
    if bench in BENCHMARKS and split in SPLITS and folder.name != f"{bench}-{split}":
        problems.append(
            f"an entry for {bench} {split} must be in a folder named {bench}-{split}, not {folder.name}"
        )

    date = meta.get("date")
    if isinstance(date, _dt.date) and not isinstance(date, _dt.datetime):
        good["date"] = date.isoformat()
    elif isinstance(date, str) and date:
        try:
            if not _DATE.fullmatch(date):
                raise ValueError
            _dt.date.fromisoformat(date)
        except ValueError:
            problems.append(f"date {date!r} is not a date YYYY-MM-DD")
    elif date is not None:
        problems.append(f"date {date!r} is not a date YYYY-MM-DD")

    if "calibrated" in meta and meta["calibrated"] is not None and not isinstance(meta["calibrated"], bool):
        problems.append(f"calibrated must be true or false, got {meta['calibrated']!r}")

    for k in ("paper", "code"):
        v = meta.get(k)
        if not isinstance(v, str) or not v.strip():
            continue
        if _is_url(v) or (k == "paper" and v == "none"):
            continue
        if k == "code" and not v.startswith(("/", "..")) and (repo / v).exists():
            continue
        problems.append(f"{k} {v!r} is not {REQUIRED_FIELDS[k]}" + (" that exists" if k == "code" else ""))

    hashes = meta.get("sets_content_sha256")
    if hashes is not None:
        if not isinstance(hashes, dict):
            problems.append("sets_content_sha256 must map each set to its SHA-256")
        else:
            if bench in BENCHMARKS:
                sets = BENCHMARKS[str(bench)].sets
                missing = [s for s in sets if s not in hashes]
                extra = [s for s in hashes if s not in sets]
                if missing:
                    problems.append(f"sets_content_sha256 lacks the sets {', '.join(missing)}")
                if extra:
                    problems.append(
                        f"sets_content_sha256 names unknown sets {', '.join(map(str, extra))}; "
                        f"{bench} has {', '.join(sets)}"
                    )
            for s, h in hashes.items():
                if not isinstance(h, str) or not _SHA256.fullmatch(h):
                    problems.append(f"sets_content_sha256 of {s!r} is not 64 lowercase hex digits: {h!r}")

    preds_name = meta.get("predictions")
    preds = folder / "predictions.csv"
    if isinstance(preds_name, str) and preds_name:
        if "/" in preds_name or "\\" in preds_name or preds_name.startswith("."):
            problems.append(f"predictions {preds_name!r} must be a file name in the entry folder")
        elif not preds_name.endswith((".csv", ".csv.gz")):
            problems.append(f"predictions {preds_name!r} must be a .csv or .csv.gz file")
        elif not (folder / preds_name).is_file():
            problems.append(f"predictions file {preds_name} is not in the entry folder")
        else:
            preds = folder / preds_name
    if problems:
        raise ValidationError(f"entry {key}: metadata is incomplete or wrong", problems)
    return Entry(folder=folder, key=key, meta=good, predictions=preds)


# ----------------------------------------------------------------------------- scoring


@dataclass(frozen=True)
class Row:
    """A re-scored entry on its board.

    Attributes:
        entry: the entry.
        result: the evaluator's result (sets, All, provenance, per-example errors).
        group: rank group (1 is best), set by :func:`rank_groups`.
        leader: method id of the group's leader (itself for the leader).
        versus_leader, versus_previous: as in :class:`Ranked`.
    """

    entry: Entry
    result: Any  # odmd_bench.evaluate.EvaluationResult
    group: int = 0
    leader: str = ""
    versus_leader: PairedDifference | None = None
    versus_previous: PairedDifference | None = None


@dataclass(frozen=True)
class Board:
    """The ranked rows of one benchmark and split."""

    benchmark: str
    split: str
    sets: tuple[str, ...]
    sets_content_sha256: dict[str, str]
    data_version: str
    rows: tuple[Row, ...]


@dataclass(frozen=True)
class Built:
    """What :func:`build` writes: the boards, the reported results, the two texts."""

    boards: tuple[Board, ...]
    reported: tuple[dict[str, Any], ...]
    markdown: str
    json_text: str


def _read_predictions_file(path: Path, read: Callable[[Path], Any]) -> Any:
    """Call ``read`` on the predictions CSV, decompressing a ``.gz`` into a temp file."""
    if path.suffix != ".gz":
        return read(path)
    try:
        with gzip.open(path, "rb") as fh:
            data = fh.read(MAX_PREDICTIONS_BYTES + 1)
    except (OSError, EOFError, zlib.error) as e:
        raise ValidationError(f"{path} cannot be scored", [f"not a readable gzip file ({e})"]) from None
    if len(data) > MAX_PREDICTIONS_BYTES:
        raise ValidationError(
            f"{path} cannot be scored", [f"decompressed size exceeds {MAX_PREDICTIONS_BYTES} bytes"]
        )
    with tempfile.TemporaryDirectory(prefix="odmd-leaderboard-") as tmp:
        plain = Path(tmp) / path.name[: -len(".gz")]
        plain.write_bytes(data)
        return read(plain)


def data_version(examples: Mapping[str, Examples]) -> str:
    """How the sets were made, e.g. ``generator v1 + imported robot`` or ``original release``."""
    parts = []
    gens = sorted(
        {int(ex.attrs["generator_version"]) for ex in examples.values() if "generator_version" in ex.attrs}
    )
    if gens:
        parts.append("generator " + ", ".join(f"v{g}" for g in gens))
    imported = [s for s, ex in examples.items() if "generator_version" not in ex.attrs]
    if imported and gens:
        parts.append("imported " + ", ".join(imported))
    elif imported:
        parts.append("original release")
    return " + ".join(parts)


def load_board_data(
    benchmark: str,
    split: str,
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
) -> dict[str, Examples]:
    """The sets of a board. A generated benchmark is generated when missing; an imported
    one is imported from ``original`` (the original release's folder) when missing and
    ``original`` is given."""
    from odmd_bench.data import load_split

    b = get_benchmark(benchmark)
    if not b.generated and original is not None and not set_file(benchmark, split, data_dir).exists():
        from odmd_bench.importer import import_release

        import_release(original, data_dir, benchmark=benchmark)
    try:
        return load_split(split, benchmark, data_dir)
    except DataError as e:
        if b.generated or original is not None:
            raise
        raise DataError(
            e.message + " (or give the leaderboard command --original PATH, or set ODMD_ORIGINAL)",
            e.problems,
        ) from None


def score_entry(entry: Entry, examples: Mapping[str, Examples]) -> Any:
    """Validate and score an entry's predictions against the sets it was made for.

    Raises
    ------
    ValidationError
        When the sets' content hashes differ from the entry's, the predictions are for
        another benchmark or split, or the file fails the evaluator's validation.
    """
    from odmd_bench.evaluate import read_predictions, score

    problems = []
    recorded = entry.meta["sets_content_sha256"]
    for s, ex in examples.items():
        now = str(ex.attrs.get("content_sha256", ""))
        if recorded.get(s) != now:
            problems.append(
                f"the predictions were made for {entry.benchmark} {entry.split} {s} with content "
                f"SHA-256 {str(recorded.get(s))[:16]}..., but that set now has {now[:16]}...: they are "
                "for different data; make new predictions on the current sets (odmd-bench leaderboard add)"
            )
    if problems:
        raise ValidationError(f"entry {entry.key}: predictions are for different data", problems)

    sizes = {s: len(ex) for s, ex in examples.items()}
    splits_seen: list[str] = []

    def set_sizes(bench: str, split: str) -> dict[str, int]:
        splits_seen.append(split)
        return sizes

    def read(path: Path) -> Any:
        return read_predictions(path, set_sizes=set_sizes, benchmark=entry.benchmark)

    title = f"entry {entry.key}: {entry.predictions.name} fails validation"
    wrong_split = f"the file holds split {{!r}} but the entry is for {entry.split!r}"
    try:
        preds = _read_predictions_file(entry.predictions, read)
    except ValidationError as e:
        lines = e.problems or [e.message]
        if splits_seen and splits_seen[0] != entry.split:
            lines = [wrong_split.format(splits_seen[0]), *lines]
        raise ValidationError(title, lines) from None
    if preds.split != entry.split:
        raise ValidationError(title, [wrong_split.format(preds.split)])
    return score(preds, examples)


# ----------------------------------------------------------------------------- ranking


@dataclass(frozen=True)
class Ranked:
    """One row's place.

    Attributes:
        key: the method.
        all_mean: its All.
        group: its rank group (1 is best).
        leader: the method leading its group (itself for a leader).
        versus_leader: comparison with the group's leader on All, A = leader, B = this
            row (None for a leader).
        versus_previous: for the leader of group g > 1, the comparison with the leader
            of group g - 1 that started the new group (A = that leader), else None.
    """

    key: str
    all_mean: float
    group: int
    leader: str
    versus_leader: PairedDifference | None = None
    versus_previous: PairedDifference | None = None


def rank_groups(
    errors: Mapping[str, Mapping[str, Any]],
    *,
    n_resamples: int | None = None,
    seed: int = RANK_SEED,
    confidence: float = RANK_CONFIDENCE,
) -> list[Ranked]:
    """Sort methods by All and form rank groups (rule in the module docstring).

    Parameters
    ----------
    errors : ``{method: {set: (N_set,) per-example percent errors}}``, the same sets
        and examples for every method.
    n_resamples, seed, confidence : passed to :func:`odmd_bench.compare.compare_errors`

    Returns
    -------
    list of Ranked, best first.

    Examples
    --------
    >>> import numpy as np
    >>> e = np.linspace(1, 2, 100)
    >>> [(r.key, r.group) for r in rank_groups({"b": {"s": e}, "a": {"s": e}, "c": {"s": e + 5}})]
    [('a', 1), ('b', 1), ('c', 2)]
    """
    n_resamples = RANK_RESAMPLES if n_resamples is None else n_resamples
    means = {
        k: float(np.mean([np.mean(np.asarray(v, dtype=np.float64)) for v in sets.values()]))
        for k, sets in errors.items()
    }
    order = sorted(errors, key=lambda k: (means[k], k))
    out: list[Ranked] = []
    for k in order:
        if not out:
            out.append(Ranked(k, means[k], 1, k))
            continue
        group, leader = out[-1].group, out[-1].leader
        c = compare_errors(
            errors[leader], errors[k], n_resamples=n_resamples, seed=seed, confidence=confidence
        )
        if c.all.verdict == TIE:
            out.append(Ranked(k, means[k], group, leader, versus_leader=c.all))
        else:
            out.append(Ranked(k, means[k], group + 1, k, versus_previous=c.all))
    return out


# ----------------------------------------------------------------------------- reported


_REPORTED_FIELDS = ("method", "benchmark", "split", "sets", "all", "training_data", "source")
_REPORTED_OPTIONAL = ("entry", "notes")


def read_reported(root: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The results reported without predictions (``reported.yaml``), checked.

    Values are kept as written (text such as ``"4.5"``), so the table shows the
    precision the source gave.
    """
    import yaml

    path = Path(root) / REPORTED
    if not path.exists():
        return []
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as e:
        raise ValidationError(f"{path} cannot be read", [str(e)]) from None
    if data is None:
        return []
    if not isinstance(data, list):
        raise ValidationError(f"{path} cannot be used", ["it must hold a list of results"])
    problems = []
    out = []
    for i, item in enumerate(data):
        where = f"result {i + 1}"
        if not isinstance(item, dict):
            problems.append(f"{where}: must be a mapping")
            continue
        where = f"result {i + 1} ({item.get('method', '?')})"
        for k in item:
            if k not in _REPORTED_FIELDS + _REPORTED_OPTIONAL:
                problems.append(
                    f"{where}: unknown field {k!r}; expected {', '.join(_REPORTED_FIELDS + _REPORTED_OPTIONAL)}"
                )
        for k in _REPORTED_FIELDS:
            if item.get(k) in (None, ""):
                problems.append(f"{where}: missing field {k!r}")
        bench = item.get("benchmark")
        if bench is not None and bench not in BENCHMARKS:
            problems.append(f"{where}: unknown benchmark {bench!r}")
            continue
        values = dict(item.get("sets") or {})
        if bench is not None:
            sets = BENCHMARKS[bench].sets
            if sorted(values) != sorted(sets):
                problems.append(f"{where}: sets must be exactly {', '.join(sets)}")
        for s, v in [*values.items(), ("all", item.get("all"))]:
            try:
                float(str(v))
            except ValueError:
                problems.append(f"{where}: value of {s} is not a number: {v!r}")
        out.append(
            {k: item.get(k) for k in _REPORTED_FIELDS + _REPORTED_OPTIONAL}
            | {"sets": {s: str(values[s]) for s in values}, "all": str(item.get("all"))}
        )
    if problems:
        raise ValidationError(f"{path} cannot be used", problems)
    return out


# ----------------------------------------------------------------------------- build


def collect(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    n_resamples: int | None = None,
) -> tuple[list[Board], list[str]]:
    """Read, validate, score and rank every entry under ``root``.

    Returns
    -------
    (boards, problems): the boards of the entries that passed, and one line per
    problem found (every entry is looked at; nothing stops at the first problem).
    """
    root = Path(root)
    problems: list[str] = []
    entries: list[Entry] = []
    for folder in discover(root):
        try:
            entries.append(read_entry(folder, root.parent))
        except ValidationError as err:
            problems.append(err.message)
            problems.extend(f"  {p}" for p in err.problems)
    boards: list[Board] = []
    by_board: dict[tuple[str, str], list[Entry]] = {}
    for e in entries:
        by_board.setdefault((e.benchmark, e.split), []).append(e)
    for (bench, split), group in sorted(by_board.items()):
        try:
            examples = load_board_data(bench, split, data_dir, original)
        except OdmdError as err:
            problems.append(
                f"{bench} {split} ({', '.join(e.key for e in group)}): data cannot be loaded: {err.render()}"
            )
            continue
        scored = []
        for e in group:
            try:
                scored.append((e, score_entry(e, examples)))
            except ValidationError as err:
                problems.append(err.message)
                problems.extend(f"  {p}" for p in err.problems)
        if not scored:
            continue
        ranked = rank_groups({e.method: r.percent_errors() for e, r in scored}, n_resamples=n_resamples)
        by_method = {e.method: (e, r) for e, r in scored}
        rows = tuple(
            Row(*by_method[x.key], x.group, x.leader, x.versus_leader, x.versus_previous) for x in ranked
        )
        b = get_benchmark(bench)
        boards.append(
            Board(
                benchmark=bench,
                split=split,
                sets=b.sets,
                sets_content_sha256={s: str(ex.attrs["content_sha256"]) for s, ex in examples.items()},
                data_version=data_version(examples),
                rows=rows,
            )
        )
    # Boards in a stable, meaningful order: the paper's data first, then by name.
    boards.sort(key=lambda bd: (bd.benchmark != "odmd-paper", bd.benchmark, bd.split))
    return boards, problems


def build(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    n_resamples: int | None = None,
) -> Built:
    """Everything ``leaderboard build`` writes, computed (nothing is written).

    Raises
    ------
    ValidationError
        Naming every problem with the entries (metadata, data, predictions).
    """
    n_resamples = RANK_RESAMPLES if n_resamples is None else n_resamples
    boards, problems = collect(root, data_dir, original, n_resamples=n_resamples)
    reported: list[dict[str, Any]] = []
    try:
        reported = read_reported(root)
    except ValidationError as e:
        problems.append(e.message)
        problems.extend(f"  {p}" for p in e.problems)
    if problems:
        raise ValidationError("the leaderboard cannot be built", problems)
    return Built(
        boards=tuple(boards),
        reported=tuple(reported),
        markdown=render_markdown(boards, reported, n_resamples=n_resamples),
        json_text=render_json(boards, reported, n_resamples=n_resamples),
    )


def _r(x: float) -> float:
    v = round(float(x), JSON_DECIMALS)
    return 0.0 if v == 0 else v  # no "-0.0"


def _diff_dict(d: PairedDifference | None, a: str, b: str) -> dict[str, Any] | None:
    """The evaluator's comparison of ``a`` (the leader) and ``b`` (this row): ``a - b``."""
    if d is None:
        return None
    return {
        "a": a,
        "b": b,
        "difference_a_minus_b": _r(d.difference),
        "ci_low": _r(d.ci_low),
        "ci_high": _r(d.ci_high),
        "p_value": _r(d.p_value),
        "verdict": d.verdict,
    }


def _rule(n_resamples: int | None) -> str:
    n_resamples = RANK_RESAMPLES if n_resamples is None else n_resamples
    return (
        "Rows sorted by All (ties by method id). The first row leads group 1; each next row is "
        "compared with the current group's leader by odmd_bench.compare.compare_errors on per-example "
        f"percent errors ({n_resamples} paired bootstrap resamples and sign flips, seed {RANK_SEED}, "
        f"confidence {RANK_CONFIDENCE}, stratified by set for All); it joins the group if the verdict "
        "on All is 'not distinguishable', otherwise it leads the next group."
    )


def render_json(
    boards: Sequence[Board], reported: Sequence[Mapping[str, Any]], *, n_resamples: int | None = None
) -> str:
    """``leaderboard.json``: every board's rows with all metrics, metadata and provenance."""
    out: dict[str, Any] = {
        "generated_by": "odmd-bench leaderboard build",
        "metric": "percent_error (|Z - Z_hat| / Z * 100); all = mean of the sets' mean percent errors",
        "float_decimals": JSON_DECIMALS,
        "rank_groups": {
            "rule": _rule(n_resamples),
            "n_resamples": RANK_RESAMPLES if n_resamples is None else n_resamples,
            "seed": RANK_SEED,
            "confidence": RANK_CONFIDENCE,
        },
        "boards": [],
        "reported": [dict(r) for r in reported],
    }
    for bd in boards:
        rows = []
        previous_leader = ""
        for pos, row in enumerate(bd.rows, 1):
            res = row.result
            meta = row.entry.meta
            if row.versus_previous is not None:
                previous_leader = next(r.leader for r in bd.rows if r.group == row.group - 1)
            rows.append(
                {
                    "position": pos,
                    "group": row.group,
                    "method": row.entry.method,
                    "name": meta["name"],
                    "all": _r(res.all_percent_error_mean),
                    "sets": {
                        s: {
                            "n": int(m["n"]),
                            **{
                                err: {k: _r(v) for k, v in m[err].items()}
                                for err in ("percent_error", "absolute_error")
                            },
                        }
                        for s, m in res.sets.items()
                    },
                    "group_leader": row.leader,
                    "versus_group_leader": _diff_dict(row.versus_leader, row.leader, row.entry.method),
                    "versus_previous_group_leader": _diff_dict(
                        row.versus_previous, previous_leader, row.entry.method
                    ),
                    "warnings": list(res.warnings),
                    "entry": f"{ENTRIES}/{row.entry.key}",
                    "predictions_file": row.entry.predictions.name,
                    "predictions_csv_sha256": res.provenance["predictions_sha256"],
                    "predictions_rows": res.provenance["predictions_rows"],
                    "metadata": {k: meta[k] for k in (*REQUIRED_FIELDS, *OPTIONAL_FIELDS) if k in meta},
                }
            )
        out["boards"].append(
            {
                "benchmark": bd.benchmark,
                "split": bd.split,
                "data_version": bd.data_version,
                "sets": list(bd.sets),
                "sets_content_sha256": bd.sets_content_sha256,
                "rows": rows,
            }
        )
    return json.dumps(out, indent=2, sort_keys=False, ensure_ascii=False) + "\n"


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _fmt(x: float) -> str:
    s = f"{x:.2f}"
    return "0.00" if s == "-0.00" else s


def render_markdown(
    boards: Sequence[Board], reported: Sequence[Mapping[str, Any]], *, n_resamples: int | None = None
) -> str:
    """``LEADERBOARD.md``: one ranked table per benchmark and split, then the reported table."""
    lines = [
        "<!-- Generated by `odmd-bench leaderboard build`; do not edit. `odmd-bench leaderboard check` "
        "(run by CI) fails when this file differs from a fresh build. -->",
        "",
        "# Leaderboard",
        "",
        "Mean percent error `|Z - Z_hat| / Z * 100` per test set (lower is better); **All** is the mean of "
        "the four sets' means (the paper's \"All Sets\"). Every number is recomputed from the committed "
        "predictions by the package's evaluator, on sets whose content SHA-256 each entry records; the "
        "full statistics are in `leaderboard.json`.",
        "",
        f"**Group**: methods that cannot be told apart share a group. {_rule(n_resamples)} "
        "**vs group best** is that difference of All (this row minus the group's best row) with its 95% "
        "bootstrap interval. **Calibrated**: uses the camera intrinsics.",
        "",
    ]
    for bd in boards:
        desc = BENCHMARKS[bd.benchmark].description
        hashes = ", ".join(f"{s} `{h[:12]}`" for s, h in bd.sets_content_sha256.items())
        lines += [
            f"## {bd.benchmark} {bd.split}",
            "",
            f"Data: {desc}. Version: {bd.data_version}; content SHA-256 {hashes}.",
            "",
        ]
        head = ["Group", "Method", *[_SET_TITLES.get(s, s) for s in bd.sets], "All", "vs group best"]
        head += ["Calibrated", "Trained on", "Data", "Date"]
        lines.append("| " + " | ".join(head) + " |")
        lines.append(
            "|"
            + "|".join(" ---: " if i in range(2, 3 + len(bd.sets)) else " --- " for i in range(len(head)))
            + "|"
        )
        for row in bd.rows:
            res = row.result
            meta = row.entry.meta
            vs = row.versus_leader
            if vs is None:
                vs_cell = "best" if row.group == 1 else "group best"
            else:
                # The evaluator reports leader - row; the table shows row - leader.
                diff, lo, hi = (-v + 0.0 for v in (vs.difference, vs.ci_high, vs.ci_low))  # + 0.0: no -0
                vs_cell = f"{diff:+.2f} [{lo:+.2f}, {hi:+.2f}]".replace("-0.00", "+0.00")
            cells = [
                str(row.group),
                f"[{_cell(meta['name'])}]({ENTRIES}/{row.entry.key}/)",
                *[_fmt(res.sets[s]["percent_error"]["mean"]) for s in bd.sets],
                f"**{_fmt(res.all_percent_error_mean)}**",
                vs_cell,
                "yes" if meta["calibrated"] else "no",
                _cell(meta["training_data"]),
                f"{bd.benchmark} ({bd.data_version})",
                str(meta["date"]),
            ]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    if reported:
        rescored = {(r.entry.method, bd.benchmark, bd.split): r for bd in boards for r in bd.rows}
        lines += [
            "## Reported in papers (not reproducible here)",
            "",
            "**These numbers are copied from publications, not computed here**: no predictions are "
            "available, so they are not re-scored, take no group and are not comparable by the paired "
            "test. Where an entry above reproduces the method, its re-scored All is shown beside.",
            "",
        ]
        benches = sorted({(r["benchmark"], r["split"]) for r in reported})
        for bench, split in benches:
            sets = BENCHMARKS[bench].sets
            head = [
                "Method",
                *[_SET_TITLES.get(s, s) for s in sets],
                "All",
                "Trained on",
                "Source",
                "Re-scored here",
            ]
            lines += [f"### {bench} {split} (reported)", ""]
            lines.append("| " + " | ".join(head) + " |")
            lines.append(
                "|"
                + "|".join(" ---: " if 1 <= i <= len(sets) + 1 else " --- " for i in range(len(head)))
                + "|"
            )
            for r in reported:
                if (r["benchmark"], r["split"]) != (bench, split):
                    continue
                here = "-"
                if r.get("entry"):
                    match = rescored.get((r["entry"], bench, split))
                    here = (
                        f"{match.entry.meta['name']}: {_fmt(match.result.all_percent_error_mean)}"
                        if match is not None
                        else f"no entry {r['entry']} yet"
                    )
                cells = [
                    _cell(r["method"]),
                    *[_cell(r["sets"][s]) for s in sets],
                    _cell(r["all"]),
                    _cell(r["training_data"]),
                    _cell(r["source"]),
                    _cell(here),
                ]
                lines.append("| " + " | ".join(cells) + " |")
            lines.append("")
    return "\n".join(lines).rstrip("\n") + "\n"


def write(root: str | os.PathLike[str], built: Built, *, plot: bool = True) -> list[str]:
    """Write ``LEADERBOARD.md``, ``leaderboard.json`` and (if matplotlib is there) the plot.

    Returns one line per thing done or skipped.
    """
    root = Path(root)
    said = []
    for name, text in ((MARKDOWN, built.markdown), (JSON_FILE, built.json_text)):
        with atomic_write(root / name, "w") as fh:
            fh.write(text)
        said.append(f"wrote {root / name}")
    if plot:
        try:
            plot_boards(built.boards, root / PLOT)
            said.append(f"wrote {root / PLOT}")
        except ModuleNotFoundError as e:
            if e.name is None or not e.name.startswith("matplotlib"):
                raise
            said.append(
                f"skipped the plot {root / PLOT}: matplotlib is not installed (pip install 'odmd-bench[plot]')"
            )
    return said


# ----------------------------------------------------------------------------- plot


def plot_boards(boards: Sequence[Board], path: str | os.PathLike[str], *, top: int = 3) -> None:
    """PNG: per board, mean percent error per set per method (bars) and median percent
    error against true depth (binned) for the ``top`` best methods.

    Raises ModuleNotFoundError when matplotlib is missing (it is an optional extra).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from odmd_bench.io import atomic_path

    n = max(1, len(boards))
    fig = Figure(figsize=(14, 4.6 * n), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n, 2, squeeze=False)
    for (ax_bar, ax_depth), bd in zip(axes, boards, strict=False):
        labels = [*(_SET_TITLES.get(s, s) for s in bd.sets), "All"]
        x = np.arange(len(labels))
        width = 0.8 / max(1, len(bd.rows))
        for i, row in enumerate(bd.rows):
            res = row.result
            vals = [res.sets[s]["percent_error"]["mean"] for s in bd.sets] + [res.all_percent_error_mean]
            bars = ax_bar.bar(
                x + (i - (len(bd.rows) - 1) / 2) * width,
                vals,
                width,
                label=f"{row.entry.meta['name']} (group {row.group})",
            )
            ax_bar.bar_label(bars, fmt="%.1f", fontsize=7, padding=1)
        ax_bar.set_xticks(x, labels)
        ax_bar.set_ylabel("mean percent error (%)")
        ax_bar.set_title(f"{bd.benchmark} {bd.split}: mean percent error per set")
        ax_bar.legend(fontsize=8)
        ax_bar.grid(axis="y", alpha=0.3)

        for row in bd.rows[:top]:
            res = row.result
            errs = res.percent_errors()
            depth = np.concatenate([res.examples[s].depth for s in bd.sets])
            err = np.concatenate([errs[s] for s in bd.sets])
            edges = np.quantile(depth, np.linspace(0, 1, 13))
            which = np.clip(np.searchsorted(edges, depth, side="right") - 1, 0, len(edges) - 2)
            centres, medians = [], []
            for b in range(len(edges) - 1):
                sel = which == b
                if sel.any():
                    centres.append(float(np.median(depth[sel])))
                    medians.append(float(np.median(err[sel])))
            ax_depth.plot(
                centres,
                medians,
                marker="o",
                label=f"{row.entry.meta['name']} (All {res.all_percent_error_mean:.2f})",
            )
        ax_depth.set_xlabel("true depth Z (m)")
        ax_depth.set_ylabel("median percent error (%) per depth bin")
        ax_depth.set_title(
            f"{bd.benchmark} {bd.split}: error against true depth, top {min(top, len(bd.rows))} (all sets)"
        )
        ax_depth.legend(fontsize=8)
        ax_depth.grid(alpha=0.3)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, metadata={"Software": None})


# ----------------------------------------------------------------------------- check


def _json_label(node: Any, i: int) -> str:
    if isinstance(node, dict):
        if "method" in node and isinstance(node["method"], str):
            return node["method"]
        if "benchmark" in node and "split" in node:
            return f"{node['benchmark']} {node['split']}"
    return str(i)


def _flatten(node: Any, prefix: str = "") -> dict[str, Any]:
    """``{path: leaf}``; list items are named by their method or benchmark when they have one."""
    out: dict[str, Any] = {}
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
        old = json.loads(committed)
    except ValueError as e:
        return [f"{name}: not valid JSON ({e}); run `odmd-bench leaderboard build`"]
    a, b = _flatten(old), _flatten(json.loads(built))
    out = []
    for k in [*a, *(k for k in b if k not in a)]:
        if k not in b:
            out.append(f"{name}: {k}: committed {a[k]!r}, build does not write it")
        elif k not in a:
            out.append(f"{name}: {k}: missing, build writes {b[k]!r}")
        elif a[k] != b[k] or type(a[k]) is not type(b[k]):
            out.append(f"{name}: {k}: committed {a[k]!r}, build writes {b[k]!r}")
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
    """One line per difference. Table rows are matched by table and row name (the method),
    so a changed cell is named by table, row and column even when rows moved."""
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
                        f"committed {x!r}, build writes {y!r}"
                    )
        rest_old = [i for i in range(i1, i2) if (k := _row_key(old, i)) is None or k[:2] not in matched]
        rest_new = [j for j in range(j1, j2) if (k := _row_key(new, j)) is None or k[:2] not in matched]
        if len(rest_old) == len(rest_new):  # lines changed in place
            for i, j in zip(rest_old, rest_new, strict=True):
                out.append(f"{name} line {i + 1}: committed {old[i]!r}, build writes {new[j]!r}")
            continue
        for i in rest_old:
            out.append(f"{name} line {i + 1}: committed {old[i]!r}, build does not write it")
        for j in rest_new:
            out.append(f"{name} line {i1 + 1}: missing, build writes {new[j]!r}")
    if len(out) > limit:
        out = [*out[:limit], f"{name}: ... and {len(out) - limit} more differences"]
    return out


def check(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    n_resamples: int | None = None,
) -> list[str]:
    """Everything that is wrong with the leaderboard folder, one line each (empty: all good).

    Entry problems (metadata, data hashes, predictions) come first; when there are
    none, the committed ``LEADERBOARD.md`` and ``leaderboard.json`` are compared with
    what ``build`` would write now. The plot is not compared.
    """
    root = Path(root)
    try:
        built = build(root, data_dir, original, n_resamples=n_resamples)
    except ValidationError as e:
        return e.problems or [e.message]
    problems = []
    for name, text, differ in (
        (MARKDOWN, built.markdown, diff_markdown),
        (JSON_FILE, built.json_text, diff_json),
    ):
        path = root / name
        if not path.is_file():
            problems.append(f"{name} is missing; run `odmd-bench leaderboard build`")
            continue
        committed = path.read_text(encoding="utf-8")
        if committed != text:
            found = differ(committed, text, name)
            problems.extend(found or [f"{name}: differs from what build writes (whitespace or line ends)"])
    return problems


# ----------------------------------------------------------------------------- add


def _gzip_bytes(data: bytes) -> bytes:
    import io

    buf = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0, compresslevel=9) as gz:
        gz.write(data)
    return buf.getvalue()


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
    """Make an entry folder from a predictions CSV: validate it against the current sets,
    record their content hashes, store the predictions gzip-compressed, write entry.yaml.

    Raises
    ------
    ValidationError
        When the predictions or the metadata are not acceptable (nothing is written).
    UsageError
        When the entry exists and ``replace`` is false.
    """
    import yaml

    root = Path(root)
    folder = root / ENTRIES / method / f"{benchmark}-{split}"
    if folder.exists() and not replace:
        raise UsageError(f"{folder} already exists; pass --replace to overwrite it")
    examples = load_board_data(benchmark, split, data_dir, original)
    meta: dict[str, Any] = {
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
    data = Path(predictions).read_bytes()
    with tempfile.TemporaryDirectory(prefix="odmd-leaderboard-add-") as tmp:
        staged = Path(tmp) / method / f"{benchmark}-{split}"
        staged.mkdir(parents=True)
        (staged / "predictions.csv.gz").write_bytes(_gzip_bytes(data))
        (staged / "entry.yaml").write_text(
            yaml.safe_dump(meta, sort_keys=False, allow_unicode=True, width=100)
        )
        entry = read_entry(staged, root.parent)
        score_entry(entry, examples)
        folder.mkdir(parents=True, exist_ok=True)
        for f in ("predictions.csv.gz", "entry.yaml"):
            with atomic_write(folder / f, "wb") as fh:
                fh.write((staged / f).read_bytes())
    return read_entry(folder, root.parent)
