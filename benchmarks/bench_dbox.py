r"""DBox speed: a training step and inference, against the original release's forward pass.

Run (and keep the result, named by commit and CPU, as ``docs/dbox.md`` says):

    .venv/bin/pytest benchmarks/bench_dbox.py --benchmark-only -p no:randomly \
        --benchmark-columns=min,median,mean,rounds -s \
        --benchmark-json benchmarks/results/<commit>-<cpu>-dbox.json

Each case runs with 1 torch thread and with 2 (this machine's cores):

- ``test_train_step``: one training step as ``train-dbox`` does it: generate 512
  examples (preset odmd, perturbation both), build the f_Rel input, forward,
  L1 loss, backward, Adam.
- ``test_inference``: forward pass on 1,000 examples (input already built), no
  gradients.
- ``impl="plain"`` is ``DBox.forward`` (and its hand-written backward, :mod:`.kernels`),
  what ships: every product a plain torch product; ``impl="reference"`` is
  :func:`odmd_bench_baselines.dbox.model.reference_forward`, the original release's forward
  written as it was (all four gate blocks computed twice per observation, per-step
  slices, ``cat`` before every FC layer) with autograd's backward. Both are measured in
  the same run on the same data, so ``median(reference) / median(plain)`` is the
  speed-up. (Until issue 44 an ``onednn`` case measured an opt-in path through oneDNN's
  private operator, and ``auto`` the default; ``bench_dbox_before_after.py`` compares
  an earlier commit's cases with this one's.)
- ``test_ratio`` prints the ratios from interleaved timings in one process.

The machines are shared: compare numbers from one run only.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from odmd_bench_baselines.dbox.formulations import make_inputs  # noqa: E402
from odmd_bench_baselines.dbox.model import DBox, reference_forward  # noqa: E402
from odmd_bench_baselines.dbox.recipe import make_optimizer  # noqa: E402

import odmd_bench  # noqa: E402

IMPLS = ("plain", "reference")
THREADS = (1, 2)


@pytest.fixture(params=THREADS, ids=lambda t: f"threads{t}")
def threads(request: pytest.FixtureRequest) -> Iterator[int]:
    before = torch.get_num_threads()
    torch.set_num_threads(request.param)
    yield request.param
    torch.set_num_threads(before)


def _forward(model: DBox, impl: str) -> Callable[[torch.Tensor], torch.Tensor]:
    if impl == "reference":
        return lambda x: reference_forward(model, x)
    return model


def _train_step(model: DBox, impl: str) -> Callable[[], float]:
    forward = _forward(model, impl)
    optimizer = make_optimizer(model)
    rng = np.random.default_rng(0)

    def step() -> float:
        batch = odmd_bench.generate(512, "odmd", "both", rng)
        inp = make_inputs(batch, "rel")
        loss = (forward(torch.from_numpy(inp.x)) - torch.from_numpy(inp.target)).abs().mean()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        return float(loss.item())

    return step


def _inference(model: DBox, impl: str) -> Callable[[], torch.Tensor]:
    forward = _forward(model, impl)
    x = torch.from_numpy(make_inputs(odmd_bench.generate(1000, "odmd", "both", 1), "rel").x)

    def run() -> torch.Tensor:
        with torch.no_grad():
            return forward(x)

    return run


@pytest.mark.parametrize("impl", IMPLS)
def test_train_step(benchmark, threads: int, impl: str) -> None:  # type: ignore[no-untyped-def]
    step = _train_step(DBox(generator=torch.Generator().manual_seed(0)), impl)
    step()  # warm-up (allocator, first-call costs)
    benchmark.extra_info.update(threads=threads, impl=impl, batch=512, torch=torch.__version__)
    loss = benchmark.pedantic(step, rounds=15, iterations=1)
    assert np.isfinite(loss)


@pytest.mark.parametrize("impl", IMPLS)
def test_inference(benchmark, threads: int, impl: str) -> None:  # type: ignore[no-untyped-def]
    run = _inference(DBox(generator=torch.Generator().manual_seed(0)), impl)
    run()
    benchmark.extra_info.update(threads=threads, impl=impl, examples=1000, torch=torch.__version__)
    out = benchmark.pedantic(run, rounds=20, iterations=1)
    assert out.shape == (1000,)


def test_ratio(threads: int) -> None:
    """Every implementation against the reference, interleaved in one process (median of 9 rounds each)."""
    model = DBox(generator=torch.Generator().manual_seed(0))
    cases = {
        "train step": {impl: _train_step(model, impl) for impl in IMPLS},
        "inference 1000": {impl: _inference(model, impl) for impl in IMPLS},
    }
    for name, fns in cases.items():
        times: dict[str, list[float]] = {impl: [] for impl in IMPLS}
        for fn in fns.values():
            fn()
        for _ in range(9):
            for impl, fn in fns.items():
                t0 = time.perf_counter()
                fn()
                times[impl].append(time.perf_counter() - t0)
        ms = {impl: float(np.median(t)) * 1e3 for impl, t in times.items()}
        ratios = ", ".join(f"{i} {ms[i]:.1f} ms ({ms['reference'] / ms[i]:.2f}x)" for i in IMPLS[:-1])
        print(f"\n{name}, {threads} thread(s): reference {ms['reference']:.1f} ms; {ratios}")
        assert all(v > 0 for v in ms.values())
