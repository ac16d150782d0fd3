"""train-dbox on several processes (torchrun, gloo on the CPU) and on CUDA.

The multi-process tests start ``python -m torch.distributed.run`` with two processes of
``tests/dbox_worker.py`` (the real command line, tiny validation sets, injected faults),
one thread each; the subprocess call has a timeout, so a hang fails the test instead of
stalling the suite.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from odmd_bench_baselines.dbox import distributed  # noqa: E402
from odmd_bench_baselines.dbox.train import train  # noqa: E402

from odmd_bench import Examples, UsageError  # noqa: E402
from odmd_bench import generate as generate_examples  # noqa: E402

WORKER = Path(__file__).with_name("dbox_worker.py")
#: Seconds a torchrun launch may take before the test fails (a hang, not a slow machine).
LAUNCH_TIMEOUT_S = 300


def _tiny_val() -> dict[str, Examples]:  # the worker's validation sets
    return {
        "normal": generate_examples(64, "odmd", "normal", 100),
        "camera": generate_examples(64, "odmd", "camera", 101),
    }


def _args(out: Path, steps: int, val_every: int, *more: str) -> list[str]:
    return [
        "train-dbox", "--config", "p", "--steps", str(steps), "--val-every", str(val_every),
        "--seed", "3", "--device", "cpu", "--threads", "1", "--out", str(out), *more,
    ]  # fmt: skip


def _torchrun(
    args: list[str], tmp_path: Path, nproc: int = 2, **env: str
) -> subprocess.CompletedProcess[str]:
    environ = {k: v for k, v in os.environ.items() if k not in distributed.TORCHRUN_VARIABLES}
    environ.update(env, OMP_NUM_THREADS="1", PYTHONWARNINGS="error")
    cmd = [
        sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", str(nproc),
        "--monitor-interval", "0.1", str(WORKER), *args,
    ]  # fmt: skip
    return subprocess.run(
        cmd, capture_output=True, text=True, timeout=LAUNCH_TIMEOUT_S, env=environ, cwd=tmp_path, check=False
    )


def _one_process(out: Path, steps: int, val_every: int, **kw: object) -> None:
    """The same run in this process (no torchrun): the reference."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        train(
            "p",
            steps,
            out,
            seed=3,
            device="cpu",
            val_every=val_every,
            val_sets=_tiny_val(),
            progress=None,
            **kw,
        )  # type: ignore[arg-type]
    finally:
        torch.set_num_threads(threads)


def _final(out: Path) -> dict[str, np.ndarray]:
    state = torch.load(out / "last.pt", weights_only=True)
    return {k: v.cpu().numpy() for k, v in state["model"].items()}  # a CUDA run saves CUDA tensors


