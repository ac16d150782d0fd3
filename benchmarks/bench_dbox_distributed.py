r"""``train-dbox`` on one and on two processes (torchrun, gloo, one thread each): steps per second.

Run (and keep the result, named by commit and CPU, as ``docs/dbox.md`` says):

    .venv/bin/pytest benchmarks/bench_dbox_distributed.py --benchmark-only -p no:randomly -s \
        --benchmark-json benchmarks/results/<commit>-<cpu>-dbox-distributed.json

Each case launches ``python -m torch.distributed.run --standalone --nproc_per_node N``
on ``tests/dbox_worker.py`` (the real command line with two tiny validation sets) for
:data:`STEPS` steps of the global batch of 512, ``--threads 1``, config ``p``. The timed
call includes the launch (torch starting in every process); ``extra_info`` holds the
training loop's own rate, ``steps_per_s`` (steps over the record's ``wall_time_s``,
which counts the loop and its two validation checks of 128 examples, not the start-up).
One round each: the machine must be otherwise idle for the numbers to mean anything.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch")

WORKER = Path(__file__).resolve().parents[1] / "tests" / "dbox_worker.py"
STEPS = 300


@pytest.mark.parametrize("nproc", [1, 2], ids=lambda n: f"processes{n}")
def test_train_steps(benchmark, nproc: int, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    env = {k: v for k, v in os.environ.items() if k not in ("RANK", "LOCAL_RANK", "WORLD_SIZE")}
    env["OMP_NUM_THREADS"] = "1"
    runs = iter(range(10**6))
    rates: list[float] = []

    def launch() -> None:
        out = tmp_path / f"run{next(runs)}"
        cmd = [
            sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", str(nproc),
            str(WORKER), "train-dbox", "--config", "p", "--steps", str(STEPS), "--val-every", str(STEPS // 2),
            "--seed", "3", "--device", "cpu", "--threads", "1", "--out", str(out),
        ]  # fmt: skip
        subprocess.run(cmd, check=True, capture_output=True, timeout=1800, env=env)
        record = json.loads((out / "dbox_p.json").read_text())
        assert record["world_size"] == nproc
        rates.append(STEPS / record["wall_time_s"])

    benchmark.pedantic(launch, rounds=1, iterations=1)
    benchmark.extra_info.update(
        steps=STEPS, processes=nproc, threads_per_process=1, steps_per_s=round(rates[-1], 2)
    )
    print(f"\n{nproc} process(es): {rates[-1]:.2f} steps/s (training loop), {STEPS} steps of 512")
