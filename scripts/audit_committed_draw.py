"""Where the committed test draw lies among fresh draws, for entries the audit doubts.

For each entry of ``--only``, its per-example percent errors on the committed ``odmd-v1``
test sets are compared with its errors on ``--draws`` fresh draws (seeds ``--first`` on:
the first draw of ``leaderboard audit --seed SEED``): per set, the mean, the median, the
99th percentile and the largest error of the committed draw beside the mean and standard
deviation of the same statistic over the fresh draws, ``z`` (how many of those standard
deviations the committed value lies from their mean) and how many fresh draws lie at or
below it; and the same for the mean over the sets (``all``).

Then, given that committed draw, the chance that an audit with ``K`` pooled fresh draws
flags the entry (its smallest one-sided p-value at most Holm's first threshold,
``LEVEL / tests``): estimated by drawing ``K`` of the fresh draws at random, many times,
with the normal approximation of the permutation test's p-value. This is the false-alarm
rate that every audit of this board meets, not the test's rate over draws of the
committed set (scripts/audit_rates.py --fresh-vs-fresh measures that one).

Writes ``--out`` (JSON) and prints it. About 4 s per draw for the two ``p-z`` entries on
a 2-core Xeon::

    python scripts/audit_committed_draw.py --only dbox-p-z-per-set,dbox-p-z --draws 60 \
        --out docs/audit_committed_draw.json
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.leaderboard.audit import LEVEL, collect_errors

ROOT = Path(__file__).resolve().parents[1] / "leaderboard"
#: Entries x tests of the recorded audit's Holm family (10 entries, three sets and all).
TESTS = 40
STATISTICS: dict[str, Callable[[np.ndarray], Any]] = {
    "mean": np.mean,
    "median": np.median,
    "q99": lambda x: np.quantile(x, 0.99),
    "max": np.max,
}


def _place(committed: float, fresh: np.ndarray) -> dict[str, Any]:
    sd = float(fresh.std(ddof=1))
    return {
        "committed": round(committed, 4),
        "fresh_mean": round(float(fresh.mean()), 4),
        "fresh_sd": round(sd, 4),
        "z": round((committed - float(fresh.mean())) / sd, 2),
        "fresh_at_or_below": int((fresh <= committed).sum()),
    }


def _flag_chance(
    c: dict[str, np.ndarray], f: dict[str, list[np.ndarray]], k: int, rng: np.random.Generator
) -> float:
    """P(smallest p <= LEVEL / TESTS) with ``k`` fresh draws pooled (normal approximation)."""
    draws = len(next(iter(f.values())))
    threshold = LEVEL / TESTS
    hits, tries = 0, 4000
    for _ in range(tries):
        pick = rng.choice(draws, k, replace=False)
        zs, ts, vs = [], [], []
        for s in c:
            fresh = np.concatenate([f[s][i] for i in pick])
            pooled = np.concatenate([c[s], fresh])
            v = pooled.var() * (1 / len(c[s]) + 1 / len(fresh))
            t = fresh.mean() - c[s].mean()
            zs.append(t / math.sqrt(v))
            ts.append(t)
            vs.append(v)
        zs.append(float(np.mean(ts)) / math.sqrt(sum(vs) / len(vs) ** 2))
        hits += 0.5 * math.erfc(max(zs) / math.sqrt(2)) <= threshold
    return hits / tries


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", required=True, help="entries (comma-separated method ids)")
    parser.add_argument("--draws", type=int, default=60, help="fresh draws (default 60)")
    parser.add_argument("--first", type=int, default=1000, help="seed of the first draw (default 1000)")
    parser.add_argument("--repeats", default="1,3,5", help="pooled draws K whose flag chance is estimated")
    parser.add_argument("--original", default=None)
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--out", type=Path, default=Path("docs/audit_committed_draw.json"))
    args = parser.parse_args()
    only = args.only.split(",")
    committed: dict[str, dict[str, np.ndarray]] = {}
    fresh: dict[str, dict[str, list[np.ndarray]]] = {m: {} for m in only}
    for seed in range(args.first, args.first + args.draws):
        found = collect_errors(
            ROOT, seed, repeats=1, data_dir=args.data_dir, original=args.original, only=only
        )
        methods = [found.rows[i]["method"] for i in found.audited]
        for k, m in enumerate(methods):
            committed.setdefault(m, {s: c[:, k] for s, c in found.committed.items()})
            for s, errors in found.fresh.items():
                fresh[m].setdefault(s, []).append(errors[:, k])
    rng = np.random.default_rng(0)
    entries = {}
    for m in only:
        c, f = committed[m], fresh[m]
        sets = {
            s: {
                name: _place(float(stat(c[s])), np.array([stat(x) for x in f[s]]))
                for name, stat in STATISTICS.items()
            }
            for s in c
        }
        all_c = float(np.mean([c[s].mean() for s in c]))
        all_f = np.mean([[x.mean() for x in f[s]] for s in c], axis=0)
        entries[m] = {
            "sets": sets,
            "all_mean": _place(all_c, all_f),
            "flag_chance_by_repeats": {
                k: round(_flag_chance(c, f, int(k), rng), 4) for k in args.repeats.split(",")
            },
        }
    doc = {
        "command": f"python scripts/audit_committed_draw.py --only {args.only} --draws {args.draws} "
        f"--first {args.first} --repeats {args.repeats}",
        "fresh_seeds": f"{args.first}-{args.first + args.draws - 1} (the first draw of each audit seed)",
        "holm_first_threshold": LEVEL / TESTS,
        "entries": entries,
    }
    text = json.dumps(doc, indent=1) + "\n"
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(args.out)
    print(text, end="")


if __name__ == "__main__":
    main()
