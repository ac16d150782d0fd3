"""Scoring: each board's sets loaded once, every entry re-scored by the evaluator and ranked.

:func:`score_csv` is the one place that calls the evaluator.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.errors import DataError, OdmdError, ValidationError
from odmd_bench.evaluation.compare import PairedDifference
from odmd_bench.evaluation.resampling import SharedDraws
from odmd_bench.evaluation.scoring import EvaluationResult
from odmd_bench.leaderboard.entry import Entry
from odmd_bench.leaderboard.files import discover, read_entry, read_predictions_bytes
from odmd_bench.leaderboard.ranking import rank_groups
from odmd_bench.leaderboard.specs import BOARDS, BoardSpec


@dataclass(frozen=True)
class Row:
    """A re-scored entry on its board.

    Attributes:
        entry: the entry.
        result: the evaluator's result (sets, All, provenance, per-example errors).
        group: rank group (1 is best).
        leader: method id of the group's leader (itself for the leader).
        versus_leader, versus_previous: as in :class:`~odmd_bench.leaderboard.ranking.Ranked`.
    """

    entry: Entry
    result: EvaluationResult
    group: int = 0
    leader: str = ""
    versus_leader: PairedDifference | None = None
    versus_previous: PairedDifference | None = None


@dataclass(frozen=True)
class Board:
    """The ranked rows of one board; a board without entries has no rows and no data."""

    spec: BoardSpec
    sets_content_sha256: dict[str, str]
    data_version: str
    rows: tuple[Row, ...]

    @property
    def benchmark(self) -> str:
        """The board's benchmark."""
        return self.spec.benchmark

    @property
    def split(self) -> str:
        """The board's split."""
        return self.spec.split

    @property
    def sets(self) -> tuple[str, ...]:
        """The board's sets, in column order."""
        return self.spec.sets


def data_version(examples: Mapping[str, Examples]) -> str:
    """How the sets were made, e.g. ``generator v1 + imported robot``, ``original release`` or ``KITTI windows, rules v1``."""
    parts = []
    gens = sorted(
        {int(ex.attrs["generator_version"]) for ex in examples.values() if "generator_version" in ex.attrs}
    )
    if gens:
        parts.append("generator " + ", ".join(f"v{g}" for g in gens))
    rules = sorted(
        {int(ex.attrs["rules_version"]) for ex in examples.values() if "rules_version" in ex.attrs}
    )
    if rules:  # kitti-tracking: windows cut from KITTI by versioned rules (odmd_bench.kitti.windows)
        parts.append("KITTI windows, rules " + ", ".join(f"v{r}" for r in rules))
    imported = [
        s
        for s, ex in examples.items()
        if "generator_version" not in ex.attrs and "rules_version" not in ex.attrs
    ]
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
    """The sets of a board, built or rebuilt where they are missing or stale.

    A generated benchmark is (re)generated where its file is missing or not right
    (:func:`~odmd_bench.data.store.ensure_generated` reuses a right file); an imported
    one is imported from ``original`` (the original release's folder), when given,
    where its file is missing or cannot be loaded as it is (an older file format, a
    damaged file). What is loaded is always verified.
    """
    from odmd_bench.data.importer import import_release
    from odmd_bench.data.store import ensure_generated, load_split

    b = get_benchmark(benchmark)
    if b.generated:
        ensure_generated(b, (split,), data_dir)
        return load_split(split, b, data_dir)
    if original is not None and not set_file(b, split, data_dir).exists():
        import_release(original, data_dir, benchmark=benchmark)
    try:
        return load_split(split, b, data_dir)
    except DataError as e:
        if original is None:
            raise DataError(
                e.message + " (or give the leaderboard command --original PATH, or set ODMD_ORIGINAL)",
                e.problems,
            ) from None
    import_release(original, data_dir, benchmark=benchmark)  # rebuilds what could not be loaded
    return load_split(split, b, data_dir)


