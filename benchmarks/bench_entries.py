r"""Speed and size of every leaderboard entry of this repository's methods (the entries' ``speed`` and ``parameters``).

Run (one core: one torch thread, OpenBLAS to one thread), with the boards' data in place
(``odmd-bench leaderboard check`` builds it; the release checkpoint's entry needs the
original release at ``../shared/odmd-original`` or ``ODMD_ORIGINAL``):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 .venv/bin/pytest benchmarks/bench_entries.py \
        --benchmark-only -p no:randomly --benchmark-columns=min,median -s

Each entry's own command (``odmd-bench baseline NAME --benchmark B --split test ...``) is
read from its ``entry.yaml``, and the method's ``run`` is timed on every set of the board's
test split with exactly those options, as ``baseline`` calls it (the sets loaded before,
the CSV not written): examples per second = examples / best time of the rounds
(``examples_per_s`` in ``extra_info``). ``parameters`` is the number of trained weights the
command uses: a DBox network's parameters times the checkpoints it runs (four with
per-set selection); 0 for the methods without trained weights. ``-s`` prints, per entry,
the two lines to put in its ``entry.yaml``.
"""

from __future__ import annotations

import os
import platform
import shlex
from pathlib import Path
from typing import Any

import pytest

from odmd_bench import load_split, methods
from odmd_bench.cli.options import given_options
from odmd_bench.leaderboard import discover, read_entry

REPO = Path(__file__).resolve().parents[1]
ROUNDS = 5
RELEASE = Path(os.environ.get("ODMD_ORIGINAL") or REPO.parent / "shared" / "odmd-original")
#: an entry's command names the user's copy of the original release so
RELEASE_PLACEHOLDER = "ODMD/"
OWN = [f for f in discover(REPO / "leaderboard") if read_entry(f).meta.code.startswith("baselines/")]


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else what :mod:`platform` says."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.partition(":")[2].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def options(command: str) -> tuple[str, dict[str, str]]:
    """(method name, its options) of an entry's ``odmd-bench baseline`` command."""
    words = shlex.split(command)
    if any(w.startswith("(") for w in words):
        words = words[: next(i for i, w in enumerate(words) if w.startswith("("))]
    assert words[:2] == ["odmd-bench", "baseline"], command
    given = {}
    for flag, value in zip(words[3::2], words[4::2], strict=False):
        if flag in ("--config", "--selection", "--mode", "--weights"):
            given[flag[2:]] = str(RELEASE / value[len(RELEASE_PLACEHOLDER) :]) if value.startswith(RELEASE_PLACEHOLDER) else value
    return words[2], given


def trained_parameters(name: str, given: dict[str, str], sets: dict[str, Any]) -> int:
    """The trained weights the command runs: a DBox network's parameters per checkpoint used."""
    if name != "dbox":
        return 0
    from odmd_bench_baselines import dbox
    from odmd_bench_baselines.dbox.model import DBox

    per_network = sum(p.numel() for p in DBox().parameters())
    files = {
        dbox.resolve_weights(ex, given.get("config"), given.get("weights"), given.get("selection", "overall"))[0]
        for ex in sets.values()
    }
    return per_network * len(files)


@pytest.mark.parametrize("folder", OWN, ids=[f"{f.parent.name}/{f.name}" for f in OWN])
def test_entry_speed(benchmark: Any, folder: Path) -> None:
    entry = read_entry(folder)
    name, given = options(entry.meta.command)
    if "weights" in given and not Path(given["weights"]).is_file():
        pytest.skip(f"the original release's checkpoint is not at {given['weights']}")
    if name == "dbox":
        import torch

        torch.set_num_threads(1)
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

    def run() -> None:
        for ex in sets.values():
            method.run(ex, **kwargs)

    benchmark.pedantic(run, rounds=ROUNDS, iterations=1, warmup_rounds=1)
    n = sum(len(ex) for ex in sets.values())
    rate = n / benchmark.stats.stats.min
    params = trained_parameters(name, given, sets)
    benchmark.extra_info.update(
        {"examples": n, "examples_per_s": rate, "parameters": params, "cpu": cpu_model(), "threads": 1}
    )
    print(
        f"\n{entry.key}: parameters: {params}\n  speed: {{examples_per_second: {rate:.4g}, "
        f"device: {cpu_model()!r}, command: ...}}"
    )
