"""The fresh-seed audit's false-alarm rate and power, measured on the committed board.

For each seed of ``--seeds``, the whole ``odmd-v1`` test board is audited as
``odmd-bench leaderboard audit --seed SEED`` does (every entry honest: none was tuned on
the test sets): a flagged entry is a false alarm. On the first ``--power-seeds`` seeds
the same re-runs are tested again with an advantage planted in every entry's committed
errors: on a random fraction ``q`` of the examples of each committed set the error is
set to 0 (the method answers the truth there, as a partial memoriser would), so the
committed mean drops by about ``q`` times itself; a flagged entry is then a detection.

With ``--fresh-vs-fresh`` each seed draws two fresh sets and tests one against the
other, as if the first were the committed set: honest by construction on both sides,
so the flags count the test's own false alarms, free of how the committed draw fell.
``--repeats K`` pools K fresh draws per set as the audit does (default: the audit's
default); with ``--fresh-vs-fresh`` K + 1 are drawn, the first in the committed set's place.

Writes ``--out`` (JSON: per seed, the flagged entries and raw p-values; the summary) and
prints the summary. Slow (every DBox configuration re-run per seed: about a minute per
seed on 2 cores with five draws); run it with ``nice`` (output: docs/audit_rates.json)::

    nice -n 19 python scripts/audit_rates.py --seeds 1-50 --power-seeds 10 --jobs 2 \
        --original ../shared/odmd-original --only box-ls,parallax,expansion,robust,dbox,dbox-p-z,dbox-p-z-per-set
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import time
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.leaderboard.audit import REPEATS, Collected, assess, collect_errors, flagged

ROOT = Path(__file__).resolve().parents[1] / "leaderboard"
#: Fractions of committed examples whose error is set to 0.
FRACTIONS = (0.01, 0.02, 0.05, 0.1)


def _seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def planted(found: Collected, q: float, seed: int) -> Collected:
    """``found`` with the error of a random fraction ``q`` of each committed set's examples set to 0."""
    rng = np.random.default_rng([seed, int(q * 10_000)])
    committed = {}
    for s, c in found.committed.items():
        c = c.copy()
        for k in range(c.shape[1]):
            chosen = rng.choice(len(c), size=round(q * len(c)), replace=False)
            c[chosen, k] = 0.0
        committed[s] = c
    return Collected(found.header, found.rows, found.audited, committed, found.fresh)


def fresh_vs_fresh(found: Collected, repeats: int) -> Collected:
    """``repeats + 1`` fresh draws: the first as the committed set, the rest as the fresh ones (honest by construction)."""
    committed, fresh = {}, {}
    for s, f in found.fresh.items():
        n = len(f) // (repeats + 1)
        committed[s], fresh[s] = f[:n], f[n:]
    return Collected({**found.header, "repeats": repeats}, found.rows, found.audited, committed, fresh)


