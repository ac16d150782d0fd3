"""How far a float32 re-run's depths lie from exact arithmetic: the basis of the audit check's tolerance.

``leaderboard check --audits`` compares the figures an audit computes from re-run depths
within a relative :data:`~odmd_bench.leaderboard.audit_check.DEPTH_RTOL` of each depth
(odmd_bench/leaderboard/audit_check.py says why). A float32 result lies within its
rounding error of the exact one whatever kernel computed it, so two processors' depths
differ by at most twice the larger error. This script measures that error for every
DBox entry of the board (the only float32 methods shipped): each network is run on the
fresh sets of an audit seed as the method runs it (float32, this machine's kernel) and in
float64 on the same float32 input, and the relative difference of the depths is reported
(largest, 99.99th and 50th percentile). Nothing is written.

    python scripts/audit_kernel_error.py [--seed 175360163338434] [--repeats 1] [--original ../shared/odmd-original]

Needs torch (``pip install -e ".[dbox]"``).
"""

from __future__ import annotations

import argparse
import copy
import os
import platform
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seed", type=int, default=175360163338434, help="the audit seed of the fresh sets")
    parser.add_argument("--repeats", type=int, default=1, help="fresh draws per set")
    parser.add_argument("--original", default=os.environ.get("ODMD_ORIGINAL"), help="the original release")
    args = parser.parse_args()

    import torch
    from odmd_bench_baselines.dbox.choice import resolve_weights
    from odmd_bench_baselines.dbox.formulations import make_inputs
    from odmd_bench_baselines.dbox.loading import _load

    from odmd_bench.leaderboard import audit as au

    fresh = au.fresh_sets(args.seed, args.repeats)
    lines = Path("/proc/cpuinfo").read_text().splitlines() if Path("/proc/cpuinfo").exists() else []
    cpu = next((line.split(":", 1)[1].strip() for line in lines if line.startswith("model name")), "")
    print(
        f"CPU: {cpu or platform.processor()}; torch {torch.__version__}; seed {args.seed}, {args.repeats} draw(s)"
    )
    worst = 0.0
    for entry in au.board_entries(REPO / "leaderboard"):
        target = au.resolve_target(entry, REPO, args.original)
        if target.name != "dbox":
            continue
        options = {k: v for k, v in target.options.items() if k in ("config", "weights", "selection")}
        relative = []
        for draws in fresh.values():
            for ex in draws:
                path, _ = resolve_weights(ex, **options)
                model, form, _ = _load(path, None, require_record=options.get("weights") is None)
                inp = make_inputs(ex, form)
                x = torch.from_numpy(inp.x)
                with torch.no_grad():
                    single = model(x).double().numpy() * inp.scale
                    double = copy.deepcopy(model).double()(x.double()).numpy() * inp.scale
                relative.append(np.abs(single - double) / np.abs(double))
        r = np.concatenate(relative)
        worst = max(worst, float(r.max()))
        q = np.quantile(r, [0.5, 0.9999])
        print(
            f"{entry.method:<20} {len(r):>6} depths: largest {r.max():.2e}, 99.99% {q[1]:.2e}, median {q[0]:.2e}"
        )
    print(f"largest relative float32 error of a depth: {worst:.2e}")


if __name__ == "__main__":
    main()
