"""``leaderboard check --audits``: a recorded audit re-run and compared within what another processor gives.

An audit's figures come in two kinds:

- **exact**: the seeds, sizes, commands, hashes, which entries were re-run and why not,
  and the *committed* means (the committed predictions, read from their CSV and scored in
  float64 by numpy): compared as they are, digit for digit;
- **kernel-dependent**: everything computed from the re-run's depths (the fresh means,
  their intervals, the differences, the p-values and the flags). A re-run on another
  processor gives the same depths only to the last bits of float32: torch's CPU kernels
  (MKL's or oneDNN's SGEMM, AVX2 or AVX-512) sum a product in another order. These are
  compared within the tolerance derived below.

**The tolerance.** Let every re-run depth differ from this machine's by at most a relative
:data:`DEPTH_RTOL` (``|Z' - Z| <= r |Z|``). A percent error ``e = 100 |Z_true - Z| / Z_true``
then moves by at most ``100 r Z / Z_true <= r (100 + e)``. So

- a fresh mean moves by at most ``r (100 + mean)`` (the mean of the bounds), and so does the
  mean over the sets;
- a bootstrap interval's end moves by at most ``r (100 + end)``: every resample mean moves
  by at most ``r (100 + itself)``, the maps ``v -> v +- r (100 + v)`` are increasing, so each
  order statistic, and the linear interpolation between two, moves by at most that of
  itself (the resamples are drawn from the seed, not from the errors);
- a permutation p-value counts ``T* >= T``; ``T - T*`` is a sum of the fresh errors that a
  relabelling moves to the committed side, weighted ``1/m + 1/n``, so it moves by at most
  ``(1/m + 1/n)`` times the sum of the ``n`` largest error bounds (at most ``n`` fresh
  errors change sides). The re-run computes the count at ``T`` moved by that margin up and
  down: the recorded p must lie between (the same relabellings, drawn from the seed);
- Holm's adjusted p-values are increasing in each p-value, so each lies between Holm of
  the lower ends and Holm of the upper ends; an entry's flag must be set where even the
  upper ends flag it, and must not be where even the lower ends do not (a flag near the
  level may go either way, and the recorded one is accepted).

Every figure is stored rounded to 6 decimals: a further ``1e-6`` for the two roundings.

**Why ``r = 5e-5`` is safe.** A float32 result lies within its rounding error of the exact
(real-number) result, whichever kernel computed it, so two kernels' depths differ by at
most twice the larger error. ``python scripts/audit_kernel_error.py`` measures that error
for this repository's DBox networks (the only float32 methods shipped; the analytical ones
are float64 numpy, whose kernels differ in about 1e-15) against the same networks run in
float64 on the same input: on the committed audit's fresh sets the largest relative error
of a depth is 9.5e-6 (``dbox-ns``; the median 3e-7 to 4e-7), so two processors' depths
differ by at most 1.9e-5, and ``r`` is 2.6 times that (a margin for draws and inputs not
measured). ``check --audits`` reports how much of the tolerance a re-run
used: the audit recorded on an Intel Xeon, re-run on an AMD EPYC, used at most 0.02% of it
(the sixth decimal of a fresh mean). ``r = 5e-5`` is still small: on a fresh mean of 10%
it allows 0.0055 points, so a changed figure (0.01 points, an interval's end, a p-value, a
flag) is caught. A method whose depths jump under a last-bit change of its input (a
branch taken one way on one processor and the other way on another) could exceed it on
some example; the check would then fail, naming the figure, rather than pass a changed one.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odmd_bench.errors import OdmdError
from odmd_bench.evaluation.resampling import exceedances, holm, keyed_stream, p_value
from odmd_bench.leaderboard.audit_files import audit_json, audit_path, read_audits
from odmd_bench.leaderboard.audit_stats import PERMUTATION_KEY, Collected, assess_with, describe_test
from odmd_bench.leaderboard.audit_stats import n_tests as tests_of
from odmd_bench.leaderboard.diff import diff_json
from odmd_bench.leaderboard.specs import rounded

#: The relative difference of a re-run depth between two processors that the check allows
#: (module docstring: why it is safe).
DEPTH_RTOL = 5e-5
#: Two roundings to 6 decimals.
ROUNDING = 1e-6
#: The figures of a test that depend on the re-run's depths.
KERNEL_DEPENDENT = ("fresh", "fresh_interval", "difference", "p", "p_adjusted")


def error_bounds(errors: np.ndarray, rtol: float = DEPTH_RTOL) -> np.ndarray:
    """How far each percent error may move when its depth moves by a relative ``rtol``: ``rtol (100 + e)``."""
    return rtol * (100.0 + np.abs(np.asarray(errors, np.float64)))


def figure_tolerance(value: float, rtol: float = DEPTH_RTOL) -> float:
    """How far a fresh mean, an interval's end or a difference may move: ``rtol (100 + |value|)`` + rounding."""
    return rtol * (100.0 + abs(float(value))) + ROUNDING


