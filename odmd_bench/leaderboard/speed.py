"""A method's speed as the entries record it: examples per second, one thread, the processor named.

``odmd-bench leaderboard speed NAME --benchmark B --split S [--option K=V ...]`` measures
what ``odmd-bench baseline NAME ...`` does (the method's ``run`` on every set of the
board, each set in one call, the sets loaded before, no CSV written), on one thread
(``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS`` and ``MKL_NUM_THREADS`` at 1, torch's
threads at 1), and records the best of :data:`ROUNDS` rounds, each repeated until it
takes :data:`MIN_TIMED_S`. This is how the shipped entries' ``speed`` was measured
(``benchmarks/bench_entries.py`` uses the same :class:`SpeedRun`; it interleaves the
rounds of every entry). The figure is written with the CPU model, and the command that
measured it, as an entry's ``speed`` (``leaderboard add --speed FILE``).

Timing by hand rather than with pytest-benchmark: the command is part of the package
(pytest is a development tool), and what it needs is the best of a few rounds.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from odmd_bench.errors import UsageError, ValidationError

#: Rounds timed; the best is kept.
ROUNDS = 5
#: A fast method's run is repeated until one timing takes about this long (seconds).
MIN_TIMED_S = 0.2
#: The thread variables the measurement sets to 1 (BLAS, OpenMP), before numpy is loaded.
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: Significant digits kept of a rate (the spread between rounds is larger than the rest).
DIGITS = 3


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else what :mod:`platform` says."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.partition(":")[2].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown processor"


def one_thread() -> bool:
    """Whether this process runs BLAS and OpenMP on one thread (the variables were set at start)."""
    return all(os.environ.get(v) == "1" for v in THREAD_VARIABLES)


@dataclass
class SpeedRun:
    """A method's run on a board's sets, ready to time.

    Attributes:
        key: what it is (an entry, or the method's name).
        method: the loaded :class:`~odmd_bench.methods.Method`.
        kwargs: its options.
        sets: ``{set: Examples}``.
        best: the best seconds per run so far.
        repeats: runs per timing.
    """

    key: str
    method: Any
    kwargs: dict[str, Any]
    sets: Mapping[str, Any]
    best: float = float("inf")
    repeats: int = 1

    @property
    def examples(self) -> int:
        """Examples in one run (every set)."""
        return sum(len(ex) for ex in self.sets.values())

    def __call__(self) -> None:
        """One run: the method on every set."""
        for ex in self.sets.values():
            self.method.run(ex, **self.kwargs)

    def seconds(self) -> float:
        """Seconds per run, ``repeats`` runs timed together (a fast run is too short to time alone)."""
        start = time.perf_counter()
        for _ in range(self.repeats):
            self()
        return (time.perf_counter() - start) / self.repeats

    def calibrate(self) -> None:
        """Warm up, and repeat a fast run until a timing takes about :data:`MIN_TIMED_S`."""
        self.repeats = max(1, min(1000, round(MIN_TIMED_S / max(self.seconds(), 1e-6))))

    def round(self) -> None:
        """Time one round, keeping the best."""
        self.best = min(self.best, self.seconds())

    @property
    def rate(self) -> float:
        """Examples per second of the best round."""
        return self.examples / self.best


def limit_torch_threads() -> None:
    """One torch thread, where the method loaded torch (torch is never imported here for it)."""
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)


def rounded_rate(rate: float) -> int | float:
    """A rate to :data:`DIGITS` significant digits (a whole number from 100 up)."""
    from math import floor, log10

    if rate <= 0:
        return rate
    value = round(rate, DIGITS - 1 - floor(log10(rate)))
    return int(value) if value >= 100 else value


def measure(
    name: str,
    options: Mapping[str, Any],
    benchmark: str,
    split: str,
    *,
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    rounds: int = ROUNDS,
) -> dict[str, Any]:
    """The speed of ``odmd-bench baseline NAME`` with ``options`` on a board's sets.

    Returns:
        The entry's ``speed``: ``examples_per_second`` (:data:`DIGITS` significant
        digits), ``device`` (the CPU model) and ``command`` (this measurement's command).

    Raises:
        UsageError: The method is not installed, or takes an option it is given.
    """
    from odmd_bench import methods
    from odmd_bench.leaderboard.add import baseline_command
    from odmd_bench.leaderboard.board import load_board_data

    method = methods.load(name)
    refused = [k for k in options if not method.accepts(k)]
    if refused:
        raise UsageError(f"method {name!r} takes no option {', '.join(refused)}")
    sets = load_board_data(benchmark, split, data_dir, original)
    run = SpeedRun(name, method, dict(options), sets)
    run()  # the first run loads what the method loads (torch, weights)
    limit_torch_threads()
    run.calibrate()
    for _ in range(rounds):
        run.round()
    command = baseline_command(name, options, benchmark, split).replace(
        "odmd-bench baseline", "odmd-bench leaderboard speed", 1
    )
    command = command.rsplit(" -o ", 1)[0]
    return {"examples_per_second": rounded_rate(run.rate), "device": cpu_model(), "command": command}


def read_speed(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A speed file written by ``leaderboard speed -o FILE``, checked as an entry's ``speed``.

    Raises:
        ValidationError: It cannot be read, or is not a speed (every problem named).
    """
    from odmd_bench.documents import MAX_DOCUMENT_BYTES
    from odmd_bench.leaderboard.rules import speed_problems

    title = f"{path} is not a speed file (write one with `odmd-bench leaderboard speed ... -o FILE`)"
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_DOCUMENT_BYTES + 1)
        data = json.loads(raw) if len(raw) <= MAX_DOCUMENT_BYTES else None
    except (OSError, ValueError) as e:
        why = e.strerror if isinstance(e, OSError) else "not JSON"
        raise ValidationError(title, [f"it cannot be read ({why})"]) from None
    problems = speed_problems(data) if data is not None else ["it is larger than a speed file can be"]
    if problems or not isinstance(data, dict):  # speed_problems accepts mappings only
        raise ValidationError(title, problems)
    return data


def speed_text(speed: Mapping[str, Any]) -> str:
    """The speed as the lines of an entry's ``speed`` (YAML)."""
    return "speed:\n" + "".join(
        f"  {k}: {json.dumps(v) if isinstance(v, str) else v}\n" for k, v in speed.items()
    )


__all__ = [
    "DIGITS",
    "MIN_TIMED_S",
    "ROUNDS",
    "THREAD_VARIABLES",
    "SpeedRun",
    "cpu_model",
    "limit_torch_threads",
    "measure",
    "one_thread",
    "read_speed",
    "rounded_rate",
    "speed_text",
]
