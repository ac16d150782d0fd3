r"""DBox on a GPU against the CPU: training steps per second and prediction throughput.

Run on a machine with a CUDA GPU (the CUDA cases are skipped elsewhere):

    pytest benchmarks/bench_dbox_gpu.py --benchmark-only -p no:randomly -s \
        --benchmark-json benchmarks/results/<commit>-<gpu>-dbox-gpu.json

``test_train_steps``: :data:`STEPS` steps of config ``p`` (global batch 512, one
process), in this process, with one validation check at the end on two sets of 128
examples; ``extra_info["steps_per_s"]`` is steps over the record's ``wall_time_s`` (the
loop and its check, not torch's start-up). Cases: the CPU with torch's default threads
and host data (what ``train-dbox --device cpu`` runs); CUDA with host data (numpy on the
CPU, copied every step); CUDA with device data (``--data device``, the default there) in
fp32 and bf16.

``test_predict``: ``dbox.predict`` of :data:`N_PREDICT` examples (config ``p``) on the
CPU and on CUDA; examples per second = N / best time.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

import odmd_bench  # noqa: E402

STEPS = 400
N_PREDICT = 100_000
CUDA = torch.cuda.is_available()

CASES = [
    ("cpu", "host", "fp32"),
    ("cuda", "host", "fp32"),
    ("cuda", "device", "fp32"),
    ("cuda", "device", "bf16"),
    ("cuda", "device", "graph"),  # fp32, the step replayed from a CUDA graph (--cuda-graph)
]


def _val() -> dict[str, odmd_bench.Examples]:
    return {
        "normal": odmd_bench.generate(128, "odmd", "normal", 100),
        "camera": odmd_bench.generate(128, "odmd", "camera", 101),
    }


@pytest.mark.parametrize(("device", "data", "precision"), CASES, ids=["-".join(c) for c in CASES])
def test_train_steps(benchmark, device: str, data: str, precision: str, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    if device == "cuda" and not CUDA:
        pytest.skip("no CUDA device")
    from odmd_bench_baselines.dbox.train import train

    steps = STEPS if device == "cuda" else STEPS // 4
    runs = iter(range(10**6))
    rates: list[float] = []

    def run() -> None:
        out = tmp_path / f"run{next(runs)}"
        train(
            "p", steps, out, seed=0, device=device, val_every=steps, val_sets=_val(), progress=None,
            precision="fp32" if precision == "graph" else precision, data=data, cuda_graph=precision == "graph",
        )  # fmt: skip
        record = json.loads((out / "dbox_p.json").read_text())
        rates.append(steps / record["wall_time_s"])

    run()  # warm-up: CUDA context, kernels, allocator
    benchmark.pedantic(run, rounds=2, iterations=1)
    name = torch.cuda.get_device_name() if device == "cuda" else f"CPU, {torch.get_num_threads()} threads"
    benchmark.extra_info.update(steps=steps, steps_per_s=round(max(rates), 1), device_name=name)
    print(f"\n{device} {data} {precision}: {max(rates):.1f} steps/s ({name})")


@pytest.mark.parametrize("device", ["cpu", "cuda"])
def test_predict(benchmark, device: str) -> None:  # type: ignore[no-untyped-def]
    if device == "cuda" and not CUDA:
        pytest.skip("no CUDA device")
    from odmd_bench_baselines import dbox

    ex = odmd_bench.generate(N_PREDICT, "odmd", "both", rng=0).without_truth()
    dbox.predict(ex.subset(slice(0, 1000)), config="p", device=device)  # warm-up: weights verified and loaded
    benchmark.pedantic(lambda: dbox.predict(ex, config="p", device=device), rounds=3, iterations=1)
    rate = N_PREDICT / benchmark.stats.stats.min
    benchmark.extra_info["examples_per_s"] = round(rate)
    print(f"\npredict on {device}: {rate:,.0f} examples/s")
