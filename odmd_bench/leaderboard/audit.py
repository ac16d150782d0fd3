"""``leaderboard audit``: every runnable entry re-run on fresh draws of the generated test sets.

The Normal, Camera and Object sets of ``odmd-v1`` test come from a seeded generator, so a
fresh draw of the same distribution, with a seed nobody tuned on, shows whether an
entry's committed test score holds (the Robot sets are real recordings and are left
out). :func:`audit` draws the fresh sets (:func:`fresh_sets`), re-runs every entry whose
``command`` is ``odmd-bench baseline NAME ...`` of an installed method with its recorded
options (:func:`parse_command`), and compares the committed per-example percent errors
with the fresh ones.

The test (docs: leaderboard/README.md, "Is a method tuned on the test set?"): for each
entry and set, the statistic is ``fresh mean - committed mean`` (positive: the committed
score is the better one). Under the null hypothesis, the method did not use the test set,
so its per-example errors on the committed set and on the fresh draws are exchangeable
(independent examples of one distribution, each estimated on its own); the one-sided
p-value is that of a permutation test, ``(1 + #{T* >= T}) / (B + 1)`` over ``B`` random
relabellings of the pooled errors, which is exact whatever the errors' distribution
(heavy tails included). ``generated_mean`` is the mean of the three sets' statistics,
permuted within each set (stratified): the mean over the *generated* sets only, not the
board's All (which includes Robot). The p-values of every entry and test (three sets and
``generated_mean``) are
corrected together by Holm's method; an entry is **flagged** when one of its adjusted
p-values is at most :data:`LEVEL`. So an audit of honest entries flags any of them with
probability at most :data:`LEVEL` over the draws of the committed and the fresh sets
(audits of one board share its committed draw, so they are not independent trials).

Everything is seeded by the audit's seed: the same seed gives the same JSON.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import OdmdError, UsageError, ValidationError
from odmd_bench.leaderboard.audit_files import audit_json, command_method, shipped
from odmd_bench.leaderboard.entry import Entry
from odmd_bench.leaderboard.specs import SET_TITLES
from odmd_bench.leaderboard.specs import rounded as _r

if TYPE_CHECKING:
    from odmd_bench.methods import Method

#: The board audited: its generated sets are drawn afresh.
BENCHMARK = "odmd-v1"
SPLIT = "test"
#: Family-wise level: the chance that an audit flags any honest entry is at most this.
LEVEL = 0.01
#: Fresh draws per set by default, pooled. Every audit of a board meets the same committed
#: draw, which lies by chance some way from each entry's true mean; one fresh draw adds as
#: much noise again, so an honest entry that the committed draw happens to favour was
#: flagged whenever its fresh draw fell the other way (leaderboard/README.md, "Rates
#: measured"). Five draws cut the fresh side's noise to sqrt(1/5) of the committed
#: side's, and raise the power.
REPEATS = 5
#: Fewest permutations per test; more where the Holm threshold needs smaller p-values.
PERMUTATIONS = 9_999
#: Bootstrap resamples of the fresh means' intervals, and their confidence.
BOOTSTRAP = 2_000
CONFIDENCE = 0.95
#: Permutations (rows) drawn at once: bounds the memory to about 50 MB.
CHUNK = 1_000
#: How an entry's command names the user's copy of the original release.
RELEASE_PLACEHOLDER = "ODMD/"
#: The method options of a command the audit re-runs where an entry records no ``options``.
_METHOD_OPTIONS = ("--weights", "--weights-sha256", "--config", "--selection", "--mode")
#: Spawn keys of the audit's random streams (fresh sets: (repeat, set); statistics: these).
_PERMUTATION_KEY = 1_000_001
_BOOTSTRAP_KEY = 1_000_002
#: How the table labels the mean over the generated sets (JSON: ``generated_mean``).
MEAN_LABEL = "N+C+O"
#: The largest seed (the seeds are stored in JSON, read by any language as a double).
MAX_SEED = 2**53


@dataclass(frozen=True)
class Target:
    """An entry and how it is re-run.

    Attributes:
        entry: the entry.
        name: the method its command runs ("" when it cannot be re-run).
        options: the method's recorded options (``weights`` resolved to a path).
        reason: why it cannot be re-run, or None; ``failed: ...`` where the method failed.
        method: the loaded method (None when it cannot be re-run).
    """

    entry: Entry
    name: str = ""
    options: dict[str, Any] = field(default_factory=dict)
    reason: str | None = None
    method: Method | None = None


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


def parse_command(command: str, benchmark: str = BENCHMARK) -> tuple[str, dict[str, str]]:
    """The method and options of an ``odmd-bench baseline NAME ...`` command.

    A note in parentheses at the end of the command is dropped. Options are written
    ``--opt VALUE`` or ``--opt=VALUE``; ``-o``, ``--output`` and ``--data-dir`` are
    dropped (the audit writes nothing and draws its own sets).

    Returns:
        ``(NAME, {option: value})``, options by their keyword (``weights_sha256``).

    Raises:
        ValueError: the reason the command cannot be re-run, in words.

    Example:
        >>> parse_command("odmd-bench baseline dbox --config p-z --split test -o p.csv")
        ('dbox', {'config': 'p-z'})
    """
    from odmd_bench.methods import parse_command as read_command

    name, options, own = read_command(command)  # (its words read as every recorded command is)
    unknown = [o for o in options if "--" + o.replace("_", "-") not in _METHOD_OPTIONS]
    if unknown:
        raise ValueError(
            f"its command has an option the audit does not know: --{unknown[0].replace('_', '-')}"
        )
    if own.get("--benchmark", "odmd-v1") != benchmark:
        raise ValueError(f"its command runs on benchmark {own['--benchmark']}, not {benchmark}")
    if own.get("--split", "test") != SPLIT:
        raise ValueError(f"its command runs on split {own['--split']}, not {SPLIT}")
    return name, options


def resolve_target(entry: Entry, repo: Path, original: str | os.PathLike[str] | None = None) -> Target:
    """How ``entry`` is re-run, or why it cannot be.

    The method is the entry's ``plugin`` where it has one (``{source, module}``: the
    module loaded from the entry folder; ``{requirement: NAME==VERSION}``: that version
    must be installed, nothing is installed here), else the method its command names. Its
    options are the entry's recorded ``options``, else those of its command
    (:func:`parse_command`). A relative ``weights`` path is resolved in the repository
    (``repo``), or, written ``ODMD/...``, in the original release's folder ``original``.
    A plug-in that exits, raises or prints while it loads is contained: the reason says so.
    """
    from odmd_bench import methods

    plugin = getattr(entry.meta, "plugin", None)
    recorded = getattr(entry.meta, "options", None)
    try:
        if recorded is not None:
            name, given = command_method(entry.meta.command), dict(recorded)
        else:
            name, given = parse_command(entry.meta.command, entry.benchmark)
    except ValueError as e:
        if recorded is None or plugin is None or "module" not in plugin:
            return Target(entry, reason=str(e))
        # a plug-in named by its module, run with its recorded options: the command is not needed
        name, given = entry.method, dict(recorded)
    options: dict[str, Any] = dict(given)
    try:
        with methods.output_to_stderr():
            method = _load_method(entry, name, plugin)
    except UsageError as e:
        return Target(entry, reason=f"method {name!r} cannot be loaded: {e.message}")
    except (KeyboardInterrupt, OdmdError):
        raise
    except BaseException as e:  # a plug-in's import ran sys.exit, ran out of memory, ...
        return Target(entry, reason=f"failed: loading method {name!r} raised {type(e).__name__}: {e}"[:500])
    if isinstance(method, str):
        return Target(entry, reason=method)
    refused = [k for k in options if not method.accepts(k)]
    if refused:
        return Target(entry, reason=f"method {name!r} takes no option {', '.join(refused)}")
    if isinstance(options.get("weights"), str):
        text = options["weights"]
        if text.startswith(RELEASE_PLACEHOLDER):
            if original is None:
                return Target(
                    entry,
                    reason=f"its weights {text} are a file of the original release: give --original "
                    "(or set ODMD_ORIGINAL)",
                )
            path = Path(original) / text[len(RELEASE_PLACEHOLDER) :]
        else:
            path = Path(text) if Path(text).is_absolute() else repo / text
        if not path.is_file():
            return Target(entry, reason=f"its weights are not found: {path}")
        options["weights"] = path
    return Target(entry, name=name, options=options, method=method)


def _load_method(entry: Entry, name: str, plugin: Mapping[str, str] | None) -> Any:
    """The method of ``entry`` (a :class:`~odmd_bench.methods.Method`), or why it cannot be loaded (text)."""
    from importlib import metadata

    from odmd_bench import methods

    if plugin is None:
        return methods.load(name)
    if "requirement" in plugin:
        dist, _, version = plugin["requirement"].partition("==")
        try:
            installed = metadata.version(dist)
        except metadata.PackageNotFoundError:
            return f"its plug-in is not installed here (pip install {plugin['requirement']})"
        if installed != version:
            return (
                f"its plug-in {dist} {installed} is installed here, the entry needs {plugin['requirement']}"
            )
        if "module" not in plugin:
            return methods.load(name)
        return methods.load_module(name, plugin["module"], f"{dist} {installed}")
    folder = entry.folder / plugin["source"]
    if not folder.is_dir() or folder.is_symlink():
        return f"its plug-in source {plugin['source']}/ is not a folder in the entry folder"
    return methods.load_module(name, plugin["module"], f"the plug-in source of entry {entry.key}", folder)


def rerun(target: Target, fresh: Mapping[str, Sequence[Examples]]) -> dict[str, np.ndarray]:
    """Per-example percent errors of ``target`` on each fresh set, its repeats concatenated.

    Each call is contained (:func:`~odmd_bench.methods.run_contained`): its standard
    output goes to standard error, and a plug-in that exits or raises anything becomes
    a :class:`~odmd_bench.errors.MethodError`. The method gets its own read-only copy of
    each set (:meth:`~odmd_bench.data.examples.Examples.without_truth`), so it cannot change
    the sets the next entry is run on.

    Raises:
        OdmdError: the method refused to run or failed (a missing module, weights failing
            their hash, a plug-in's exception); :func:`audit` records it as the reason.
    """
    from odmd_bench import methods
    from odmd_bench.evaluation.metrics import percent_error

    method = target.method if target.method is not None else methods.load(target.name)
    out = {}
    for name, draws in fresh.items():
        parts = [
            percent_error(ex.depth, methods.run_contained(method, ex, **target.options)[0]) for ex in draws
        ]
        out[name] = np.concatenate(parts)
    return out


# ------------------------------------------------------------------------- statistics


def permutations_for(tests: int, level: float = LEVEL) -> int:
    """Permutations per test: at least :data:`PERMUTATIONS`, and enough for Holm.

    The smallest p-value, ``1 / (B + 1)``, is at most 40% of Holm's smallest threshold
    ``level / tests``.

    Example:
        >>> permutations_for(40), permutations_for(1000)
        (9999, 249999)
    """
    return max(PERMUTATIONS, math.ceil(2.5 * max(tests, 1) / level) - 1)


def permutation_pvalues(
    committed: Mapping[str, np.ndarray],
    fresh: Mapping[str, np.ndarray],
    rng: np.random.Generator,
    n_permutations: int,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """One-sided permutation p-values that the committed errors are smaller than the fresh ones.

    Args:
        committed: ``{set: (n, E)}`` per-example errors of E entries on the committed set.
        fresh: ``{set: (m, E)}`` the same entries' errors on the fresh draws.
        rng: the random stream (its draws do not depend on E).
        n_permutations: B.

    Returns:
        ``({set: (E,)}, (E,) for the mean over sets)``: ``(1 + #{T* >= T}) / (B + 1)``
        with ``T = mean(fresh) - mean(committed)``, the relabellings drawn within each set.

    When the fresh errors are ``K`` whole repeats of the committed set's size (``m = K n``,
    the audit's default), the relabellings are drawn within blocks: committed example
    ``i`` and example ``i`` of each repeat form a block, and a random one of its ``K + 1``
    members is labelled committed (for ``K = 1``, a sign flip of each pair's
    difference). Under the null hypothesis the pooled errors are exchangeable, so a
    relabelling from any fixed group of permutations keeps their distribution: the test
    is exact either way, and this one is several times faster to draw. Other sizes
    (``--size``) draw a uniformly random subset of the pooled errors.

    Example:
        >>> rng = np.random.default_rng(0)
        >>> c, f = {"a": np.zeros((50, 1))}, {"a": np.ones((50, 1))}
        >>> p, p_all = permutation_pvalues(c, f, rng, 999)
        >>> float(p["a"][0]), float(p_all[0])
        (0.001, 0.001)
    """
    counts, counts_all = _exceedances(committed, fresh, rng, n_permutations, (0.0,))
    p = {s: (1 + c[0]) / (n_permutations + 1) for s, c in counts.items()}
    return p, (1 + counts_all[0]) / (n_permutations + 1)


def _exceedances(
    committed: Mapping[str, np.ndarray],
    fresh: Mapping[str, np.ndarray],
    rng: np.random.Generator,
    n_permutations: int,
    shifts: Sequence[float | tuple[Mapping[str, np.ndarray], np.ndarray]],
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """``#{T* >= T + shift}`` for each shift: ``({set: (len(shifts), E)}, (len(shifts), E))``.

    A shift is ``0.0`` (the p-value's count) or ``({set: (E,)}, (E,) for the mean over
    sets)``; the relabellings are those :func:`permutation_pvalues` draws, whatever the shifts.
    """
    sets = list(committed)
    observed, pooled, totals, sizes = {}, {}, {}, {}
    for s in sets:
        c, f = np.asarray(committed[s], np.float64), np.asarray(fresh[s], np.float64)
        pooled[s] = np.concatenate([c, f])
        totals[s] = pooled[s].sum(axis=0)
        sizes[s] = (len(c), len(f))
        observed[s] = _statistic(c.sum(axis=0), totals[s], len(c), len(f))
    observed_all = np.mean([observed[s] for s in sets], axis=0)

    def threshold(s: str | None, shift: float | tuple[Mapping[str, np.ndarray], np.ndarray]) -> np.ndarray:
        t = observed_all if s is None else observed[s]
        by = shift if isinstance(shift, float) else (shift[1] if s is None else shift[0][s])
        return t + by - _tie(t)

    limits = {s: np.array([threshold(s, x) for x in shifts]) for s in sets}
    limits_all = np.array([threshold(None, x) for x in shifts])
    exceed = {s: np.zeros((len(shifts), len(observed[s])), np.int64) for s in sets}
    exceed_all = np.zeros((len(shifts), len(observed_all)), np.int64)
    done = 0
    while done < n_permutations:
        rows = min(CHUNK, n_permutations - done)
        stats = []
        for s in sets:
            n, m = sizes[s]
            if m % n == 0:
                committed_sum = _block_sums(pooled[s], n, m // n, rows, rng)
            else:
                # a uniformly random subset: the smaller group's positions drawn
                labels = np.zeros((rows, n + m))
                for row in labels:
                    row[rng.choice(n + m, min(n, m), replace=False)] = 1.0
                drawn = labels @ pooled[s]
                committed_sum = drawn if n <= m else totals[s] - drawn
            t = _statistic(np.asarray(committed_sum), totals[s], n, m)
            exceed[s] += (t[None] >= limits[s][:, None]).sum(axis=1)
            stats.append(t)
        t_all = np.mean(stats, axis=0)
        exceed_all += (t_all[None] >= limits_all[:, None]).sum(axis=1)
        done += rows
    return exceed, exceed_all


def _block_sums(pooled: np.ndarray, n: int, k: int, rows: int, rng: np.random.Generator) -> np.ndarray:
    """``(rows, E)`` committed-group sums, one random member of each block of ``k + 1`` labelled committed.

    Block ``i`` is ``pooled[i + j * n]`` for ``j = 0..k``. The sum is that of the last
    members plus, for each block whose pick ``j`` is not the last, ``x_j - x_k``.
    """
    blocks = pooled.reshape(k + 1, n, -1)
    out = np.broadcast_to(blocks[k].sum(axis=0), (rows, blocks.shape[2])).copy()
    if k == 1:  # a fair bit per block: whether the committed label stays on the committed example
        bits = rng.integers(0, 256, (rows, (n + 7) // 8), dtype=np.uint8)
        stays = np.unpackbits(bits, axis=1, count=n).astype(np.float64)
        return out + stays @ (blocks[0] - blocks[1])
    picks = rng.integers(0, k + 1, (rows, n), dtype=np.int16)
    for j in range(k):
        out += (picks == j).astype(np.float64) @ (blocks[j] - blocks[k])
    return out


def _statistic(committed_sum: np.ndarray, total: np.ndarray, n: int, m: int) -> np.ndarray:
    """``mean(fresh) - mean(committed)`` from the committed group's sum and the pooled total."""
    return (total - committed_sum) / m - committed_sum / n


def _tie(observed: np.ndarray) -> np.ndarray:
    """A relabelling within rounding of the observed statistic counts as reaching it (conservative)."""
    return 1e-9 * (np.abs(observed) + 1.0)


def bootstrap_intervals(
    fresh: Mapping[str, np.ndarray], rng: np.random.Generator, n_resamples: int = BOOTSTRAP
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Percentile bootstrap intervals of the fresh means: ``({set: (E, 2)}, (E, 2) for the mean over sets)``.

    Each set is resampled on its own (stratified); the mean over sets is taken per resample.
    """
    alpha = (1 - CONFIDENCE) / 2
    means = {}
    for s, f in fresh.items():
        f = np.asarray(f, np.float64)
        counts = rng.multinomial(len(f), np.full(len(f), 1.0 / len(f)), size=n_resamples)
        means[s] = counts @ f / len(f)
    over_sets = np.mean(list(means.values()), axis=0)

    def interval(x: np.ndarray) -> np.ndarray:
        return np.quantile(x, [alpha, 1 - alpha], axis=0).T

    return {s: interval(m) for s, m in means.items()}, interval(over_sets)


def holm(pvalues: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p-values (same order as given).

    Example:
        >>> holm(np.array([0.01, 0.04, 0.03])).tolist()
        [0.03, 0.06, 0.06]
    """
    p = np.asarray(pvalues, np.float64)
    order = np.argsort(p, kind="stable")
    scaled = (len(p) - np.arange(len(p))) * p[order]
    adjusted = np.minimum(1.0, np.maximum.accumulate(scaled))
    out = np.empty_like(p)
    out[order] = adjusted
    return out


# ------------------------------------------------------------------------- the audit


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


@dataclass(frozen=True)
class Collected:
    """An audit's data before its test: the rows, and the per-example errors of the re-run entries.

    Attributes:
        header: the audit's fields but ``test`` and ``entries``.
        rows: one per entry, ``sets``, ``generated_mean`` and ``flagged`` not filled in yet.
        audited: the indices in ``rows`` of the re-run entries, in column order.
        committed: ``{set: (n, E)}`` errors on the committed sets, a column per re-run entry.
        fresh: ``{set: (m, E)}`` errors on the fresh draws.
        shipped: the entries whose method is shipped in this repository (:func:`shipped`).
    """

    header: dict[str, Any]
    rows: list[dict[str, Any]]
    audited: list[int]
    committed: dict[str, np.ndarray]
    fresh: dict[str, np.ndarray]
    shipped: frozenset[str] = frozenset()


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
    """
    seed, sets, audited, c, f = (
        found.header["seed"],
        list(found.header["sets"]),
        found.audited,
        found.committed,
        found.fresh,
    )
    rows = [{**row, "sets": {}} for row in found.rows]
    tests = len(audited) * (len(sets) + 1)
    n_permutations = permutations_for(tests)
    if audited:
        if progress is not None:
            progress(f"testing {len(audited)} entries: {n_permutations:,} permutations per test")
        p_sets, p_all = permutation_pvalues(c, f, _stream(seed, _PERMUTATION_KEY), n_permutations)
        ci_sets, ci_all = bootstrap_intervals(f, _stream(seed, _BOOTSTRAP_KEY))
        # Holm over every entry and test at once, flattened entry-major
        flat = np.column_stack([*(p_sets[s] for s in sets), p_all]).ravel()
        adjusted = holm(flat).reshape(len(audited), len(sets) + 1)
        for k, i in enumerate(audited):
            row = rows[i]
            for j, s in enumerate(sets):
                row["sets"][s] = _test_dict(
                    c[s][:, k].mean(), f[s][:, k].mean(), ci_sets[s][k], p_sets[s][k], adjusted[k, j]
                )
            row["generated_mean"] = {
                "sets": sets,
                **_test_dict(
                    np.mean([c[s][:, k].mean() for s in sets]),
                    np.mean([f[s][:, k].mean() for s in sets]),
                    ci_all[k],
                    p_all[k],
                    adjusted[k, -1],
                ),
            }
            row["flagged"] = bool((adjusted[k] <= LEVEL).any())
    return {
        **found.header,
        "test": describe_test(tests, n_permutations),
        "entries": rows,
    }


def describe_test(tests: int, n_permutations: int) -> dict[str, Any]:
    """The audit's ``test`` field: the statistic, the test, its permutations and the Holm family's size."""
    return {
        "statistic": "difference = fresh mean - committed mean of per-example percent errors "
        "(positive: the committed score is the better one); generated_mean = the mean over the "
        "generated sets (normal, camera, object) of each figure, not the board's All (four sets)",
        "p": "one-sided permutation test, (1 + #{T* >= T}) / (B + 1), relabelling within each set",
        "permutations": n_permutations,
        "correction": "holm",
        "tests": tests,
        "level": LEVEL,
        "bootstrap_resamples": BOOTSTRAP,
        "confidence": CONFIDENCE,
    }


def _stream(seed: int, key: int) -> np.random.Generator:
    return np.random.Generator(np.random.SFC64(np.random.SeedSequence(seed, spawn_key=(key,))))


def _test_dict(
    committed: float, fresh: float, interval: np.ndarray, p: float, adjusted: float
) -> dict[str, Any]:
    return {
        "committed": _r(committed),
        "fresh": _r(fresh),
        "fresh_interval": [_r(interval[0]), _r(interval[1])],
        "difference": _r(fresh - committed),
        "p": _r(p),
        "p_adjusted": _r(adjusted),
    }


def flagged(result: Mapping[str, Any]) -> list[str]:
    """The method ids an audit flags."""
    return [e["method"] for e in result["entries"] if e.get("flagged")]


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


def _fmt(x: float) -> str:
    s = f"{x:.2f}"
    return "0.00" if s == "-0.00" else s


def _p(x: float) -> str:
    return f"{x:.4f}" if x >= 1e-4 else f"{x:.1e}"


def audit_table(result: Mapping[str, Any]) -> str:
    """The audit for people: one line per entry and test, then the verdict."""
    t = result["test"]
    sizes = ", ".join(f"{SET_TITLES.get(s, s)} {n:,}" for s, n in result["sets"].items())
    lines = [
        f"audit of {result['benchmark']} {result['split']}, seed {result['seed']}: "
        f"{result['repeats']} fresh draw(s) of {sizes} examples",
        f"one-sided permutation test ({t['permutations']:,} permutations), Holm over {t['tests']} tests, "
        f"level {t['level']}; difference = fresh - committed mean % error",
        f"{MEAN_LABEL} = the mean over the generated sets {', '.join(SET_TITLES.get(s, s) for s in result['sets'])}"
        " (not the board's All, which includes Robot)",
        "",
        f"{'entry':<22} {'set':<7} {'committed':>9} {'fresh':>7} {'95% interval':>17} "
        f"{'difference':>10} {'p':>8} {'p (Holm)':>8}",
    ]
    for e in result["entries"]:
        if not e["runnable"]:
            failed = str(e["reason"]).startswith("failed: ")
            lines.append(f"{e['method']:<22} {'' if failed else 'not audited: '}{e['reason']}")
            continue
        for s, v in [*e["sets"].items(), (MEAN_LABEL, e["generated_mean"])]:
            lo, hi = v["fresh_interval"]
            lines.append(
                f"{e['method']:<22} {s:<7} {_fmt(v['committed']):>9} {_fmt(v['fresh']):>7} "
                f"{'[' + _fmt(lo) + ', ' + _fmt(hi) + ']':>17} {v['difference']:>+10.2f} "
                f"{_p(v['p']):>8} {_p(v['p_adjusted']):>8}"
                + ("  FLAGGED" if e["flagged"] and v["p_adjusted"] <= t["level"] else "")
            )
    lines.append("")
    hits = flagged(result)
    n_run = sum(1 for e in result["entries"] if e["runnable"])
    lines.append(
        f"flagged: {', '.join(hits)} (committed score better than the fresh sets allow)"
        if hits
        else f"nothing flagged: {n_run} of {len(result['entries'])} entries audited"
    )
    return "\n".join(lines) + "\n"


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