def _summary(result: dict[str, Any]) -> dict[str, Any]:
    ps = [
        t["p"] for e in result["entries"] if e["runnable"] for t in [*e["sets"].values(), e["generated_mean"]]
    ]
    return {
        "flagged": flagged(result),
        "tests": len(ps),
        "raw_p_at_most_0.05": sum(p <= 0.05 for p in ps),
        "raw_p_at_most_0.01": sum(p <= 0.01 for p in ps),
        "p": {
            e["method"]: {**{s: t["p"] for s, t in e["sets"].items()}, "all": e["generated_mean"]["p"]}
            for e in result["entries"]
            if e["runnable"]
        },
        "committed_all": {
            e["method"]: e["generated_mean"]["committed"] for e in result["entries"] if e["runnable"]
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-50", help="audit seeds, FIRST-LAST (default 1-50)")
    parser.add_argument("--power-seeds", type=int, default=20, help="how many of them also measure power")
    parser.add_argument("--original", default=None, help="the original release (for dbox-release's weights)")
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--jobs", type=int, default=1, help="seeds audited at once (processes)")
    parser.add_argument(
        "--fresh-vs-fresh",
        action="store_true",
        help="test two fresh draws against each other instead of the committed sets against one: "
        "the test's false-alarm rate over draws of both sides, free of the committed draw",
    )
    parser.add_argument(
        "--repeats",
        type=int,
        default=REPEATS,
        help=f"fresh draws per set, pooled (default {REPEATS}, the audit's)",
    )
    parser.add_argument("--only", default=None, help="audit these entries alone (comma-separated method ids)")
    parser.add_argument("--out", type=Path, default=Path("docs/audit_rates.json"))
    args = parser.parse_args()
    seeds = _seeds(args.seeds)
    jobs = [(seed, i < args.power_seeds, args) for i, seed in enumerate(seeds)]
    runs: list[dict[str, Any]] = []
    with multiprocessing.Pool(args.jobs) as pool:
        for run in pool.imap(_one, jobs):
            runs.append(run)
            print(
                f"seed {run['seed']}: flagged {run['honest']['flagged'] or 'none'} ({run['seconds']} s)",
                flush=True,
            )
            _write(args.out, runs, args)


def _one(job: tuple[int, bool, argparse.Namespace]) -> dict[str, Any]:
    """One seed's audit, honest and (``power``) with the planted advantages."""
    seed, power, args = job
    start = time.perf_counter()
    only = args.only.split(",") if args.only else None
    drawn = args.repeats + 1 if args.fresh_vs_fresh else args.repeats
    found = collect_errors(
        ROOT, seed, repeats=drawn, data_dir=args.data_dir, original=args.original, only=only
    )
    if args.fresh_vs_fresh:
        found = fresh_vs_fresh(found, args.repeats)
    run: dict[str, Any] = {"seed": seed, "honest": _summary(assess(found))}
    if power:
        run["planted"] = {str(q): _summary(assess(planted(found, q, seed))) for q in FRACTIONS}
    run["seconds"] = round(time.perf_counter() - start, 1)
    return run


def _write(out: Path, runs: list[dict[str, Any]], args: argparse.Namespace) -> None:
    n = len(runs)
    entries = sorted(runs[0]["honest"]["committed_all"])
    tests = sum(r["honest"]["tests"] for r in runs)
    power = {}
    with_power = [r for r in runs if "planted" in r]
    for q in FRACTIONS:
        if with_power:
            power[str(q)] = {
                m: sum(m in r["planted"][str(q)]["flagged"] for r in with_power) / len(with_power)
                for m in entries
            }
    summary = {
        "command": f"python scripts/audit_rates.py --seeds {args.seeds} --power-seeds {args.power_seeds}"
        + (" --original ORIGINAL" if args.original else "")
        + f" --repeats {args.repeats}"
        + (f" --only {args.only}" if args.only else "")
        + (" --fresh-vs-fresh" if args.fresh_vs_fresh else "")
        + (f" --jobs {args.jobs}" if args.jobs != 1 else ""),
        "seeds": n,
        "audits_with_a_false_alarm": sum(bool(r["honest"]["flagged"]) for r in runs),
        "false_alarms_by_entry": {m: sum(m in r["honest"]["flagged"] for r in runs) for m in entries},
        "raw_tests": tests,
        "raw_p_at_most_0.05": sum(r["honest"]["raw_p_at_most_0.05"] for r in runs),
        "raw_p_at_most_0.01": sum(r["honest"]["raw_p_at_most_0.01"] for r in runs),
        "power_seeds": len(with_power),
        "power_planted_fraction_to_detection_rate": power,
        "committed_all_of_the_audited_sets": runs[0]["honest"]["committed_all"],
        "seconds_per_seed_median": float(np.median([r["seconds"] for r in runs])),
    }
    text = json.dumps({"summary": summary, "runs": runs}, indent=1) + "\n"
    tmp = out.with_suffix(".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(out)


if __name__ == "__main__":
    main()