def statistic_margins(
    committed: Mapping[str, np.ndarray], fresh: Mapping[str, np.ndarray], rtol: float = DEPTH_RTOL
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """How far ``T - T*`` may move, per set and entry, and for the mean over sets: ``({set: (E,)}, (E,))``.

    ``(1/m + 1/n)`` times the sum of the ``n`` largest error bounds of the ``m`` fresh
    errors of each column (module docstring).
    """
    out = {}
    for s in committed:
        n, f = len(committed[s]), np.asarray(fresh[s], np.float64)
        m = len(f)
        bounds = error_bounds(f, rtol)
        k = min(n, m)
        largest = np.partition(bounds, m - k, axis=0)[m - k :] if m else bounds
        out[s] = (1.0 / m + 1.0 / n) * largest.sum(axis=0)
    return out, np.mean(list(out.values()), axis=0)


def pvalue_ranges(
    found: Collected, n_permutations: int, rtol: float = DEPTH_RTOL
) -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest p-value another processor may give: two ``(E, sets + 1)`` arrays.

    ``found`` is a :class:`~odmd_bench.leaderboard.audit_stats.Collected`; the columns are its
    sets in order, then the mean over sets, as :func:`~odmd_bench.leaderboard.audit_stats.assess_with`
    orders them for Holm; ``n_permutations`` is the record's.
    """
    return _ranges_and_pvalues(found, n_permutations, rtol)[0]


def _ranges_and_pvalues(
    found: Collected, n_permutations: int, rtol: float
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[dict[str, np.ndarray], np.ndarray]]:
    """:func:`pvalue_ranges`, and the p-values themselves, counted on one pass of relabellings.

    The p-values are those :func:`~odmd_bench.leaderboard.audit_stats.assess_with` draws
    with ``n_permutations``: the same stream gives the same relabellings, whatever the shifts.
    """
    sets = list(found.header["sets"])
    margins = statistic_margins(found.committed, found.fresh, rtol)
    up, down = margins, ({s: -v for s, v in margins[0].items()}, -margins[1])
    counts, counts_all = exceedances(
        found.committed,
        found.fresh,
        keyed_stream(found.header["seed"], PERMUTATION_KEY),
        n_permutations,
        (up, down, 0.0),
    )
    low = np.column_stack([*(counts[s][0] for s in sets), counts_all[0]])
    high = np.column_stack([*(counts[s][1] for s in sets), counts_all[1]])
    pvalues = (
        {s: p_value(c[2], n_permutations) for s, c in counts.items()},
        p_value(counts_all[2], n_permutations),
    )
    return (p_value(low, n_permutations), p_value(high, n_permutations)), pvalues


@dataclass
class Comparison:
    """What comparing a record with its re-run found.

    Attributes:
        problems: one line per difference beyond what another processor may give.
        notes: entries the record re-ran that cannot be re-run here (a plug-in not
            installed), or the other way round: their recorded figures are kept unchecked.
        largest_share: the largest difference of a kernel-dependent figure (fresh means,
            intervals, differences) as a share of its tolerance (0 to 1 when it passes).
    """

    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    largest_share: float = 0.0


def compare(doc: Mapping[str, Any], found: Collected, name: str, rtol: float = DEPTH_RTOL) -> Comparison:
    """Compare the recorded audit ``doc`` with its re-run ``found`` (a ``Collected`` of the same entries).

    Entries the record re-ran and that cannot be re-run here are a note, not a difference,
    when their method is a plug-in (a contributor's, not installed here) and a problem
    when it is shipped in this repository; their recorded p-values enter Holm's
    correction as recorded. Entries re-run here that the record did not re-run are a
    note (record the audit again to audit them).
    """
    from odmd_bench.leaderboard import audit as au

    out = Comparison()
    level = float(doc["test"]["level"])
    recorded = {e["method"]: e for e in doc["entries"]}
    for e in doc["entries"]:
        tests = [*e["sets"].values(), *([e["generated_mean"]] if e["generated_mean"] else [])]
        if (
            e["runnable"] is True
            and isinstance(e["flagged"], bool)
            and e["flagged"] != any(t["p_adjusted"] <= level for t in tests)
        ):
            out.problems.append(
                f"{name}: entries[{e['method']}].flagged: {e['flagged']} is not what its adjusted "
                f"p-values give at level {level}"
            )
    here = {found.rows[i]["method"] for i in found.audited}
    rows, kept_as_recorded = [], {}
    for row in found.rows:
        theirs = recorded.get(row["method"])
        if theirs is not None and theirs["runnable"] and not row["runnable"]:
            if row["method"] in found.shipped:
                out.problems.append(
                    f"{name}: entries[{row['method']}]: a method shipped in this repository, re-run by the "
                    f"record, cannot be re-run here: {row['reason']}"
                )
            else:
                out.notes.append(
                    f"{name}: entry {row['method']} not audited here: {row['reason']} (its recorded "
                    "figures are kept, unchecked)"
                )
            row = kept_as_recorded[row["method"]] = {**theirs}
        elif theirs is not None and not theirs["runnable"] and row["runnable"]:
            out.notes.append(
                f"{name}: entry {row['method']} can be re-run here, the record did not ({theirs['reason']}): "
                f"record the audit again to audit it"
            )
            here.discard(row["method"])
            row = kept_as_recorded[row["method"]] = {**theirs}
        rows.append(row)
    kept = [k for k, i in enumerate(found.audited) if found.rows[i]["method"] in here]
    found = Collected(
        found.header,
        rows,
        [found.audited[k] for k in kept],
        {s: c[:, kept] for s, c in found.committed.items()},
        {s: f[:, kept] for s, f in found.fresh.items()},
        found.shipped,
    )
    sets = list(found.header["sets"])
    n_tests = sum(1 for e in doc["entries"] if e["runnable"]) * (len(sets) + 1)
    n_permutations = au.permutations_for(n_tests)
    ranges = None
    if found.audited and au.permutations_for(tests_of(found)) == n_permutations:
        # the re-run's p-values and their ranges: the same relabellings, drawn once
        ranges, pvalues = _ranges_and_pvalues(found, n_permutations, rtol)
        again = assess_with(found, n_permutations, pvalues=pvalues)
    else:
        again = au.assess(found)
    again = {
        **again,
        "test": describe_test(n_tests, n_permutations),
        "entries": [kept_as_recorded.get(e["method"], e) for e in again["entries"]],
    }
    out.problems += diff_json(audit_json(_exact_part(doc)), audit_json(_exact_part(again)), name)
    if out.problems or not found.audited:
        return out
    others = [
        t["p"]
        for e in doc["entries"]
        if e["runnable"] and e["method"] not in here
        for t in [*e["sets"].values(), e["generated_mean"]]
    ]
    low, high = ranges if ranges is not None else pvalue_ranges(found, n_permutations, rtol)
    adjusted_low = holm(np.concatenate([low.ravel(), others]))[: low.size].reshape(low.shape)
    adjusted_high = holm(np.concatenate([high.ravel(), others]))[: high.size].reshape(high.shape)
    for k, i in enumerate(found.audited):
        method = found.rows[i]["method"]
        mine = next(e for e in again["entries"] if e["method"] == method)
        theirs = recorded[method]
        for j, key in enumerate([*sets, None]):
            where = f"{name}: entries[{method}].{'generated_mean' if key is None else 'sets.' + key}"
            a = theirs["generated_mean"] if key is None else theirs["sets"][key]
            b = mine["generated_mean"] if key is None else mine["sets"][key]
            pairs = [(f"{where}.{f}", a[f], b[f], b["fresh"]) for f in ("fresh", "difference")]
            pairs += [
                (
                    f"{where}.fresh_interval[{end}]",
                    a["fresh_interval"][end],
                    b["fresh_interval"][end],
                    b["fresh_interval"][end],
                )
                for end in (0, 1)
            ]
            for label, x, y, scale in pairs:
                tolerance = figure_tolerance(scale, rtol)
                out.largest_share = max(out.largest_share, abs(x - y) / tolerance)
                if abs(x - y) > tolerance:
                    out.problems.append(
                        f"{label}: committed {x!r}, the re-run gives {y!r} (another processor may give "
                        f"+-{tolerance:.2g})"
                    )
            out.problems += _within(f"{where}.p", a["p"], low[k, j], high[k, j])
            out.problems += _within(
                f"{where}.p_adjusted", a["p_adjusted"], adjusted_low[k, j], adjusted_high[k, j]
            )
        must, may = bool((adjusted_high[k] <= level).any()), bool((adjusted_low[k] <= level).any())
        if (must and not theirs["flagged"]) or (theirs["flagged"] and not may):
            out.problems.append(
                f"{name}: entries[{method}].flagged: committed {theirs['flagged']}, the re-run gives {must}"
            )
    return out


def _exact_part(doc: Mapping[str, Any]) -> dict[str, Any]:
    """``doc`` without the figures that depend on the re-run's depths."""
    entries = []
    for e in doc["entries"]:
        e = dict(e)
        e.pop("flagged", None)
        for key in ("sets", "generated_mean"):
            if isinstance(e.get(key), dict):
                if key == "sets":
                    e[key] = {s: _strip(t) for s, t in e[key].items()}
                else:
                    e[key] = _strip(e[key])
        entries.append(e)
    return {**doc, "entries": entries}


def _strip(test: Any) -> Any:
    return {k: v for k, v in test.items() if k not in KERNEL_DEPENDENT} if isinstance(test, dict) else test


def _within(where: str, recorded: float, low: float, high: float) -> list[str]:
    lo, hi = rounded(low), rounded(high)
    if lo - ROUNDING / 2 <= recorded <= hi + ROUNDING / 2:
        return []
    shown = f"{lo!r}" if lo == hi else f"{lo!r} to {hi!r}"
    return [f"{where}: committed {recorded!r}, the re-run gives {shown} (on any processor)"]


def rerun_audits(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    progress: Callable[[str], None] | None = None,
    rtol: float = DEPTH_RTOL,
) -> list[str]:
    """Re-run every recorded audit (``leaderboard check --audits``): one line per difference.

    Each file is audited again with its seed, repeats, sizes, entries and date; its exact
    fields are compared as they are, the others within what another processor's float32
    kernels may give (module docstring).
    """
    from odmd_bench.leaderboard.audit import collect_errors, generated_sets

    say = progress or (lambda _line: None)
    audits, problems = read_audits(root)
    for doc in audits:
        name = f"audits/{doc['seed']}.json"
        committed = {s: int(p["n"]) for s, p in generated_sets().items()}
        sizes = set(doc["sets"].values())
        if list(doc["sets"]) != list(committed) or len(sizes) != 1:
            problems.append(
                f"{name}: its sets {doc['sets']} are not those an audit draws ({', '.join(committed)})"
            )
            continue
        size = sizes.pop()
        say(f"re-running {name}")
        try:
            found = collect_errors(
                root,
                doc["seed"],
                repeats=doc["repeats"],
                size=None if all(n == size for n in committed.values()) else size,
                data_dir=data_dir,
                original=original,
                only=[e["method"] for e in doc["entries"]],
                date=doc["date"],
                progress=progress,
            )
        except OdmdError as e:
            problems.append(f"{name}: cannot be re-run: {e.render()}")
            continue
        result = compare(doc, found, name, rtol)
        text = audit_path(root, doc["seed"]).read_text(encoding="utf-8")
        if not result.problems and text != audit_json(json.loads(text)):
            result.problems.append(
                f"{name}: not written as `leaderboard audit --record` writes it (whitespace)"
            )
        for line in result.notes:
            say(line)
        if not result.problems:
            say(
                f"{name}: the figures computed from re-run depths are within {result.largest_share:.2%} of "
                f"what another processor may give (a relative {rtol:g} of each depth)"
            )
        problems += result.problems
    return problems


__all__ = [
    "Comparison",
    "DEPTH_RTOL",
    "KERNEL_DEPENDENT",
    "compare",
    "error_bounds",
    "figure_tolerance",
    "pvalue_ranges",
    "rerun_audits",
    "statistic_margins",
]
