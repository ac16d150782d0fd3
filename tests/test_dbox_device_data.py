"""DBox training batches generated on the training device (``train-dbox --data device``).

The torch generator must be the numpy generator's arithmetic (fed numpy's draws it gives
generator version 1's examples bit for bit), a step's batch must depend on (seed, step)
alone, and a run on it must resume and split over processes as the host stream does.
The CUDA tests run where torch sees a GPU and are skipped elsewhere.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from odmd_bench_baselines.dbox import device_data  # noqa: E402
from odmd_bench_baselines.dbox.formulations import make_inputs  # noqa: E402
from odmd_bench_baselines.dbox.train import train  # noqa: E402
from test_dbox_distributed import _args, _final, _rel_diff, _tiny_val, _torchrun  # noqa: E402

import odmd_bench  # noqa: E402
from odmd_bench import UsageError  # noqa: E402
from odmd_bench.data.config import get_preset  # noqa: E402
from odmd_bench.data.generator import as_rng  # noqa: E402

CUDA = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")


def _arrays(ex: odmd_bench.Examples) -> dict[str, torch.Tensor]:
    return {k: torch.from_numpy(getattr(ex, k)) for k in ("boxes", "camera", "depth")}


@pytest.mark.parametrize("preset", ["odmd", "odms"])
@pytest.mark.parametrize("perturbation", ["normal", "camera", "object", "both"])
def test_the_torch_generator_is_the_numpy_generator_bit_for_bit(preset: str, perturbation: str) -> None:
    n = 300  # > 1: replacement has donors
    want = odmd_bench.generate(n, preset, perturbation, rng=11)
    draws = device_data.numpy_draws(n, get_preset(preset), perturbation, as_rng(11))
    got = device_data.geometry(draws, get_preset(preset))
    for name in ("boxes", "camera", "depth"):
        assert np.array_equal(got[name].numpy(), getattr(want, name)), name
    if perturbation in ("object", "both"):
        assert want.extras["replaced"].any()  # the replacement was exercised


@pytest.mark.parametrize("formulation", ["rel", "abs"])
def test_network_batches_are_make_inputs(formulation: str) -> None:
    ex = odmd_bench.generate(200, "odmd", "both", rng=2)
    x, y = device_data.network_batch(_arrays(ex), formulation)
    want = make_inputs(ex, formulation)
    assert x.dtype == torch.float32 and y.dtype == torch.float32
    np.testing.assert_allclose(x.numpy(), want.x, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(y.numpy(), want.target, rtol=1e-6)
    rows = slice(50, 120)
    xr, yr = device_data.network_batch(_arrays(ex), formulation, rows)
    assert torch.equal(xr, x[rows]) and torch.equal(yr, y[rows])


def test_a_steps_batch_depends_on_the_seed_and_the_step_alone() -> None:
    cpu = torch.device("cpu")
    a = device_data.DeviceBatches("odmd", "both", "rel", 3, cpu)
    b = device_data.DeviceBatches("odmd", "both", "rel", 3, cpu)
    x5, y5 = a.batch(5, 64)
    a.batch(6, 64)
    assert torch.equal(b.batch(5, 64)[0], x5) and torch.equal(a.batch(5, 64)[1], y5)  # any order
    x_rows, _ = b.batch(5, 64, slice(32, 64))  # a process's rows are its share of the global batch
    assert torch.equal(x_rows, x5[32:])
    assert not torch.equal(a.batch(6, 64)[0], x5)
    assert not torch.equal(device_data.DeviceBatches("odmd", "both", "rel", 4, cpu).batch(5, 64)[0], x5)
    seeds = {device_data.step_seed(s, t) for s in range(20) for t in range(50)}
    assert len(seeds) == 1000 and all(0 <= s < 2**63 for s in seeds)


def test_the_device_stream_has_the_generators_distribution() -> None:
    """Other draws, the same distribution: the depths' quantiles agree with numpy's stream."""
    n = 100_000  # the 5 % quantile of depth lies in a thin tail: it needs this many
    cpu = torch.device("cpu")
    gen = torch.Generator().manual_seed(0)
    draws = device_data.draw(n, get_preset("odmd"), "both", gen, cpu)
    got = device_data.geometry(draws, get_preset("odmd"))
    want = odmd_bench.generate(n, "odmd", "both", rng=0)
    q = [0.05, 0.25, 0.5, 0.75, 0.95]
    np.testing.assert_allclose(np.quantile(got["depth"].numpy(), q), np.quantile(want.depth, q), rtol=0.01)
    widths = got["boxes"][:, :, 2].numpy()
    np.testing.assert_allclose(np.quantile(widths, q), np.quantile(want.boxes[:, :, 2], q), rtol=0.02)
    share = float(draws.replace[0].float().mean())  # type: ignore[index]
    assert abs(share - get_preset("odmd").replace_prob) < 0.01


def _run(out: Path, steps: int, val_every: int = 2, **kw: object) -> object:
    """A run on device data in this process, one thread, batches of 64."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return train(
            "p", steps, out, seed=3, device="cpu", val_every=val_every, val_sets=_tiny_val(), batch_size=64,
            progress=None, data="device", **kw,
        )  # type: ignore[arg-type]  # fmt: skip
    finally:
        torch.set_num_threads(threads)


