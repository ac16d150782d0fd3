"""Training DBox on freshly generated ODMD examples.

The paper's recipe (L1 loss on the formulation's target, Adam, learning rate 1e-3,
batches of 512 new examples per step, n = 10) with one change that lets a short run
come close to the paper's 10-million-step result: the learning rate follows a cosine
decay from 1e-3 to 1e-3 * ``min_lr_ratio`` over the run (``schedule="cosine"``;
``schedule="constant"`` is the paper's). The model kept is the one with the best
validation score ("All": the mean over the validation sets of their mean percent
error), checked every ``val_every`` steps (the paper checks every hundredth of
training); per set, the model with the best val score on that set is kept too (the
paper's per-set selection). Test sets are never looked at.

Everything random comes from the seed: a ``numpy.random.Generator`` (PCG64) for the
data and a ``torch.Generator`` for the initial weights, so a run on the CPU with the
same seed and thread count gives the same weights, and a resumed run continues
exactly where the interrupted one was (model, optimizer, step, data generator state,
validation history are all in ``last.pt``). With ``data="device"`` (the default on
CUDA) the batches are drawn by the same generator written in torch, on the training
device (:mod:`.device_data`): step t's batch from a generator seeded with (seed, t).

Under ``torchrun`` the run is one model trained by several processes with
DistributedDataParallel (:mod:`.distributed`): every process draws the step's whole
batch from the same generator and trains on its own rows of it, so the global batch of
a step is the same examples whatever the number of processes, and the weights equal a
one-process run's to float rounding. Process 0 alone validates and writes; a run
resumes with any number of processes.

A second, lower-rate cycle can start from an earlier run's best weights (``init``,
with a lower peak ``lr``): the optimizer starts fresh, the schedule is a new cosine.

Files in the output folder:

- ``last.pt``: the resumable training state (written atomically at every check).
- ``dbox_<config>.pt``: the best model's state dict (on val All), in the original
  release's key layout, float32; ``dbox_<config>.json`` beside it records config, seed,
  steps, command, CPU and wall time, the CPU kernels used, validation scores and the
  file's SHA-256 (``weights_sha256``, checked whenever the file is loaded).
- ``dbox_<config>.<set>.pt`` (and ``.json``): the paper's per-set selection, the model
  with the best val score on that set (section 4.3: "the number of training iterations
  for each test set using the best corresponding validation performance").
- ``log.jsonl``: one line per validation check.
- ``claim.json`` and ``.claim.lock``: the run's claim on the folder (:mod:`.claim`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TextIO

import torch
from odmd_bench_baselines.dbox.claim import claimed
from odmd_bench_baselines.dbox.configs import (
    CONFIGS as CONFIGS,  # the training configurations, named here too
)
from odmd_bench_baselines.dbox.configs import get_config
from odmd_bench_baselines.dbox.device_data import DATA_SOURCES
from odmd_bench_baselines.dbox.distributed import DEFAULT_TIMEOUT_S, cleanup, finish, launch_ranks, setup
from odmd_bench_baselines.dbox.distributed import resolve_device as _resolve_device
from odmd_bench_baselines.dbox.loop import TrainResult, run
from odmd_bench_baselines.dbox.recipe import BATCH_SIZE, LEARNING_RATE, PRECISIONS, SCHEDULES
from odmd_bench_baselines.dbox.run_files import STATE_FILE

import odmd_bench
from odmd_bench import Examples, UsageError, get_benchmark

__all__ = ["CONFIGS", "TrainResult", "resolve_device", "train"]


def resolve_device(device: str) -> torch.device:
    """``auto`` (CUDA when available, else CPU), ``cpu`` or ``cuda``."""
    return _resolve_device(device)


def train(
    config: str,
    steps: int,
    out: str | Path,
    seed: int = 0,
    device: str = "auto",
    val_every: int | None = None,
    resume: bool = False,
    schedule: str = "cosine",
    min_lr_ratio: float = 0.01,
    lr: float = LEARNING_RATE,
    init: str | Path | None = None,
    val_sets: Mapping[str, Examples] | None = None,
    data_dir: str | Path | None = None,
    batch_size: int = BATCH_SIZE,
    val_benchmark: str | None = None,
    command: str | None = None,
    progress: TextIO | None = sys.stderr,
    progress_every: int = 50,
    on_step: Callable[[int, float], None] | None = None,
    precision: str = "fp32",
    dist_timeout: float = DEFAULT_TIMEOUT_S,
    data: str = "auto",
    cuda_graph: bool = False,
) -> TrainResult:
    """Train DBox in one of the paper's configurations; keep the best model by validation.

    Args:
        config: ``p``, ``ns``, ``abs``, ``p-z``, ``ns-z`` or ``abs-z`` (see :data:`CONFIGS`).
        steps: total training steps (over all resumed calls).
        out: output folder (created); refuses to overwrite an earlier run unless
            ``resume``.
        seed: seed of the data stream and of the initial weights.
        device: ``auto``, ``cpu`` or ``cuda``.
        val_every: steps between validation checks (default ``steps // 100``, at
            least 1, as the paper's "every hundredth of training").
        resume: continue from ``out/last.pt`` (same config, steps, seed, schedule).
        schedule: ``cosine`` (default) or ``constant`` (the paper's).
        min_lr_ratio: final learning rate of the cosine schedule relative to ``lr``.
        lr: peak learning rate (1e-3, the paper's).
        init: start from these weights (a checkpoint in the original layout, e.g.
            an earlier run's best) instead of the seeded random initialisation; the
            optimizer starts fresh. For a second, lower-rate cosine cycle.
        val_sets: the validation sets; default: all sets of the validation
            benchmark's ``val`` split, read from the data folder.
        data_dir: data folder for the default validation sets.
        batch_size: examples per step (512 in the paper).
        val_benchmark: the benchmark whose ``val`` split selects the model (default:
            the config's, :data:`CONFIGS`). The training data do not depend on it: the
            same seed and options give the same trajectory, selected on other data
            (the paper selects its Table 1 rows on ODMD val, its Table 2 rows on ODMS).
        command: the command line to record beside the weights.
        progress: stream for the progress line (None: silent).
        progress_every: steps between progress lines when not on a terminal.
        on_step: called with (step, loss) after every step (for tests; on CUDA in
            bursts, at each progress line, since a per-step loss would copy from the GPU).
        precision: ``fp32`` or ``bf16`` (automatic mixed precision, :data:`PRECISIONS`).
        dist_timeout: under torchrun, seconds a collective operation waits for the
            other processes before the run stops with an error.
        data: where the batches are generated: ``host`` (numpy on the CPU, the stream
            the shipped weights were trained on), ``device`` (the same generator in
            torch on the training device, :mod:`.device_data`: no copy per step, another
            random stream) or ``auto`` (``device`` on CUDA, ``host`` on the CPU).
        cuda_graph: capture the training step in a CUDA graph and replay it
            (:mod:`.graphs`; one process, CUDA, fp32): the same arithmetic with one
            launch per step instead of hundreds.

    Under torchrun (``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK`` set) the processes train one
    model together (see the module's docstring); ``batch_size`` is the global batch.

    Returns:
        :class:`TrainResult` (in every process; only process 0's ``best_*`` are measured).
    """
    cfg = get_config(config)
    if val_benchmark is not None and val_benchmark != cfg.val_benchmark:
        cfg = dataclasses.replace(cfg, val_benchmark=get_benchmark(val_benchmark).name)
    problems = []
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        problems.append(f"steps must be a positive integer, got {steps!r}")
    if schedule not in SCHEDULES:
        problems.append(f"unknown schedule {schedule!r}; expected one of {', '.join(SCHEDULES)}")
    if init is not None and not Path(init).is_file():
        problems.append(f"--init weights not found: {init}")
    if not 0.0 < lr <= 1.0:
        problems.append(f"lr must be in (0, 1], got {lr}")
    if not 0.0 <= min_lr_ratio <= 1.0:
        problems.append(f"min_lr_ratio must be in [0, 1], got {min_lr_ratio}")
    if val_every is not None and val_every < 1:
        problems.append(f"val_every must be a positive integer, got {val_every}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        problems.append(f"seed must be a non-negative integer, got {seed!r}")
    if precision not in PRECISIONS:
        problems.append(f"unknown precision {precision!r}; expected one of {', '.join(PRECISIONS)}")
    if data != "auto" and data not in DATA_SOURCES:
        problems.append(f"unknown data source {data!r}; expected auto or one of {', '.join(DATA_SOURCES)}")
    rank, world, _ = launch_ranks()
    if batch_size < world:
        problems.append(f"the batch of {batch_size} cannot be split among {world} processes")
    if cuda_graph and (world > 1 or precision != "fp32" or _resolve_device(device).type != "cuda"):
        problems.append(
            "--cuda-graph runs one process on CUDA in fp32 (--device cuda, --precision fp32, no torchrun)"
        )
    if problems:
        raise UsageError("invalid training options", problems)
    every = val_every if val_every is not None else max(steps // 100, 1)
    _resolve_device(device)  # a missing GPU is a usage error before the processes meet
    out = Path(out)
    state_path = out / STATE_FILE
    weights_path = out / f"dbox_{cfg.name}.pt"

    def check_folder() -> None:
        if state_path.exists() and not resume:
            raise UsageError(
                f"{out} already holds a training run ({STATE_FILE}); pass --resume to continue it "
                "or choose another --out"
            )
        if resume and not state_path.exists():
            raise UsageError(f"nothing to resume: {state_path} does not exist")
        if not resume and out.is_dir():
            held = sorted(
                f.name for f in out.iterdir() if f.name.startswith("dbox_") or f.name == "log.jsonl"
            )
            if held:
                raise UsageError(
                    f"{out} already holds weights or a log ({', '.join(held[:5])}{', ...' if len(held) > 5 else ''}), "
                    "which a new run would replace; choose an empty or new --out"
                )

    # Process 0 (which alone writes) holds the folder while it trains (.claim): of two runs
    # started together into one folder, one trains and the other is refused, naming the first.
    hold: contextlib.AbstractContextManager[None] = contextlib.nullcontext()
    if rank == 0:
        hold = claimed(out, resume=resume, check=check_folder, command=command)
    else:
        check_folder()
    with hold:
        if val_sets is None:
            val_sets = odmd_bench.load_split("val", cfg.val_benchmark, data_dir)
        val_names = list(val_sets)
        if not val_names:
            raise UsageError("no validation sets")

        owned = not torch.distributed.is_initialized()
        ctx = setup(device, dist_timeout)
        try:
            result = run(
                ctx, cfg, steps, out, seed, every, resume, schedule, min_lr_ratio, lr, init, val_sets,
                batch_size, command, progress, progress_every, on_step, precision, state_path, weights_path,
                data, cuda_graph,
            )  # fmt: skip
            if owned:
                # Every process leaves together: one that tore its group down while process 0
                # was still validating and writing could abort at exit (gloo's threads).
                finish(ctx)
            return result
        finally:
            if owned:
                cleanup(ctx)
