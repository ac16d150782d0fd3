"""``leaderboard audit``: every runnable entry re-run on fresh draws of the generated test sets.

The Normal, Camera and Object sets of ``odmd-v1`` test come from a seeded generator, so a
fresh draw of the same distribution, with a seed nobody tuned on, shows whether an
entry's committed test score holds (the Robot sets are real recordings and are left
out). :func:`audit` draws the fresh sets (:func:`fresh_sets`), re-runs every entry whose
``command`` is ``odmd-bench baseline NAME ...`` of an installed method with its recorded
options (:mod:`~odmd_bench.leaderboard.audit_targets`), and compares the committed
per-example percent errors with the fresh ones: the test, Holm's correction and the flags
are :mod:`~odmd_bench.leaderboard.audit_stats`'s, the text table
:mod:`~odmd_bench.leaderboard.audit_table`'s, the recorded files
:mod:`~odmd_bench.leaderboard.audit_files`'.

Everything is seeded by the audit's seed: the same seed gives the same JSON.
"""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import OdmdError, UsageError, ValidationError
from odmd_bench.evaluation.resampling import holm, holm_permutations, permutation_pvalues
from odmd_bench.leaderboard.audit_files import audit_json, command_method, shipped
from odmd_bench.leaderboard.audit_stats import (
    BOOTSTRAP,
    CONFIDENCE,
    LEVEL,
    Collected,
    assess_with,
    bootstrap_intervals,
    describe_test,
    flagged,
    n_tests,
)
from odmd_bench.leaderboard.audit_table import audit_table
from odmd_bench.leaderboard.audit_targets import (
    BENCHMARK,
    SPLIT,
    Target,
    parse_command,
    rerun,
    resolve_target,
)
from odmd_bench.leaderboard.entry import Entry

#: Fresh draws per set by default, pooled. Every audit of a board meets the same committed
#: draw, which lies by chance some way from each entry's true mean; one fresh draw adds as
#: much noise again, so an honest entry that the committed draw happens to favour was
#: flagged whenever its fresh draw fell the other way (leaderboard/README.md, "Rates
#: measured"). Five draws cut the fresh side's noise to sqrt(1/5) of the committed
#: side's, and raise the power.
REPEATS = 5
#: Fewest permutations per test; more where the Holm threshold needs smaller p-values.
PERMUTATIONS = 9_999
#: The largest seed (the seeds are stored in JSON, read by any language as a double).
MAX_SEED = 2**53