def test_a_device_data_run_resumes_on_the_same_stream(tmp_path: Path) -> None:
    whole = tmp_path / "whole"
    _run(whole, 6)
    record = json.loads((whole / "dbox_p.json").read_text())
    assert record["data"] == "device" and record["steps_done"] == 6

    class Stop(Exception):
        pass

    def stop(step: int, loss: float) -> None:
        if step == 5:
            raise Stop

    out = tmp_path / "run"
    with pytest.raises(Stop):
        _run(out, 6, on_step=stop)
    assert torch.load(out / "last.pt", weights_only=True)["step"] == 4
    _run(out, 6, resume=True)
    assert all(
        np.array_equal(a, b) for a, b in zip(_final(out).values(), _final(whole).values(), strict=True)
    )
    with pytest.raises(UsageError, match="cannot resume") as e:  # the data source is part of a run
        train("p", 6, out, seed=3, device="cpu", val_every=2, val_sets=_tiny_val(), batch_size=64,
              progress=None, resume=True, data="host")  # fmt: skip
    assert e.value.problems == ["data: run has 'device', asked for None"]
    with pytest.raises(UsageError, match="invalid training options") as e:
        train("p", 2, tmp_path / "y", device="cpu", val_sets=_tiny_val(), progress=None, data="gpu")
    assert e.value.problems == ["unknown data source 'gpu'; expected auto or one of host, device"]