def _rel_diff(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> float:
    assert a.keys() == b.keys()
    return max(float(np.abs(a[k] - b[k]).max() / max(np.abs(b[k]).max(), 1e-12)) for k in a)


@pytest.fixture(scope="module")
def reference_30(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One process, 30 steps of 512, seed 3: the issue's command without torchrun."""
    out = tmp_path_factory.mktemp("one") / "run"
    _one_process(out, 30, 15)
    return out


def test_two_processes_train_the_weights_of_one_and_only_process_0_writes(
    reference_30: Path, tmp_path: Path
) -> None:
    out = tmp_path / "two"
    watch = tmp_path / "writes"
    watch.mkdir()
    done = _torchrun(_args(out, 30, 15), tmp_path, DBOX_TEST_WRITES=str(watch))
    assert done.returncode == 0, done.stderr[-3000:]
    assert "best step" in done.stdout and done.stdout.count("weights:") == 1  # process 0 reports
    two, one = _final(out), _final(reference_30)
    assert _rel_diff(two, one) <= 1e-4
    record = json.loads((out / "dbox_p.json").read_text())
    assert record["world_size"] == 2 and record["batch_per_process"] == 256
    assert record["backend"] == "gloo" and record["devices"] == ["cpu", "cpu"]
    one_record = json.loads((reference_30 / "dbox_p.json").read_text())
    assert one_record["world_size"] == 1 and one_record["backend"] is None
    assert record["best_step"] == one_record["best_step"]
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in reference_30.iterdir())
    logged = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    reference = [json.loads(line) for line in (reference_30 / "log.jsonl").read_text().splitlines()]
    assert [e["step"] for e in logged] == [15, 30]
    for got, want in zip(logged, reference, strict=True):  # the global batch's loss, not process 0's
        assert got["loss"] == pytest.approx(want["loss"], rel=1e-4)
    # Every write under --out came from process 0: its list shows the watch works.
    assert json.loads((watch / "writes.0.json").read_text())
    assert json.loads((watch / "writes.1.json").read_text()) == []


def test_a_killed_process_stops_the_run_and_it_resumes_on_another_number(tmp_path: Path) -> None:
    """A killed process stops the run, and the run resumes on another number of processes.

    Process 1 is killed after step 6 of 8 (the state holds step 4): every process stops and
    torchrun names the one that died; resumed on one process, the run ends with the weights
    of one process's whole run.
    """
    out = tmp_path / "run"
    done = _torchrun(_args(out, 8, 4, "--batch-size", "64"), tmp_path, DBOX_TEST_FAIL="1:6:kill")
    assert done.returncode != 0
    assert "Signal 9 (SIGKILL)" in done.stderr and "rank      : 1" in done.stderr, done.stderr[-3000:]
    assert torch.load(out / "last.pt", weights_only=True)["step"] == 4
    _one_process(out, 8, 4, resume=True, batch_size=64)
    whole = tmp_path / "whole"
    _one_process(whole, 8, 4, batch_size=64)
    assert _rel_diff(_final(out), _final(whole)) <= 1e-4


@pytest.mark.slow
def test_a_hanging_process_stops_the_others_after_the_collective_timeout(tmp_path: Path) -> None:
    done = _torchrun(
        _args(tmp_path / "run", 40, 20, "--dist-timeout", "3"), tmp_path, DBOX_TEST_FAIL="1:3:hang"
    )
    assert done.returncode != 0
    assert "process 0 of 2 stopped at step 4" in done.stderr, done.stderr[-3000:]
    assert "within 3 s (--dist-timeout)" in done.stderr
    assert "internal error" not in done.stderr  # a report, not a traceback


@pytest.mark.slow
def test_a_run_resumes_on_more_processes(tmp_path: Path) -> None:
    """Interrupted on one process after its check at step 4, resumed on two: one process's weights."""
    whole = tmp_path / "whole"
    _one_process(whole, 8, 4)
    out = tmp_path / "run"

    class Stop(Exception):
        pass

    def stop(step: int, loss: float) -> None:
        if step == 6:
            raise Stop

    with pytest.raises(Stop):
        _one_process(out, 8, 4, on_step=stop)
    assert torch.load(out / "last.pt", weights_only=True)["step"] == 4
    done = _torchrun([*_args(out, 8, 4), "--resume"], tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert torch.load(out / "last.pt", weights_only=True)["step"] == 8
    assert _rel_diff(_final(out), _final(whole)) <= 1e-4


def test_launch_variables_are_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    assert distributed.launch_ranks({}) == (0, 1, 0)
    assert distributed.launch_ranks({"RANK": "1", "WORLD_SIZE": "2", "LOCAL_RANK": "1"}) == (1, 2, 1)
    with pytest.raises(UsageError) as e:
        distributed.launch_ranks({"RANK": "2", "WORLD_SIZE": "2", "LOCAL_RANK": "x"})
    assert e.value.problems == ["LOCAL_RANK='x' is not an integer"]
    with pytest.raises(UsageError) as e:
        distributed.launch_ranks({"RANK": "2", "WORLD_SIZE": "2", "LOCAL_RANK": "0"})
    assert e.value.problems == ["RANK=2 must be in [0, 1] for WORLD_SIZE=2"]
    with pytest.raises(UsageError) as e:
        distributed.launch_ranks({"RANK": "0"})
    assert e.value.problems == ["LOCAL_RANK is not set", "WORLD_SIZE is not set"]
    monkeypatch.setenv("RANK", "0")
    monkeypatch.setenv("LOCAL_RANK", "0")
    monkeypatch.setenv("WORLD_SIZE", "4")
    with pytest.raises(UsageError, match="invalid training options") as e:
        train("p", 2, "unused", device="cpu", val_sets=_tiny_val(), batch_size=3, progress=None)
    assert e.value.problems == ["the batch of 3 cannot be split among 4 processes"]


def test_shards_are_the_batch_once_in_order() -> None:
    for n in (1, 7, 512):
        for world in range(1, min(n, 9) + 1):
            rows = [list(range(n))[distributed.shard(n, r, world)] for r in range(world)]
            assert sum(rows, []) == list(range(n))
            assert max(map(len, rows)) - min(map(len, rows)) <= 1


def test_bf16_trains_on_the_cpu(tmp_path: Path) -> None:
    """Mixed precision runs its own forward pass: the first loss is fp32's to bf16 rounding."""
    opts = {"seed": 0, "device": "cpu", "val_sets": _tiny_val(), "batch_size": 32, "progress": None}
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        bf16 = train("p", 4, tmp_path / "bf16", val_every=2, precision="bf16", **opts)  # type: ignore[arg-type]
        fp32 = train("p", 1, tmp_path / "fp32", val_every=1, **opts)  # type: ignore[arg-type]
    finally:
        torch.set_num_threads(threads)
    assert np.isfinite(bf16.losses).all() and bf16.losses[0] != fp32.losses[0]
    assert bf16.losses[0] == pytest.approx(fp32.losses[0], rel=2e-2)
    record = json.loads((tmp_path / "bf16" / "dbox_p.json").read_text())
    assert record["precision"] == "bf16" and record["steps_done"] == 4
    with pytest.raises(UsageError, match="unknown precision 'fp8'"):
        train("p", 2, tmp_path / "x", precision="fp8", **opts)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="cannot resume"):  # the precision is part of a run
        train("p", 4, tmp_path / "bf16", val_every=2, resume=True, **opts)  # type: ignore[arg-type]


def test_a_torchrun_restart_resumes_and_the_batch_size_is_an_option(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A restart by torchrun (--max-restarts: the same command again) continues the run in --out."""
    import odmd_bench_baselines.dbox.train as train_module
    from click.testing import CliRunner

    from odmd_bench.cli.main import cli

    monkeypatch.setattr(train_module.odmd_bench, "load_split", lambda *a, **k: _tiny_val())
    out = tmp_path / "run"
    args = _args(out, 4, 2, "--batch-size", "16")
    first = CliRunner().invoke(cli, args)
    assert first.exit_code == 0, first.output
    record = json.loads((out / "dbox_p.json").read_text())
    assert record["batch_size"] == 16 and "--batch-size 16" in record["command"]
    again = CliRunner().invoke(cli, args)
    assert again.exit_code == 2 and "--resume" in again.output  # a new launch must say so
    monkeypatch.setenv("TORCHELASTIC_RESTART_COUNT", "1")
    restarted = CliRunner().invoke(cli, args)
    assert restarted.exit_code == 0, restarted.output
    assert "best step" in restarted.output  # the finished run, continued: nothing left to do


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
@pytest.mark.parametrize("precision", ["fp32", "bf16"])
@pytest.mark.parametrize("data", ["host", "device"])
def test_a_few_steps_on_cuda(tmp_path: Path, precision: str, data: str) -> None:
    result = train(
        "p", 20, tmp_path / "run", seed=0, device="cuda", val_every=10, val_sets=_tiny_val(),
        batch_size=512, progress=None, precision=precision, data=data,
    )  # fmt: skip
    losses = np.array(result.losses)
    assert len(losses) == 20 and np.isfinite(losses).all() and losses[-5:].mean() < losses[:3].mean()
    record = json.loads((tmp_path / "run" / "dbox_p.json").read_text())
    assert record["devices"][0].startswith("cuda:0") and record["precision"] == precision
    assert record["data"] == data
    if data == "device":  # another stream: nothing to compare step by step with the CPU's
        return
    cpu = train(
        "p", 1, tmp_path / "cpu", seed=0, device="cpu", val_every=1, val_sets=_tiny_val(),
        batch_size=512, progress=None,
    )  # fmt: skip
    assert result.losses[0] == pytest.approx(cpu.losses[0], rel=1e-2 if precision == "bf16" else 1e-4)