def check_seed(seed: object, what: str = "seed") -> int:
    """``seed`` if it is an integer in ``[0, 2**53]``, else a :class:`UsageError`."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed <= MAX_SEED:
        raise UsageError(f"{what} must be an integer from 0 to 2**53, got {seed!r}")
    return int(seed)


def fresh_seed(seed: int, repeat: int, set_index: int) -> int:
    """The generator seed of fresh set ``set_index`` (in the board's order) of draw ``repeat``.

    Derived by ``numpy.random.SeedSequence``, the same on every machine.

    Example:
        >>> fresh_seed(7, 0, 0) == fresh_seed(7, 0, 0) != fresh_seed(7, 0, 1)
        True
    """
    sequence = np.random.SeedSequence(check_seed(seed), spawn_key=(repeat, set_index))
    return int(sequence.generate_state(1, np.uint64)[0])


def generated_sets(benchmark: str = BENCHMARK, split: str = SPLIT) -> dict[str, dict[str, Any]]:
    """``{set: manifest entry}`` of the sets of ``benchmark`` ``split`` made by the generator."""
    from odmd_bench.data.manifests import manifest
    from odmd_bench.data.registry import get_benchmark

    pins = manifest(get_benchmark(benchmark))["splits"][split]
    return {s: dict(p) for s, p in pins.items() if p.get("kind") == "generated"}


def fresh_sets(
    seed: int, repeats: int = REPEATS, size: int | None = None, benchmark: str = BENCHMARK
) -> dict[str, list[Examples]]:
    """Fresh draws of the generated test sets: ``{set: [examples of each repeat]}``.

    Each set is drawn with the generator version, preset and perturbation of the committed
    set, ``size`` examples (default: as many as the committed set) and the seed
    :func:`fresh_seed` derives; its ``attrs`` are those of a loaded set (``benchmark``,
    ``split``, ``set``, ``content_sha256``, ...), so that a method cannot tell it apart by
    them. Nothing is written.

    Raises:
        UsageError: a bad seed, repeat count or size.
        DataError: the package's generator is not the version the benchmark pins.
    """
    from odmd_bench.data.generator import GENERATOR_VERSION, generate
    from odmd_bench.data.hashing import content_sha256, group_attrs, set_arrays
    from odmd_bench.errors import DataError

    check_seed(seed)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise UsageError(f"repeats must be a positive integer, got {repeats!r}")
    if size is not None and (isinstance(size, bool) or not isinstance(size, int) or size < 1):
        raise UsageError(f"size must be a positive integer, got {size!r}")
    out: dict[str, list[Examples]] = {}
    for index, (name, pin) in enumerate(generated_sets(benchmark).items()):
        if pin["generator_version"] != GENERATOR_VERSION:
            raise DataError(
                f"{benchmark} {SPLIT} {name} needs generator version {pin['generator_version']}, "
                f"this package has version {GENERATOR_VERSION}"
            )
        draws = []
        for r in range(repeats):
            s = fresh_seed(seed, r, index)
            ex = generate(size or int(pin["n"]), pin["preset"], pin["perturbation"], rng=s)
            ex.attrs.update(source="generator", seed=s, preset=pin["preset"])
            ex.attrs.update(benchmark=benchmark, split=SPLIT, set=name)
            ex.attrs.update(group_attrs(ex, name, content_sha256(set_arrays(ex))))
            draws.append(ex)
        out[name] = draws
    return out


def permutations_for(tests: int, level: float = LEVEL) -> int:
    """Permutations per test: at least :data:`PERMUTATIONS`, and enough for Holm.

    The smallest p-value, ``1 / (B + 1)``, is at most 40% of Holm's smallest threshold
    ``level / tests`` (:func:`~odmd_bench.evaluation.resampling.holm_permutations`).

    Example:
        >>> permutations_for(40), permutations_for(1000)
        (9999, 249999)
    """
    return max(PERMUTATIONS, holm_permutations(tests, level))


def board_entries(root: str | os.PathLike[str], benchmark: str = BENCHMARK) -> list[Entry]:
    """The entries of the audited board, by method id.

    Raises:
        ValidationError: an entry cannot be read (every problem named).
    """
    from odmd_bench.leaderboard.files import discover, read_entry

    root = Path(root)
    entries, problems = [], []
    for folder in discover(root):
        if folder.name != f"{benchmark}-{SPLIT}":
            continue
        try:
            entries.append(read_entry(folder, root.parent))
        except ValidationError as e:
            problems += [f"{e.message}: {p}" for p in e.problems] or [e.message]
    if problems:
        raise ValidationError("the board cannot be audited; run `odmd-bench leaderboard check`", problems)
    return sorted(entries, key=lambda e: e.method)


def audit(
    root: str | os.PathLike[str],
    seed: int,
    *,
    repeats: int = REPEATS,
    size: int | None = None,
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    only: Iterable[str] | None = None,
    date: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Audit the ``odmd-v1`` test board under ``root`` with fresh sets drawn from ``seed``.

    Args:
        root: the leaderboard folder.
        seed: the audit's seed (fresh sets, permutations, bootstrap).
        repeats: fresh draws per set, pooled (default :data:`REPEATS`).
        size: examples per fresh set (default: as many as the committed set).
        data_dir: the data folder (the committed sets; generated if missing).
        original: the original release's folder (weights written ``ODMD/...``).
        only: audit these entries (method ids) alone; default: every entry of the board.
        date: recorded as ``date`` (default: today, UTC).
        progress: called with a line per step.

    Returns:
        The audit as JSON-ready data (see leaderboard/README.md).

    Raises:
        UsageError: a bad seed, repeats, size, or an unknown entry in ``only``.
        ValidationError: an entry cannot be read or scored.
    """
    found = collect_errors(
        root,
        seed,
        repeats=repeats,
        size=size,
        data_dir=data_dir,
        original=original,
        only=only,
        date=date,
        progress=progress,
    )
    return assess(found, progress=progress)


def collect_errors(
    root: str | os.PathLike[str],
    seed: int,
    *,
    repeats: int = REPEATS,
    size: int | None = None,
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    only: Iterable[str] | None = None,
    date: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> Collected:
    """The first half of :func:`audit` (same arguments): score, draw, re-run; no test yet."""
    from odmd_bench.leaderboard.board import load_board_data, score_entry

    say = progress or (lambda _line: None)
    seed = check_seed(seed)
    fresh = fresh_sets(seed, repeats, size)
    sets = list(fresh)
    entries = board_entries(root, BENCHMARK)
    if only is not None:
        wanted = list(only)
        unknown = sorted(set(wanted) - {e.method for e in entries})
        if unknown:
            raise UsageError(f"no entry {', '.join(unknown)} on the {BENCHMARK} {SPLIT} board")
        entries = [e for e in entries if e.method in wanted]
    examples = load_board_data(BENCHMARK, SPLIT, data_dir, original) if entries else {}
    repo = Path(root).resolve().parent
    rows: list[dict[str, Any]] = []
    committed: dict[str, list[np.ndarray]] = {s: [] for s in sets}
    rerun_errors: dict[str, list[np.ndarray]] = {s: [] for s in sets}
    audited: list[int] = []
    own: set[str] = set()
    for entry in entries:
        result = score_entry(entry, examples)
        row: dict[str, Any] = {
            "method": entry.method,
            "name": entry.meta.name,
            "command": entry.meta.command,
            "predictions_csv_sha256": result.provenance["predictions_sha256"],
            "runnable": False,
            "reason": None,
            "sets": {},
            "generated_mean": None,
            "flagged": None,
        }
        rows.append(row)
        if shipped(entry) is not None:
            own.add(entry.method)
        target = resolve_target(entry, repo, original)
        if target.reason is None:
            say(f"re-running {entry.method} ({target.name}) on the fresh sets")
            try:
                errors = rerun(target, fresh)
            except OdmdError as e:
                target = Target(entry, reason=f"failed: {e.message}")
        if target.reason is not None:
            row["reason"] = target.reason
            say(
                f"{'' if target.reason.startswith('failed: ') else 'not audited: '}{entry.method}: {target.reason}"
            )
            continue
        row["runnable"] = True
        audited.append(len(rows) - 1)
        errs = result.percent_errors()
        for s in sets:
            committed[s].append(errs[s])
            rerun_errors[s].append(errors[s])
    header = {
        "generated_by": "odmd-bench leaderboard audit",
        "seed": seed,
        "benchmark": BENCHMARK,
        "split": SPLIT,
        "date": date or _dt.datetime.now(_dt.timezone.utc).date().isoformat(),
        "repeats": repeats,
        "sets": {s: len(fresh[s][0]) for s in sets},
        "fresh_seeds": {s: [int(ex.attrs["seed"]) for ex in fresh[s]] for s in sets},
    }
    empty = np.zeros((0, 0))
    c = {s: np.column_stack(committed[s]) if audited else empty for s in sets}
    f = {s: np.column_stack(rerun_errors[s]) if audited else empty for s in sets}
    return Collected(header, rows, audited, c, f, frozenset(own))


def assess(found: Collected, *, progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """The second half of :func:`audit`: the test, the intervals, Holm, the flags; the audit's data.

    ``found.committed`` may be changed before (a planted advantage, to measure the test's power).
    The test is :func:`~odmd_bench.leaderboard.audit_stats.assess_with`'s, with
    :func:`permutations_for` permutations per test.
    """
    return assess_with(found, permutations_for(n_tests(found)), progress=progress)


def record_problems(root: str | os.PathLike[str], result: Mapping[str, Any]) -> list[str]:
    """Why ``result`` must not be recorded (``audit --record``): empty when it may.

    An audit recorded in a partial environment must not replace a re-run with "not
    re-run": an entry of a method shipped in this repository that was not re-run, or an
    entry that a recorded audit re-ran and this one could not, refuses the record (a
    contributor's plug-in that is not installed, and was never audited, is recorded as
    not audited). So does an audit of some entries (``--only``) over a recorded file of
    the same seed that holds others (their audit would be lost).
    """
    from odmd_bench.leaderboard.audit_files import audit_path, read_audits

    entries = {e.method: e for e in board_entries(root)}
    recorded, _ = read_audits(root)
    before = {e["method"]: d["seed"] for d in recorded for e in d["entries"] if e["runnable"]}
    problems = []
    for row in result["entries"]:
        if row["runnable"]:
            continue
        method = shipped(entries[row["method"]]) if row["method"] in entries else None
        if method is not None:
            problems.append(
                f"entry {row['method']} runs {method}, shipped in this repository, and was not re-run here: "
                f"{row['reason']}"
            )
        elif row["method"] in before:
            problems.append(
                f"entry {row['method']} was re-run by audits/{before[row['method']]}.json and not here: "
                f"{row['reason']}"
            )
    path = audit_path(root, int(result["seed"]))
    same = next((d for d in recorded if d["seed"] == result["seed"]), None)
    if same is not None:
        dropped = sorted({e["method"] for e in same["entries"]} - {e["method"] for e in result["entries"]})
        if dropped:
            problems.append(
                f"{path.name} holds entries this audit leaves out ({', '.join(dropped)}): recording would drop "
                "their audit; audit them too (no --only) or use another seed"
            )
    return problems


# The names of the audit's other rooms (and of the engine) are importable from here, as before.
__all__ = [
    "BENCHMARK",
    "BOOTSTRAP",
    "CONFIDENCE",
    "LEVEL",
    "PERMUTATIONS",
    "REPEATS",
    "SPLIT",
    "Target",
    "Collected",
    "assess",
    "audit",
    "audit_json",
    "audit_table",
    "board_entries",
    "bootstrap_intervals",
    "check_seed",
    "collect_errors",
    "command_method",
    "describe_test",
    "flagged",
    "fresh_seed",
    "fresh_sets",
    "generated_sets",
    "holm",
    "parse_command",
    "permutation_pvalues",
    "permutations_for",
    "record_problems",
    "rerun",
    "resolve_target",
    "shipped",
]
