"""The numbers of docs/odms-guard.md's analysis: tails per set, and what the guard changes.

``python -m odmd_bench_baselines.dbox_guard.analysis [--data-dir D]`` prints, as markdown:

- per set of ODMS-detection val (the methods run here) and test (the committed
  leaderboard predictions), the mean, median and max percent error and the share of
  the mean carried by the worst 1 % of examples, for the guard, DBox_p^z per-set and
  Box_LS;
- on val and on test, by failure mode (examples whose start the guard repaired,
  examples it capped, the rest), the DBox_p^z per-set and guard means and counts over
  100 %.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

import odmd_bench

#: The compared methods: label -> leaderboard entry.
ENTRIES = {"DBox guard": "dbox-guard", "DBox_p^z per-set": "dbox-p-z-per-set", "Box_LS": "box-ls"}
BENCHMARK = "odms-detection"


def tail(errors: np.ndarray) -> dict[str, float]:
    """Mean, median, max and the share of the mean carried by the worst 1 % of examples.

    The worst 1 % is the ``ceil(n / 100)`` largest errors; ``top1_share`` is their sum
    over the sum of all errors.

    Example:
        >>> e = np.array([1.0] * 99 + [101.0])
        >>> {k: round(v, 3) for k, v in tail(e).items()}
        {'mean': 2.0, 'median': 1.0, 'max': 101.0, 'top1_share': 0.505}
    """
    e = np.asarray(errors, dtype=np.float64)
    k = max(1, math.ceil(e.size / 100))
    worst = np.sort(e)[::-1][:k]
    return {
        "mean": float(e.mean()),
        "median": float(np.median(e)),
        "max": float(e.max()),
        "top1_share": float(worst.sum() / e.sum()),
    }


def val_errors(data_dir: str | Path | None) -> dict[str, dict[str, np.ndarray]]:
    """Per method and set, the val percent errors (each method sees no true depth)."""
    from odmd_bench_baselines import box_ls, dbox, dbox_guard

    predict = {
        "DBox guard": dbox_guard.predict,
        "DBox_p^z per-set": lambda ex: dbox.predict(ex, config="p-z", selection="per-set"),
        "Box_LS": box_ls.predict,
    }
    sets = odmd_bench.load_split("val", BENCHMARK, data_dir)
    return {
        label: {s: odmd_bench.percent_error(ex.depth, run(ex.without_truth())) for s, ex in sets.items()}
        for label, run in predict.items()
    }


def test_errors(root: Path, data_dir: str | Path | None) -> dict[str, dict[str, np.ndarray]]:
    """Per method and set, the test percent errors of the committed leaderboard entries."""
    out: dict[str, dict[str, np.ndarray]] = {}
    for label, entry in ENTRIES.items():
        path = root / "entries" / entry / f"{BENCHMARK}-test" / "predictions.csv.gz"
        per = odmd_bench.evaluate(path, benchmark=BENCHMARK, data_dir=data_dir).per_example()
        out[label] = {s: per["percent_error"][per["set"] == s] for s in dict.fromkeys(per["set"])}
    return out


def tail_table(errors: Mapping[str, Mapping[str, np.ndarray]]) -> str:
    """The markdown table of :func:`tail` per set and method."""
    lines = [
        "| set | method | mean | median | max | worst 1 % share |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    first = next(iter(errors.values()))
    for s in first:
        for label, per_set in errors.items():
            t = tail(per_set[s])
            lines.append(
                f"| {s} | {label} | {t['mean']:.2f} | {t['median']:.2f} | {t['max']:.1f} | "
                f"{100 * t['top1_share']:.1f} % |"
            )
    return "\n".join(lines)


def modes(
    data_dir: str | Path | None, errors: Mapping[str, Mapping[str, np.ndarray]], split: str = "val"
) -> str:
    """The DBox_p^z per-set and guard errors of ``split`` by what the guard did to the example."""
    from odmd_bench_baselines.dbox_guard.method import choose_parameters, details

    sets = odmd_bench.load_split(split, BENCHMARK, data_dir)
    lines = [
        "| set | examples | n | DBox_p^z per-set mean | guard mean | DBox over 100 % | guard over 100 % |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for s, ex in sets.items():
        _, repaired, capped, _ = details(ex.without_truth(), *choose_parameters(ex))
        base, guard = errors["DBox_p^z per-set"][s], errors["DBox guard"][s]
        groups = {
            "wrong start repaired": repaired,
            "capped": capped & ~repaired,
            "the rest": ~repaired & ~capped,
        }
        for g, m in groups.items():
            if m.any():
                lines.append(
                    f"| {s} | {g} | {int(m.sum())} | {base[m].mean():.2f} | {guard[m].mean():.2f} | "
                    f"{int((base[m] > 100).sum())} | {int((guard[m] > 100).sum())} |"
                )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the analysis tables."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data-dir", default=None, help="data folder (default: odmd-bench's)")
    parser.add_argument("--root", type=Path, default=Path("leaderboard"), help="the leaderboard folder")
    args = parser.parse_args(argv)
    val = val_errors(args.data_dir)
    print("ODMS-detection val\n\n" + tail_table(val) + "\n")
    test = test_errors(args.root, args.data_dir)
    print("ODMS-detection test (committed entries)\n\n" + tail_table(test) + "\n")
    print("val, by failure mode\n\n" + modes(args.data_dir, val) + "\n")
    print("test (read once, after the selection), by failure mode\n\n" + modes(args.data_dir, test, "test"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