def score_predictions(data: bytes, entry: Entry, examples: Mapping[str, Examples]) -> EvaluationResult:
    """Validate and score an entry's predictions (the CSV's bytes) against its sets.

    Raises:
        ValidationError: When the file fails the evaluator's validation, or holds
            another split than the entry's.
    """
    return score_csv(
        data,
        examples,
        key=entry.key,
        file_name=entry.predictions.name,
        benchmark=entry.benchmark,
        split=entry.split,
    )


def score_csv(
    data: bytes, examples: Mapping[str, Examples], *, key: str, file_name: str, benchmark: str, split: str
) -> EvaluationResult:
    """Validate and score predictions (the CSV's bytes) of the entry ``key`` against its sets.

    This is the one call into the evaluator (``add`` scores a file with it before the
    entry's metadata exists).

    Raises:
        ValidationError: When the file fails the evaluator's validation, or holds
            another split than ``split``.
    """
    from odmd_bench.evaluation.coverage import check_coverage
    from odmd_bench.evaluation.parse import parse_predictions
    from odmd_bench.evaluation.scoring import score

    title = f"entry {key}: {file_name} fails validation"
    name = file_name.removesuffix(".gz")
    try:
        parsed = parse_predictions(data, name=name, benchmark=benchmark, strict=False)
    except ValidationError as e:
        raise ValidationError(title, e.problems or [e.message]) from None
    if parsed.split is not None and parsed.split != split:
        wrong = f"the file holds split {parsed.split!r} but the entry is for {split!r}"
        raise ValidationError(title, [wrong, *parsed.problems.lines()])
    try:
        preds = check_coverage(parsed, {s: len(ex) for s, ex in examples.items()}, board=True)
    except ValidationError as e:
        raise ValidationError(title, e.problems or [e.message]) from None
    return score(preds, examples)


def score_entry(entry: Entry, examples: Mapping[str, Examples]) -> EvaluationResult:
    """Check that the sets are those the entry was made for, then score its predictions.

    Raises:
        ValidationError: When the sets' content hashes differ from the entry's, or the
            predictions cannot be read or fail validation.
    """
    problems = []
    recorded = entry.meta.sets_content_sha256
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
    return score_predictions(read_predictions_bytes(entry.predictions), entry, examples)


def _problem_lines(err: OdmdError) -> list[str]:
    """One line per problem, each saying which entry it is of (so that they count right)."""
    return [f"{err.message}: {p}" for p in err.problems] or [err.message]


def _duplicates(spec: BoardSpec, scored: dict[str, tuple[Entry, EvaluationResult]]) -> list[str]:
    """Drop from ``scored`` each entry whose name an earlier one has; a problem line for each.

    Two rows of one name could not be told apart. (Identical estimates on every set are
    refused as a copy by :func:`_copies`.)
    """
    problems = []
    seen: dict[str, Entry] = {}
    for method, (entry, _) in list(scored.items()):
        other = seen.setdefault(entry.meta.name, entry)
        if other is not entry:
            problems.append(name_clash(spec, entry, other))
            del scored[method]
    return problems


def name_clash(spec: BoardSpec, entry: Entry, other: Entry) -> str:
    """The problem of two entries of one board with one name (``build`` and ``add`` alike)."""
    return f"{entry.key}: has the name {entry.meta.name!r} of {other.key} on {spec.key}; rename one of them"


#: Estimates this close (relative, on every example) are the same: a method run again
#: elsewhere differs in the last bits (about 1e-14 for Box_LS), never by this much.
SAME_RTOL = 1e-9


def same_predictions(a: EvaluationResult, b: EvaluationResult, sets: tuple[str, ...]) -> bool:
    """Whether two results hold the same estimates on every one of ``sets`` (to :data:`SAME_RTOL`)."""
    return all(
        np.allclose(a.predictions[s], b.predictions[s], rtol=SAME_RTOL, atol=0.0, equal_nan=True)
        for s in sets
    )


