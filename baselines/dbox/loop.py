"""The DBox training loop of one process: steps, validation checks, the model kept.

:func:`run` is the loop of :func:`.train.train` in each process, its options checked and
its folder claimed: draw the step's batch (host or device), train on this process's rows
of it, and at every check validate (process 0), keep the best model overall and per set,
and write the run's files (:mod:`.run_files`). Under torchrun the processes meet at the
gradient average, the loss readings and the CPU-time sum (:mod:`.distributed`).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import torch
from odmd_bench_baselines.dbox.configs import TrainConfig, get_config
from odmd_bench_baselines.dbox.device_data import DeviceBatches
from odmd_bench_baselines.dbox.distributed import DistContext, all_sum, collective_failure, shard
from odmd_bench_baselines.dbox.graphs import GraphedStep
from odmd_bench_baselines.dbox.loading import load_failure, load_model
from odmd_bench_baselines.dbox.model import DBox
from odmd_bench_baselines.dbox.recipe import (
    TrainStep,
    batch_tensors,
    learning_rate,
    make_optimizer,
    validation_scores,
)
from odmd_bench_baselines.dbox.run_files import (
    append_log,
    load_state,
    save_state,
    write_record,
    write_weights,
)
from odmd_bench_baselines.dbox.weights import per_set_path

import odmd_bench
from odmd_bench import DataError, Examples, StorageError, UsageError, file_sha256


@dataclass
class TrainResult:
    """What a training run produced.

    Attributes:
        out: output folder.
        weights: path of the best model's state dict.
        best_step: step of the best validation score.
        best_scores: validation scores of the best model.
        losses: training loss of every step run in this call.
        steps_done: steps completed (over all resumed calls).
    """

    out: Path
    weights: Path
    best_step: int
    best_scores: dict[str, float]
    losses: list[float] = field(default_factory=list)
    steps_done: int = 0


class _Progress:
    r"""A one-line progress report: ``\r``-rewritten on a terminal, a line per update otherwise."""

    def __init__(self, stream: TextIO | None, total: int, every: int) -> None:
        self.stream = stream
        self.total = total
        self.every = every
        self.tty = bool(stream is not None and stream.isatty())
        self.t0 = time.perf_counter()
        self.start_step = 0

    def update(self, step: int, loss: float, lr: float, val: str, force: bool = False) -> None:
        if self.stream is None or (not force and step % self.every and step != self.total):
            return
        done = step - self.start_step
        rate = done / max(time.perf_counter() - self.t0, 1e-9)
        eta = (self.total - step) / rate if rate > 0 else float("nan")
        line = (
            f"step {step}/{self.total} ({100 * step / self.total:.1f}%) loss {loss:.5f} lr {lr:.2e} "
            f"{val} | {rate:.1f} steps/s, eta {eta / 60:.1f} min"
        )
        if self.tty:
            self.stream.write("\r" + line[:200].ljust(120))
            if step == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()


def run(
    ctx: DistContext,
    cfg: TrainConfig,
    steps: int,
    out: Path,
    seed: int,
    every: int,
    resume: bool,
    schedule: str,
    min_lr_ratio: float,
    lr: float,
    init: str | Path | None,
    val_sets: Mapping[str, Examples],
    batch_size: int,
    command: str | None,
    progress: TextIO | None,
    progress_every: int,
    on_step: Callable[[int, float], None] | None,
    precision: str,
    state_path: Path,
    weights_path: Path,
    data: str,
    cuda_graph: bool,
) -> TrainResult:
    """The training loop of :func:`.train.train`, in each process, its options checked."""
    dev = ctx.device
    if data == "auto":
        data = "device" if dev.type == "cuda" else "host"
    val_names = list(val_sets)
    settings = {
        "config": cfg.name,
        "steps": steps,
        "seed": seed,
        "schedule": schedule,
        "min_lr_ratio": min_lr_ratio,
        "lr": lr,
        "init": None if init is None else {"path": str(init), "sha256": file_sha256(init)},
        "batch_size": batch_size,
        "val_every": every,
        "val_sets": val_names,
        "val_benchmark": cfg.val_benchmark,
    }
    if precision != "fp32":  # absent from the settings of runs before precision was one
        settings["precision"] = precision
    if data != "host":  # likewise: runs before data on the device was one drew on the host
        settings["data"] = data
    launch = {**launch_record(ctx, batch_size), "cuda_graph": cuda_graph}
    model = DBox(generator=torch.Generator().manual_seed(seed)).to(dev)
    if init is not None:
        start, _ = load_model(init)
        model.load_state_dict(start.state_dict())
    optimizer = make_optimizer(model, lr)
    rng = np.random.default_rng(seed)
    step = 0
    best: dict[str, Any] = {
        "step": -1,
        "scores": {"all": math.inf},
        "per_set": {},
        "cpu_s": 0.0,
        "wall_s": 0.0,
    }
    if resume:
        state = load_state(state_path)
        # Runs saved before val_benchmark was a setting used the config's own.
        state["settings"].setdefault("val_benchmark", get_config(cfg.name).val_benchmark)
        if state["settings"] != settings:
            diff = [
                f"{k}: run has {state['settings'].get(k)!r}, asked for {settings.get(k)!r}"
                for k in {**state["settings"], **settings}
                if state["settings"].get(k) != settings.get(k)
            ]
            raise UsageError(f"cannot resume {out}: the options differ from the run's", diff)
        try:
            model.load_state_dict(state["model"])
            optimizer.load_state_dict(state["optimizer"])
            rng.bit_generator.state = json.loads(state["rng"])
            step = int(state["step"])
            best = json.loads(state["best"])
            best.setdefault("per_set", {})
            best.setdefault("cpu_s", 0.0)
            best.setdefault("wall_s", 0.0)
        except Exception as e:  # torch, json and numpy raise many kinds for a damaged state
            raise DataError(
                f"{state_path} is not a usable DBox training state ({load_failure(e)}); "
                "start the run again in a new --out"
            ) from None
        if not 0 <= step <= steps or not isinstance(best, dict) or not isinstance(best.get("scores"), dict):
            raise DataError(f"{state_path} is not a usable DBox training state (step {step} of {steps})")
    if ctx.is_main:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise StorageError(
                f"cannot create the run folder {out}: {e.strerror or type(e).__name__}; give --out a folder "
                "you can write"
            ) from None

    net: torch.nn.Module = TrainStep(model, precision)
    if ctx.distributed:
        from torch.nn.parallel import DistributedDataParallel

        try:  # DDP checks that every process holds the same parameters, and starts from process 0's
            net = DistributedDataParallel(net, device_ids=[dev] if dev.type == "cuda" else None)
        except RuntimeError as e:
            raise collective_failure(ctx, step, e) from None
    rows = shard(batch_size, ctx.rank, ctx.world_size)
    batches = (
        DeviceBatches(cfg.preset, cfg.perturbation, cfg.formulation, seed, dev) if data == "device" else None
    )
    # Each process's loss is its rows' share of the global batch's mean (sum / B, times N
    # because DDP averages the N gradients): exact for any split of the batch. One process
    # keeps the plain mean, the arithmetic of runs before DDP.
    share = ctx.world_size / batch_size
    bar = _Progress(progress if ctx.is_main else None, steps, progress_every)
    bar.start_step = step
    val_text = "val All -" if best["step"] < 0 else _val_text(best)
    losses: list[float] = []
    pending: list[torch.Tensor] = []  # losses not yet read (on a GPU: read at each report)
    cpu_base, wall0 = best["cpu_s"], time.perf_counter() - best["wall_s"]
    cpu0 = time.process_time()
    model.train()
    graphed: GraphedStep | None = None
    while step < steps:
        rate = learning_rate(step, steps, schedule, min_lr_ratio, lr)
        if graphed is None:
            for group in optimizer.param_groups:
                group["lr"] = rate
        if batches is not None:  # step t's batch depends on (seed, t) alone
            x, y = batches.batch(step, batch_size, rows)
        else:
            batch = odmd_bench.generate(batch_size, cfg.preset, cfg.perturbation, rng)
            x, y, _ = batch_tensors(batch, cfg.formulation, dev, rows)
        if cuda_graph:
            if graphed is None:  # captured at the first step, with its batch for the warm-up
                graphed = GraphedStep(net, optimizer, x, y, capture=True)
            loss = graphed.step(x, y, rate)
        else:
            try:
                err = (net(x) - y).abs()
                loss = err.sum() * share if ctx.distributed else err.mean()
                optimizer.zero_grad(set_to_none=True)
                loss.backward()  # DDP averages the gradients over the processes here
            except RuntimeError as e:
                if ctx.distributed:
                    raise collective_failure(ctx, step + 1, e) from None
                raise
            optimizer.step()
        step += 1
        pending.append(loss.detach())
        check = step % every == 0 or step == steps
        if dev.type == "cpu" or check or step % progress_every == 0:
            for i, v in enumerate(_read_losses(ctx, pending, step)):
                losses.append(v)
                if on_step is not None:
                    on_step(step - len(pending) + 1 + i, v)
            pending.clear()
        value = losses[-1] if losses else math.nan
        if check:
            try:  # the CPU time of every process
                cpu_s = cpu_base + all_sum(ctx, [time.process_time() - cpu0])[0]
            except RuntimeError as e:
                raise collective_failure(ctx, step, e) from None
            if not ctx.is_main:
                continue
            scores = validation_scores(model, val_sets, cfg.formulation, dev)
            best["cpu_s"] = cpu_s
            best["wall_s"] = time.perf_counter() - wall0
            if scores["all"] < best["scores"]["all"]:
                best.update(step=step, scores=scores)
                write_weights(model, weights_path)
            for name in val_names:  # the paper's per-set selection (ODMS, section 4.3)
                kept = best["per_set"].get(name)
                if kept is None or scores[name] < kept["scores"][name]:
                    best["per_set"][name] = {"step": step, "scores": scores}
                    write_weights(model, per_set_path(weights_path, name))
            val_text = f"val All {scores['all']:.3f} " + _val_text(best)
            save_state(state_path, model, optimizer, rng, step, best, settings)
            write_record(weights_path, cfg, settings, best, step, command, launch=launch)
            for name, kept in best["per_set"].items():
                write_record(
                    per_set_path(weights_path, name), cfg, settings, best, step, command, (name, kept), launch
                )
            append_log(out / "log.jsonl", {"step": step, "lr": rate, "loss": value, **scores})
            bar.update(step, value, rate, val_text, force=True)
        elif not pending:
            bar.update(step, value, rate, val_text)
    return TrainResult(
        out=out,
        weights=weights_path,
        best_step=int(best["step"]),
        best_scores=dict(best["scores"]),
        losses=losses,
        steps_done=step,
    )


def _read_losses(ctx: DistContext, pending: list[torch.Tensor], step: int) -> list[float]:
    """The global batch's losses of the ``pending`` steps (one copy from the device)."""
    values = torch.stack(pending)
    if ctx.distributed:
        try:  # each process holds its rows' share; the global mean is their mean
            torch.distributed.all_reduce(values)
        except RuntimeError as e:
            raise collective_failure(ctx, step, e) from None
        values = values / ctx.world_size
    return [float(v) for v in values.tolist()]


def launch_record(ctx: DistContext, batch_size: int) -> dict[str, Any]:
    """How the run was launched, for its record: processes, batch per process, backend, devices."""
    device = str(ctx.device)
    if ctx.device.type == "cuda":
        device += f" ({torch.cuda.get_device_name(ctx.device)})"
    devices = [device]
    if ctx.distributed:
        gathered: list[Any] = [None] * ctx.world_size
        torch.distributed.all_gather_object(gathered, device)
        devices = [str(d) for d in gathered]
    per = sorted(
        {len(range(batch_size)[shard(batch_size, r, ctx.world_size)]) for r in range(ctx.world_size)}
    )
    return {
        "world_size": ctx.world_size,
        "batch_per_process": per[0] if len(per) == 1 else per,
        "backend": ctx.backend,
        "devices": devices,
    }


def _val_text(best: Mapping[str, Any]) -> str:
    return f"(best {best['scores']['all']:.3f} @ {best['step']})"