def test_two_processes_on_device_data_train_the_weights_of_one(tmp_path: Path) -> None:
    one = tmp_path / "one"
    _run(one, 6, val_every=3)
    two = tmp_path / "two"
    done = _torchrun(_args(two, 6, 3, "--data", "device", "--batch-size", "64"), tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert _rel_diff(_final(two), _final(one)) <= 1e-4
    record = json.loads((two / "dbox_p.json").read_text())
    assert record["world_size"] == 2 and record["data"] == "device" and "--data device" in record["command"]


@CUDA
def test_the_generator_on_cuda_is_the_cpus_arithmetic() -> None:
    n = 512
    cfg = get_preset("odmd")
    draws = device_data.numpy_draws(n, cfg, "both", as_rng(7))
    on_gpu = device_data.Draws(
        draws.u.cuda(), draws.camera_noise.cuda(), draws.box_noise.cuda(),  # type: ignore[union-attr]
        tuple(t.cuda() for t in draws.replace),  # type: ignore[arg-type, union-attr]
    )  # fmt: skip
    got = device_data.geometry(on_gpu, cfg)
    want = odmd_bench.generate(n, "odmd", "both", rng=7)
    for name in ("boxes", "camera", "depth"):
        np.testing.assert_allclose(got[name].cpu().numpy(), getattr(want, name), rtol=1e-12, atol=1e-15)
    batches = device_data.DeviceBatches("odmd", "both", "rel", 0, torch.device("cuda"))
    x, y = batches.batch(9, 512)
    assert x.is_cuda and torch.equal(batches.batch(9, 512)[0], x) and torch.isfinite(y).all()


@CUDA
def test_dbox_predicts_on_cuda_as_on_the_cpu() -> None:
    from odmd_bench_baselines import dbox

    ex = odmd_bench.generate(3000, "odmd", "both", rng=1).without_truth()
    cpu = dbox.predict(ex, config="p")
    gpu = dbox.predict(ex, config="p", device="cuda")
    np.testing.assert_allclose(gpu, cpu, rtol=1e-4)


def _steps_eager(
    model: torch.nn.Module, batches: list[tuple[torch.Tensor, torch.Tensor]], rates: list[float]
) -> torch.optim.Optimizer:
    """Plain training steps (the loop without a graph) with a fresh optimizer, returned."""
    from odmd_bench_baselines.dbox.recipe import make_optimizer

    opt = make_optimizer(model)
    for (x, y), rate in zip(batches, rates, strict=True):
        for group in opt.param_groups:
            group["lr"] = rate
        loss = (model(x) - y).abs().mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
    return opt


def test_the_graphed_steps_warm_up_is_undone() -> None:
    """The step a CUDA graph replays, run eagerly: the warm-up leaves no trace in the weights."""
    from odmd_bench_baselines.dbox.graphs import GraphedStep, plain_optimizer_state
    from odmd_bench_baselines.dbox.model import DBox
    from odmd_bench_baselines.dbox.recipe import make_optimizer

    cpu = torch.device("cpu")
    source = device_data.DeviceBatches("odmd", "both", "rel", 0, cpu)
    batches = [source.batch(t, 32) for t in range(5)]
    rates = [1e-3, 9e-4, 8e-4, 7e-4, 6e-4]
    plain = DBox(generator=torch.Generator().manual_seed(0))
    graphed_model = DBox(generator=torch.Generator().manual_seed(0))
    _steps_eager(plain, batches, rates)
    opt = make_optimizer(graphed_model)
    step = GraphedStep(graphed_model, opt, *batches[0], capture=False)
    losses = [float(step.step(x, y, rate)) for (x, y), rate in zip(batches, rates, strict=True)]
    for a, b in zip(plain.parameters(), graphed_model.parameters(), strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-6)  # float32 lr tensor
    assert losses[0] > losses[-1]
    state = plain_optimizer_state(opt)
    assert all(isinstance(g["lr"], float) and g["capturable"] is False for g in state["param_groups"])
    assert float(next(iter(opt.state.values()))["step"]) == 5  # the warm-up's steps undone


def test_cuda_graph_is_refused_where_it_cannot_run(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="invalid training options") as e:
        train("p", 2, tmp_path / "r", device="cpu", val_sets=_tiny_val(), progress=None, cuda_graph=True)
    assert e.value.problems == [
        "--cuda-graph runs one process on CUDA in fp32 (--device cuda, --precision fp32, no torchrun)"
    ]


@CUDA
def test_a_graphed_run_on_cuda_trains_the_weights_of_an_eager_one(tmp_path: Path) -> None:
    opts = {"seed": 0, "device": "cuda", "val_every": 10, "val_sets": _tiny_val(), "progress": None}
    eager = train("p", 30, tmp_path / "eager", **opts)  # type: ignore[arg-type]
    graphed = train("p", 30, tmp_path / "graph", cuda_graph=True, **opts)  # type: ignore[arg-type]
    assert _rel_diff(_final(tmp_path / "graph"), _final(tmp_path / "eager")) <= 1e-3
    np.testing.assert_allclose(graphed.losses, eager.losses, rtol=1e-3)
    record = json.loads((tmp_path / "graph" / "dbox_p.json").read_text())
    assert record["cuda_graph"] is True and record["data"] == "device"

    class Stop(Exception):
        pass

    def stop(step: int, loss: float) -> None:
        if step == 15:  # read at the check of step 20, before it: the state holds step 10
            raise Stop

    resumed = tmp_path / "resumed"
    with pytest.raises(Stop):
        train("p", 30, resumed, cuda_graph=True, on_step=stop, **opts)  # type: ignore[arg-type]
    assert torch.load(resumed / "last.pt", weights_only=True)["step"] == 10
    train("p", 30, resumed, cuda_graph=True, resume=True, **opts)  # type: ignore[arg-type]
    assert _rel_diff(_final(resumed), _final(tmp_path / "eager")) <= 1e-3


def test_a_graphed_step_continues_a_run_that_has_adams_state() -> None:
    """Captured mid-run (a resumed run): the warm-up's undoing restores Adam's moments and step count."""
    from odmd_bench_baselines.dbox.graphs import GraphedStep
    from odmd_bench_baselines.dbox.model import DBox

    source = device_data.DeviceBatches("odmd", "both", "rel", 1, torch.device("cpu"))
    batches = [source.batch(t, 32) for t in range(6)]
    rates = [1e-3] * 6
    plain = DBox(generator=torch.Generator().manual_seed(2))
    _steps_eager(plain, batches, rates)
    resumed = DBox(generator=torch.Generator().manual_seed(2))
    opt = _steps_eager(resumed, batches[:3], rates[:3])  # the run before its interruption
    step = GraphedStep(resumed, opt, *batches[3], capture=False)
    for (x, y), rate in zip(batches[3:], rates[3:], strict=True):
        step.step(x, y, rate)
    for a, b in zip(plain.parameters(), resumed.parameters(), strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-6)
    assert float(next(iter(opt.state.values()))["step"]) == 6