def _copies(spec: BoardSpec, scored: dict[str, tuple[Entry, EvaluationResult]]) -> list[str]:
    """Drop from ``scored`` each entry whose predictions an earlier entry has on every set.

    A copy is not a new result, and with equal scores it could take the original's place
    (ties are broken by method id). Which is the copy cannot be known from the files, so
    the problem names both (and fails ``check``); the board keeps the earlier date (then
    the lower method id).
    """
    problems = []
    kept: list[tuple[Entry, EvaluationResult]] = []
    for method, (entry, result) in sorted(scored.items(), key=lambda kv: (kv[1][0].meta.date, kv[0])):
        first = next((other for other, theirs in kept if same_predictions(result, theirs, spec.sets)), None)
        if first is None:
            kept.append((entry, result))
            continue
        problems.append(
            f"{first.key} and {entry.key} have the same predictions on every set of {spec.key}; "
            "a copy is not a new result: remove the copy"
        )
        del scored[method]
    return problems


def _score_board(
    spec: BoardSpec,
    entries: list[Entry],
    data_dir: str | os.PathLike[str] | None,
    original: str | os.PathLike[str] | None,
    n_resamples: int | None,
    draws: SharedDraws,
) -> tuple[Board | None, list[str]]:
    """One board from its entries (an empty board needs no data)."""
    if not entries:
        return Board(spec, {}, "", ()), []
    try:
        examples = load_board_data(spec.benchmark, spec.split, data_dir, original)
    except OdmdError as err:
        keys = ", ".join(e.key for e in entries)
        return None, [f"{spec.key} ({keys}): data cannot be loaded: {err.render()}"]
    problems: list[str] = []
    scored: dict[str, tuple[Entry, EvaluationResult]] = {}
    for e in entries:
        try:
            scored[e.method] = (e, score_entry(e, examples))
        except ValidationError as err:
            problems += _problem_lines(err)
    problems += _duplicates(spec, scored)
    problems += _copies(spec, scored)
    if not scored:
        return None, problems
    errors = {m: r.percent_errors() for m, (_, r) in scored.items()}
    ranked = rank_groups(errors, n_resamples=n_resamples, draws=draws)
    rows = tuple(Row(*scored[x.key], x.group, x.leader, x.versus_leader, x.versus_previous) for x in ranked)
    hashes = {s: str(ex.attrs["content_sha256"]) for s, ex in examples.items()}
    return Board(spec, hashes, data_version(examples), rows), problems


def _progress_line(spec: BoardSpec, n: int, n_problems: int, seconds: float) -> str:
    """E.g. ``odmd-v1 test: 10 entries re-scored and ranked (0.4 s)``."""
    if n == 0:
        return f"{spec.key}: no entries"
    entries = f"{n} {'entry' if n == 1 else 'entries'}"
    if n_problems:
        return f"{spec.key}: {entries} re-scored, {n_problems} {'problem' if n_problems == 1 else 'problems'} ({seconds:.1f} s)"
    return f"{spec.key}: {entries} re-scored and ranked ({seconds:.1f} s)"


def collect(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    n_resamples: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[Board], list[str]]:
    """Read, validate, score and rank every entry under ``root``.

    ``progress``, when given, is called with one line per board once it is done (what
    was scored, how long it took): the command line prints it on standard error.

    Returns:
        ``(boards, problems)``: every board of :data:`~odmd_bench.leaderboard.specs.BOARDS`
        with the entries that passed, and one line per problem found (every entry is
        looked at; nothing stops at the first problem).
    """
    root = Path(root)
    problems: list[str] = []
    entries: list[Entry] = []
    for folder in discover(root):
        try:
            entries.append(read_entry(folder, root.parent))
        except ValidationError as err:
            problems += _problem_lines(err)
    boards: list[Board] = []
    draws = SharedDraws()  # boards of the same sets rank on the same draws: made once
    for spec in BOARDS:
        mine = [e for e in entries if (e.benchmark, e.split) == (spec.benchmark, spec.split)]
        start = time.perf_counter()
        board, found = _score_board(spec, mine, data_dir, original, n_resamples, draws)
        problems += found
        if progress is not None:
            progress(_progress_line(spec, len(mine), len(found), time.perf_counter() - start))
        if board is not None:
            boards.append(board)
    return boards, problems
