"""``odmd-bench train-dbox``: train the DBox network (torch is imported inside the command only).

A plug-in command: registered in the entry-point group ``odmd_bench.commands``.
"""

from __future__ import annotations

import shlex
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
from odmd_bench_baselines.dbox.weights import CONFIGS

from odmd_bench import BENCHMARKS
from odmd_bench.cli.options import FiniteFloatRange, data_dir_option


def config_option(**kwargs: Any) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The ``--config`` option: one of the paper's six DBox configurations."""
    return click.option("--config", "config", type=click.Choice(CONFIGS), **kwargs)


@click.command(name="train-dbox")
@config_option(
    default="p",
    show_default=True,
    help="p: perturbations, f_Rel (the paper's best); ns: no perturbation; abs: f_Abs; "
    "p-z, ns-z, abs-z: the same with z-only motion (ODMS preset).",
)
@click.option(
    "--steps", type=click.IntRange(min=1), default=40_000, show_default=True, help="Training steps."
)
@click.option(
    "--seed", type=click.IntRange(min=0), default=0, show_default=True, help="Seed of data and weights."
)
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto", show_default=True)
@click.option(
    "--val-every",
    type=click.IntRange(min=1),
    default=None,
    help="Steps between validation checks (default: a hundredth of --steps).",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    required=True,
    help="Output folder (weights, resumable state last.pt, log.jsonl).",
)
@click.option("--resume", is_flag=True, help="Continue the run in --out from its last checkpoint.")
@click.option(
    "--schedule",
    type=click.Choice(["cosine", "constant"]),
    default="cosine",
    show_default=True,
    help="Learning rate: cosine decay from 1e-3 to 1e-5, or the paper's constant 1e-3.",
)
@click.option(
    "--lr",
    type=FiniteFloatRange(min=0.0, min_open=True, max=1.0),
    default=1e-3,
    show_default=True,
    help="Peak learning rate (the paper's 1e-3).",
)
@click.option(
    "--init",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Start from these weights (original layout, e.g. an earlier run's dbox_p.pt) "
    "for a second, lower-rate cosine cycle.",
)
@click.option(
    "--threads",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="CPU threads for torch (0: torch's default). Results are reproducible for a given count on a given kind of CPU.",
)
@click.option(
    "--val-benchmark",
    type=click.Choice(list(BENCHMARKS)),
    default=None,
    help="Benchmark whose val split selects the model [default: odmd-v1 for p, ns, abs; "
    "odms-detection for the z-axis configurations]. The training data do not depend on it.",
)
@click.option(
    "--batch-size",
    type=click.IntRange(min=1),
    default=512,
    show_default=True,
    help="Examples per step, over all processes (the paper's 512); see docs/dbox.md for the learning rate.",
)
@click.option(
    "--precision",
    type=click.Choice(["fp32", "bf16"]),
    default="fp32",
    show_default=True,
    help="bf16: the forward pass in automatic mixed precision (bfloat16 products; meant for GPUs).",
)
@click.option(
    "--data",
    type=click.Choice(["auto", "host", "device"]),
    default="auto",
    show_default=True,
    help="Where the batches are generated: host (numpy on the CPU: the stream the shipped weights were "
    "trained on), device (the same generator in torch on --device: no copy per step, another random "
    "stream); auto: device on CUDA, host on the CPU.",
)
@click.option(
    "--cuda-graph",
    is_flag=True,
    help="Capture the training step in a CUDA graph and replay it: one launch per step instead of "
    "hundreds (one process, --device cuda, fp32).",
)
@click.option(
    "--dist-timeout",
    type=FiniteFloatRange(min=0.0, min_open=True),
    default=600.0,
    show_default=True,
    help="Under torchrun: seconds a process waits for the others before the run stops with an error.",
)
@data_dir_option
def train_dbox(
    config: str,
    steps: int,
    seed: int,
    device: str,
    val_every: int | None,
    out: Path,
    resume: bool,
    schedule: str,
    lr: float,
    init: Path | None,
    threads: int,
    val_benchmark: str | None,
    batch_size: int,
    precision: str,
    dist_timeout: float,
    data: str,
    cuda_graph: bool,
    data_dir: Path | None,
) -> None:
    """Train DBox on freshly generated examples; keep the best model by validation.

    Prints a progress line (loss, latest and best validation score). The best model
    is written to OUT/dbox_CONFIG.pt (original key layout) with a JSON record beside it.

    Under torchrun (torchrun --nproc_per_node N --no-python odmd-bench train-dbox ...)
    N processes train one model with DistributedDataParallel (gloo on the CPU, nccl on
    CUDA), each on its share of the same global batch of 512; process 0 writes.
    """
    import os

    import torch  # a missing torch is reported by the command line with the extra to install
    from odmd_bench_baselines.dbox.train import train

    if threads:
        torch.set_num_threads(threads)
    restarts = os.environ.get("TORCHELASTIC_RESTART_COUNT", "0")
    if not resume and restarts.isdigit() and int(restarts) > 0 and (out / "last.pt").exists():
        resume = True  # torchrun restarted the processes (--max-restarts): continue the run

    # The canonical command that reproduces this run (every option spelt out).
    args = ["odmd-bench", "train-dbox", "--config", config, "--steps", str(steps), "--seed", str(seed)]
    args += ["--val-every", str(val_every)] if val_every is not None else []
    args += ["--schedule", schedule, "--lr", f"{lr:g}"] + (["--init", str(init)] if init else [])
    args += ["--val-benchmark", val_benchmark] if val_benchmark is not None else []
    args += ["--batch-size", str(batch_size)] if batch_size != 512 else []
    args += ["--threads", str(threads), "--device", device, "--precision", precision]
    args += ["--data", data] if data != "auto" else []
    args += ["--cuda-graph"] if cuda_graph else []
    args += ["--out", str(out)]
    args += ["--resume"] if resume else []
    command = shlex.join(args)
    result = train(
        config,
        steps,
        out,
        seed=seed,
        device=device,
        val_every=val_every,
        resume=resume,
        schedule=schedule,
        lr=lr,
        init=init,
        data_dir=data_dir,
        val_benchmark=val_benchmark,
        command=command,
        progress=sys.stderr,
        precision=precision,
        dist_timeout=dist_timeout,
        batch_size=batch_size,
        data=data,
        cuda_graph=cuda_graph,
    )
    from odmd_bench_baselines.dbox.distributed import launch_ranks, leave

    rank, world, _ = launch_ranks()
    if rank == 0:  # process 0 reports; the others did not validate
        scores = ", ".join(f"{k} {v:.3f}" for k, v in result.best_scores.items())
        click.echo(f"best step {result.best_step}: val mean percent error {scores}")
        click.echo(f"weights: {result.weights}")
    if world > 1:  # under torchrun: done, without the C++ runtime's teardown (see leave)
        leave()


@click.command(name="select-dbox")
@click.argument("runs", nargs=-1, required=True, type=click.Path(file_okay=False, path_type=Path))
@config_option(required=True, help="The configuration the runs trained.")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    required=True,
    help="Folder for the chosen checkpoints and records (e.g. baselines/dbox/weights).",
)
@data_dir_option
def select_dbox(runs: tuple[Path, ...], config: str, out: Path, data_dir: Path | None) -> None:
    """Choose among several train-dbox runs of one configuration, on val only.

    The overall checkpoint is the run with the lowest best val All; each per-set
    checkpoint is the run with the lowest best val score on that set (ties: the run
    given first). Every candidate is hash-checked and its recorded val scores are
    measured again on the runs' val split; the chosen files are copied with their
    records, which list every candidate and its score.
    """
    from odmd_bench_baselines.dbox.select import select_runs, verify_scores, write_selection

    import odmd_bench

    command = shlex.join(
        ["odmd-bench", "select-dbox", *map(str, runs), "--config", config, "--out", str(out)]
    )
    selection = select_runs(runs, config)
    benchmark = selection.candidates["all"][0].record.get("val_benchmark")
    if not isinstance(benchmark, str) or benchmark not in BENCHMARKS:
        raise odmd_bench.DataError(f"the runs name no known val benchmark ({benchmark!r})")
    n = verify_scores(selection, odmd_bench.load_split("val", benchmark, data_dir))
    click.echo(f"measured the val scores of {n} checkpoints again on {benchmark} val: as recorded")
    write_selection(selection, out, command)
    for key, cand in selection.chosen.items():
        others = ", ".join(f"{c.score:.3f}" for c in selection.candidates[key])
        click.echo(f"{key:>8}: {cand.run} (val {cand.score:.3f}; candidates {others})")
