"""Choosing the guard's parameters on ODMS-detection val only (docs/odms-guard.md).

The pre-registered grid: ``tau`` in :data:`TAUS`, ``alpha`` in :data:`ALPHAS`, ``cap``
in :data:`CAPS`, searched in that order (``tau`` outermost; the first minimum is kept,
so ties go to the smaller intervention). Each candidate of :data:`CANDIDATES` frees
some of them (the others stay at their first value) and chooses them per set on that
set's val mean with the set's DBox checkpoint, and once for all sets on val All with
the overall checkpoint (for data of no known set). The candidate with the lowest val All
of its per-set choice is selected; one within :data:`PREFER_SIMPLER` of it with fewer
free parameters is preferred. Test is never read.

``python -m odmd_bench_baselines.dbox_guard.select [--data-dir D] [--out FILE]`` writes
the record (every candidate's choices and val scores, the selection) as JSON, by
default over the shipped ``parameters.json``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from odmd_bench_baselines import box_ls, dbox
from odmd_bench_baselines.dbox_guard.method import PARAMETERS_FILE, Parameters
from odmd_bench_baselines.dbox_guard.steps import blend, cap, flag_wrong_starts, repair, travel

import odmd_bench
from odmd_bench import Examples

#: The benchmark and split that choose.
BENCHMARK, SPLIT = "odms-detection", "val"
#: The grids, in search order.
TAUS: tuple[float | None, ...] = (None, 0.5, 0.6, 0.7)
ALPHAS: tuple[float, ...] = (0.0, 0.25)
CAPS: tuple[float | None, ...] = (None, 4.0, 3.5, 3.0, 2.5)
#: Candidate -> its free parameters.
CANDIDATES: dict[str, tuple[str, ...]] = {
    "G1 repair": ("tau",),
    "G2 cap": ("cap",),
    "G3 blend": ("alpha",),
    "G4 guard": ("tau", "alpha", "cap"),
}
#: A candidate this close to the best val All with fewer free parameters is preferred.
PREFER_SIMPLER = 0.01


def grid(free: Sequence[str]) -> list[Parameters]:
    """The parameter sets a candidate with ``free`` parameters searches, in order."""
    taus = TAUS if "tau" in free else TAUS[:1]
    alphas = ALPHAS if "alpha" in free else ALPHAS[:1]
    caps = CAPS if "cap" in free else CAPS[:1]
    return [Parameters(t, a, c) for t, a, c in itertools.product(taus, alphas, caps)]


def errors(sets: Mapping[str, Examples], selection: str) -> dict[Parameters, dict[str, np.ndarray]]:
    """Per-example percent errors of every parameter set of the full grid, per set."""
    out: dict[Parameters, dict[str, np.ndarray]] = {}
    for name, examples in sets.items():
        length = travel(examples)
        for tau in TAUS:
            fixed = repair(examples, flag_wrong_starts(examples.boxes, examples.detected, tau))
            z_dbox = dbox.predict(fixed.without_truth(), config="p-z", selection=selection)
            z_ls = box_ls.predict(fixed.without_truth())
            for alpha in ALPHAS:
                mixed = blend(z_dbox, z_ls, alpha)
                for c in CAPS:
                    z = cap(mixed, length, c)
                    out.setdefault(Parameters(tau, alpha, c), {})[name] = odmd_bench.percent_error(
                        examples.depth, z
                    )
    return out


def _first_min(scores: list[tuple[Parameters, float]]) -> tuple[Parameters, float]:
    best = scores[0]
    for item in scores[1:]:
        if item[1] < best[1]:
            best = item
    return best


def choose(
    per_set_errors: Mapping[Parameters, Mapping[str, np.ndarray]],
    overall_errors: Mapping[Parameters, Mapping[str, np.ndarray]],
    sets: Sequence[str],
) -> dict[str, Any]:
    """Every candidate's choices and val scores, and the selected candidate."""
    record: dict[str, Any] = {}
    for cand, free in CANDIDATES.items():
        options = grid(free)
        chosen = {}
        for s in sets:
            p, score = _first_min([(p, float(per_set_errors[p][s].mean())) for p in options])
            chosen[s] = {"parameters": p.as_dict(), "val_mean": round(score, 4)}
        all_ = float(np.mean([chosen[s]["val_mean"] for s in sets]))
        p_all, score_all = _first_min(
            [(p, float(np.mean([overall_errors[p][s].mean() for s in sets]))) for p in options]
        )
        record[cand] = {
            "free": list(free),
            "per_set": chosen,
            "val_all": round(all_, 4),
            "overall": {"parameters": p_all.as_dict(), "val_all": round(score_all, 4)},
        }
    best = min(record, key=lambda c: record[c]["val_all"])
    near = [c for c in record if record[c]["val_all"] <= record[best]["val_all"] + PREFER_SIMPLER]
    selected = min(near, key=lambda c: (len(CANDIDATES[c]), record[c]["val_all"], list(CANDIDATES).index(c)))
    return {"candidates": record, "selected": selected}


def select(data_dir: str | Path | None = None) -> dict[str, Any]:
    """The guard's record: the grid, every candidate, the selection and its parameters."""
    sets = odmd_bench.load_split(SPLIT, BENCHMARK, data_dir)
    names = list(sets)
    per_set_errors = errors(sets, "per-set")
    overall_errors = errors(sets, "overall")
    base = Parameters()
    result = choose(per_set_errors, overall_errors, names)
    chosen = result["candidates"][result["selected"]]
    return {
        "method": "dbox-guard",
        "selected_on": {
            "benchmark": BENCHMARK,
            "split": SPLIT,
            "content_sha256": {s: str(sets[s].attrs.get("content_sha256", "")) for s in names},
        },
        "grid": {"tau": list(TAUS), "alpha": list(ALPHAS), "cap": list(CAPS)},
        "rule": (
            "per candidate, per set: the first minimum of the set's val mean over the candidate's "
            "grid; selected: the lowest val All, a candidate within "
            f"{PREFER_SIMPLER} with fewer free parameters preferred"
        ),
        "dbox_p_z_per_set_val": {s: round(float(per_set_errors[base][s].mean()), 4) for s in names},
        "candidates": result["candidates"],
        "selected": result["selected"],
        "per_set": {s: chosen["per_set"][s]["parameters"] for s in names},
        "overall": chosen["overall"]["parameters"],
        "command": "python -m odmd_bench_baselines.dbox_guard.select",
    }


def main(argv: Sequence[str] | None = None) -> int:
    """The command: choose on val, write the record, print each candidate; exit status."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data-dir", default=None, help="data folder (default: odmd-bench's)")
    parser.add_argument("--out", type=Path, default=PARAMETERS_FILE, help="record to write")
    args = parser.parse_args(argv)
    try:
        record = select(args.data_dir)
    except odmd_bench.OdmdError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    with odmd_bench.atomic_write(args.out, "w") as fh:
        fh.write(json.dumps(record, indent=2) + "\n")
    cands = record["candidates"]
    for name, c in cands.items():
        print(
            f"{name}: val All {c['val_all']:.2f} "
            + " ".join(f"{s} {v['val_mean']:.2f}" for s, v in c["per_set"].items())
        )
    print(f"selected: {record['selected']}; wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
