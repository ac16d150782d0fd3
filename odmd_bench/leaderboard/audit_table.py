"""The fresh-seed audit for people: ``leaderboard audit``'s text table (``--format table``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from odmd_bench.leaderboard.audit_stats import flagged
from odmd_bench.leaderboard.specs import SET_TITLES

#: How the table labels the mean over the generated sets (JSON: ``generated_mean``).
MEAN_LABEL = "N+C+O"


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


__all__ = ["MEAN_LABEL", "audit_table"]
