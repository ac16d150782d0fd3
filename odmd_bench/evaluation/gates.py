"""Pass/fail rules for continuous integration: a ceiling on All, and no significant regression.

Each rule returns whether it passed and the lines that say why; the command line prints
them and exits 1 on a failure (``evaluate --max-all``, ``compare --fail-if-worse``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from odmd_bench.errors import UsageError
from odmd_bench.evaluation.compare import A_BETTER, B_BETTER, Comparison, PairedDifference
from odmd_bench.evaluation.report import signed
from odmd_bench.evaluation.result import EvaluationResult


def check_ceiling(ceiling: float) -> None:
    """Raise :class:`~odmd_bench.errors.UsageError` unless ``ceiling`` is a finite number >= 0."""
    if not math.isfinite(ceiling) or ceiling < 0:
        raise UsageError(f"--max-all must be a finite number >= 0, got {ceiling}")


def max_all_gate(result: EvaluationResult, ceiling: float) -> tuple[bool, str]:
    """Whether All (mean of the sets' mean percent errors) is at most ``ceiling``, and why.

    Examples:
        >>> from odmd_bench.evaluation.result import EvaluationResult
        >>> r = EvaluationResult("odmd-v1", "test", {}, 4.25, {})
        >>> max_all_gate(r, 5.0)
        (True, 'ok: All 4.25 is at most --max-all 5')
        >>> max_all_gate(r, 4.0)[0]
        False
    """
    check_ceiling(ceiling)
    value = result.all_percent_error_mean
    if value <= ceiling:
        return True, f"ok: All {value:.2f} is at most --max-all {ceiling:g}"
    return (
        False,
        f"fail: All {value:.2f} is above --max-all {ceiling:g} (mean percent error, lower is better)",
    )


def _because(name: str, d: PairedDifference, confidence: float) -> str:
    # A - B, as the comparison's table prints it (A: the baseline, B: the candidate).
    return (
        f"{name}: A - B (baseline - candidate) = {signed(d.difference)} points of mean percent error, "
        f"{confidence * 100:.6g}% interval [{signed(d.ci_low)}, {signed(d.ci_high)}], p = {d.p_value:.4f} "
        "(negative: the baseline's error is lower)"
    )


def _unless(d: PairedDifference, confidence: float) -> str:
    """Why a pass stands beside an interval that lies wholly on the worse side (empty otherwise).

    The verdict needs the interval *and* the test; when only the interval says worse, the
    line says so, so that "ok" never reads as what the interval beside it contradicts.
    """
    if d.ci_high < 0 and d.verdict != A_BETTER:
        return (
            f" (the interval lies above 0, but the test's p = {d.p_value:.4f} is not below "
            f"{1 - confidence:.2g}: worse needs both)"
        )
    return ""


def fail_if_worse(c: Comparison, sets: Sequence[str] = ()) -> tuple[bool, list[str]]:
    """Whether the candidate (B) is not significantly worse than the baseline (A).

    Worse means the paired comparison's verdict is "A better" (the interval of
    ``A - B`` below 0 and the sign-flip test's ``p < 1 - confidence``), on All or on
    any of ``sets``. Each line says what the verdict is: worse (fail), significantly
    better, or not significantly worse (not distinguishable).

    Args:
        c: the comparison, A = baseline, B = candidate.
        sets: sets checked besides All. Where only one set was compared, All is that set
            alone: it is checked once, on one line.

    Returns:
        ``(passed, lines)``: one line per target checked, failures first.

    Examples:
        >>> import numpy as np
        >>> from odmd_bench.evaluation.compare import compare_errors
        >>> a = {"camera": np.linspace(1.0, 2.0, 40)}
        >>> passed, lines = fail_if_worse(compare_errors(a, {"camera": a["camera"] + 1}), ["camera"])
        >>> passed, len(lines), lines[0][:62]
        (False, 1, 'fail: the candidate is significantly worse on camera (= All, t')
        >>> fail_if_worse(compare_errors(a, {"camera": a["camera"] - 1}))[1][0][:49]
        'ok: the candidate is significantly better on All:'
    """
    unknown = [s for s in sets if s not in c.sets]
    if unknown:
        raise UsageError(
            f"--fail-if-worse: set {unknown[0]!r} was not compared; compared: {', '.join(c.sets)}"
        )
    if len(c.sets) == 1 and list(sets) == list(c.sets):
        (only,) = c.sets
        targets = [(f"{only} (= All, the only set compared)", c.sets[only])]
    else:
        targets = [("All", c.all), *((s, c.sets[s]) for s in dict.fromkeys(sets))]
    worse = [(n, d) for n, d in targets if d.verdict == A_BETTER]
    lines = [
        f"fail: the candidate is significantly worse on {_because(n, d, c.confidence)}" for n, d in worse
    ]
    for n, d in targets:
        if d.verdict == B_BETTER:
            lines.append(f"ok: the candidate is significantly better on {_because(n, d, c.confidence)}")
        elif d.verdict != A_BETTER:
            lines.append(
                f"ok: not significantly worse on {_because(n, d, c.confidence)}{_unless(d, c.confidence)}"
            )
    return not worse, lines
