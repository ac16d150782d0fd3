r"""Speed and size of every leaderboard entry of this repository's methods (the entries' ``speed`` and ``parameters``).

Run (one core: one torch thread, OpenBLAS to one thread), with the boards' data in place
(``odmd-bench leaderboard check`` builds it; the release checkpoint's entry needs the
original release at ``../shared/odmd-original`` or ``ODMD_ORIGINAL``):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 .venv/bin/pytest benchmarks/bench_entries.py \
        --benchmark-only -p no:randomly -s

Each entry's own command (``odmd-bench baseline NAME --benchmark B --split test ...``) is
read from its ``entry.yaml``, and the method's ``run`` is timed on every set of the board's
test split with exactly those options, as ``baseline`` calls it (the sets loaded before,
the CSV not written): examples per second = examples / best time of the rounds. The
timing is :class:`odmd_bench.leaderboard.speed.SpeedRun`'s, which ``odmd-bench leaderboard
speed NAME ...`` uses for one method (a contributor's plug-in). The
rounds are interleaved (each runs every entry once), so that a machine shared with other
work slows every entry alike; ``extra_info`` holds each entry's ``examples_per_s``. ``parameters`` is the number of trained weights the
command uses: a DBox network's parameters times the checkpoints it runs (four with
per-set selection); 0 for the methods without trained weights. ``-s`` prints them.
"""

from __future__ import annotations

import os
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from odmd_bench import load_split, methods
from odmd_bench.cli.options import given_options
from odmd_bench.leaderboard import discover, read_entry
from odmd_bench.leaderboard.speed import ROUNDS, SpeedRun, cpu_model

REPO = Path(__file__).resolve().parents[1]
RELEASE = Path(os.environ.get("ODMD_ORIGINAL") or REPO.parent / "shared" / "odmd-original")
#: an entry's command names the user's copy of the original release so
RELEASE_PLACEHOLDER = "ODMD/"
OWN = [f for f in discover(REPO / "leaderboard") if read_entry(f).meta.code.startswith("baselines/")]


def options(command: str) -> tuple[str, dict[str, str]]:
    """(method name, its options) of an entry's ``odmd-bench baseline`` command."""
    words = shlex.split(command)
    if any(w.startswith("(") for w in words):
        words = words[: next(i for i, w in enumerate(words) if w.startswith("("))]
    assert words[:2] == ["odmd-bench", "baseline"], command
    given = {}
    for flag, value in zip(words[3::2], words[4::2], strict=False):
        if flag in ("--config", "--selection", "--mode", "--weights"):
            given[flag[2:]] = (
                str(RELEASE / value[len(RELEASE_PLACEHOLDER) :])
                if value.startswith(RELEASE_PLACEHOLDER)
                else value
            )
    return words[2], given


def trained_parameters(name: str, given: dict[str, str], sets: dict[str, Any]) -> int:
    """The trained weights the command runs: a DBox network's parameters per checkpoint used."""
    if name == "dbox-guard":  # the shipped p-z per-set checkpoints, with an inference step
        given = {"config": "p-z", "selection": "per-set"}
    elif name != "dbox":
        return 0
    from odmd_bench_baselines import dbox
    from odmd_bench_baselines.dbox.model import DBox

    per_network = sum(p.numel() for p in DBox().parameters())
    files = {
        dbox.resolve_weights(
            ex, given.get("config"), given.get("weights"), given.get("selection", "overall")
        )[0]
        for ex in sets.values()
    }
    return per_network * len(files)


@dataclass
class Run(SpeedRun):
    """One entry's command, ready to time, with the trained parameters it runs.

    The timing is :class:`~odmd_bench.leaderboard.speed.SpeedRun`'s (what ``odmd-bench
    leaderboard speed`` times).
    """

    parameters: int = 0


def _prepare(folder: Path) -> Run | None:
    entry = read_entry(folder)
    name, given = options(entry.meta.command)
    if "weights" in given and not Path(given["weights"]).is_file():
        return None  # the original release's checkpoint is not here
    method = methods.load(name)
    kwargs = given_options(
        method,
        weights=Path(given["weights"]) if "weights" in given else None,
        weights_sha256=None,
        config=given.get("config"),
        selection=given.get("selection"),
        mode=given.get("mode"),
    )
    sets = load_split(entry.split, entry.benchmark)
    return Run(entry.key, method, kwargs, sets, parameters=trained_parameters(name, given, sets))


def test_entries_speed(benchmark: Any) -> None:
    """Every entry once per round, the rounds interleaved, so that a busy machine slows all alike."""
    import torch

    torch.set_num_threads(1)
    runs = [r for r in map(_prepare, OWN) if r is not None]
    skipped = len(OWN) - len(runs)

    for run in runs:  # warm up, and repeat a fast command until a timing takes about 0.2 s
        run.calibrate()

    def one_round() -> None:
        for run in runs:
            run.round()

    benchmark.pedantic(one_round, rounds=ROUNDS, iterations=1, warmup_rounds=1)
    cpu = cpu_model()
    benchmark.extra_info.update({"cpu": cpu, "threads": 1, "rounds": ROUNDS, "skipped": skipped})
    for run in runs:
        rate = run.examples / run.best
        benchmark.extra_info[run.key] = {
            "examples": run.examples,
            "best_s": run.best,
            "repeats": run.repeats,
            "examples_per_s": rate,
            "parameters": run.parameters,
        }
        print(
            f"{run.key}: parameters {run.parameters}, {rate:.4g} examples/s ({run.examples} in {run.best:.4f} s)"
        )
    print(f"on {cpu}, one thread, best of {ROUNDS} interleaved rounds; {skipped} entries skipped")
