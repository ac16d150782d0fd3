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
import hashlib
import json
import math
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import torch
from odmd_bench_baselines.dbox.claim import claimed
from odmd_bench_baselines.dbox.configs import (
    CONFIGS as CONFIGS,  # the training configurations, named here too
)
from odmd_bench_baselines.dbox.configs import TrainConfig, get_config
from odmd_bench_baselines.dbox.device_data import DATA_SOURCES, DeviceBatches
from odmd_bench_baselines.dbox.distributed import (
    DEFAULT_TIMEOUT_S,
    DistContext,
    all_sum,
    cleanup,
    collective_failure,
    finish,
    launch_ranks,
    setup,
    shard,
)
from odmd_bench_baselines.dbox.distributed import resolve_device as _resolve_device
from odmd_bench_baselines.dbox.graphs import GraphedStep, plain_optimizer_state
from odmd_bench_baselines.dbox.model import DBox, make_inputs, predict_depth, reference_forward, use_onednn
from odmd_bench_baselines.dbox.weights import load_failure, load_model, per_set_path

import odmd_bench
from odmd_bench import (
    DataError,
    Examples,
    StorageError,
    UsageError,
    atomic_path,
    atomic_write,
    file_sha256,
    get_benchmark,
)

BATCH_SIZE = 512
LEARNING_RATE = 1e-3
SCHEDULES = ("cosine", "constant")
#: ``fp32``: float32 throughout; ``bf16``: the forward pass under automatic mixed
#: precision (bfloat16 products), the loss, gradients, Adam and validation in float32.
PRECISIONS = ("fp32", "bf16")
STATE_FILE = "last.pt"


def learning_rate(
    step: int, steps: int, schedule: str, min_lr_ratio: float, peak: float = LEARNING_RATE
) -> float:
    """The learning rate for step ``step`` (0-based) of ``steps``.

    ``cosine``: from ``peak`` (1e-3) down to ``peak * min_lr_ratio`` at the last step;
    ``constant``: ``peak`` throughout (the paper).
    """
    if schedule == "constant":
        return peak
    frac = min(step / max(steps - 1, 1), 1.0)
    low = peak * min_lr_ratio
    return low + 0.5 * (peak - low) * (1.0 + math.cos(math.pi * frac))


def make_optimizer(model: torch.nn.Module, lr: float = LEARNING_RATE) -> torch.optim.Adam:
    """The paper's optimizer, Adam, in PyTorch's fused implementation.

    One kernel for all parameters: the same update rule, equal to rounding, in a third of the time of the
    per-parameter loop on a CPU.
    """
    return torch.optim.Adam(model.parameters(), lr=lr, fused=True)


def resolve_device(device: str) -> torch.device:
    """``auto`` (CUDA when available, else CPU), ``cpu`` or ``cuda``."""
    return _resolve_device(device)


class _Step(torch.nn.Module):
    """The network's training forward pass, in the run's precision (what DDP wraps).

    ``bf16`` runs the original formulation (:func:`reference_forward`: autograd through
    plain torch operations, which autocast casts) under autocast; ``fp32`` the model
    itself, the same arithmetic as a one-process run without this wrapper.
    """

    def __init__(self, model: DBox, precision: str) -> None:
        super().__init__()
        self.model = model
        self.precision = precision

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.precision == "bf16":
            with torch.autocast(x.device.type, dtype=torch.bfloat16):
                return reference_forward(self.model, x).float()
        out: torch.Tensor = self.model(x)
        return out


def batch_tensors(
    examples: Examples, formulation: str, device: torch.device, rows: slice = slice(None)
) -> tuple[torch.Tensor, torch.Tensor, np.ndarray]:
    """Network input (B, n_obs, 7), target (B,) on ``device``, and scale (B,) float64.

    ``rows``: the rows of the batch this process trains on (all by default).
    """
    inp = make_inputs(examples, formulation)
    x = torch.from_numpy(inp.x[rows]).to(device, non_blocking=True)
    y = torch.from_numpy(inp.target[rows]).to(device, non_blocking=True)
    return x, y, inp.scale[rows]


def validation_scores(
    model: DBox, val_sets: Mapping[str, Examples], formulation: str, device: torch.device
) -> dict[str, float]:
    """Mean percent error per set, and ``all``: the mean of the sets' means."""
    scores: dict[str, float] = {}
    for name, ex in val_sets.items():
        pred = predict_depth(model, ex, formulation, device)
        scores[name] = float(np.mean(np.abs(ex.depth - pred) / ex.depth * 100.0))
    scores["all"] = float(np.mean([scores[n] for n in val_sets]))
    return scores


def original_state_dict(model: DBox) -> dict[str, torch.Tensor]:
    """The model's parameters in the original release's layout, float32, on the CPU."""
    return {k: v.detach().to("cpu", torch.float32).clone() for k, v in model.state_dict().items()}


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
            result = _run(
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


def _run(
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
    """The training loop of :func:`train`, in each process, its options checked."""
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
    launch = {**_launch_record(ctx, batch_size), "cuda_graph": cuda_graph}
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
        state = _load_state(state_path)
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

    net: torch.nn.Module = _Step(model, precision)
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
                _write_weights(model, weights_path)
            for name in val_names:  # the paper's per-set selection (ODMS, section 4.3)
                kept = best["per_set"].get(name)
                if kept is None or scores[name] < kept["scores"][name]:
                    best["per_set"][name] = {"step": step, "scores": scores}
                    _write_weights(model, per_set_path(weights_path, name))
            val_text = f"val All {scores['all']:.3f} " + _val_text(best)
            _save_state(state_path, model, optimizer, rng, step, best, settings)
            _write_record(weights_path, cfg, settings, best, step, command, launch=launch)
            for name, kept in best["per_set"].items():
                _write_record(
                    per_set_path(weights_path, name), cfg, settings, best, step, command, (name, kept), launch
                )
            _append_log(out / "log.jsonl", {"step": step, "lr": rate, "loss": value, **scores})
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


def _launch_record(ctx: DistContext, batch_size: int) -> dict[str, Any]:
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


def _append_log(path: Path, entry: Mapping[str, Any]) -> None:
    """Add one line to the log, dropping lines of checks a resumed run repeats."""
    lines = path.read_text(encoding="utf-8").splitlines() if path.exists() else []
    kept = [line for line in lines if json.loads(line)["step"] < entry["step"]]
    with atomic_write(path, "w") as fh:
        fh.write("".join(line + "\n" for line in kept) + json.dumps(dict(entry)) + "\n")


def _write_weights(model: DBox, path: Path) -> None:
    with atomic_write(path) as fh:
        torch.save(original_state_dict(model), fh)


def _write_record(
    weights: Path,
    cfg: TrainConfig,
    settings: Mapping[str, Any],
    best: Mapping[str, Any],
    step: int,
    command: str | None,
    per_set: tuple[str, Mapping[str, Any]] | None = None,
    launch: Mapping[str, Any] | None = None,
) -> None:
    """The JSON record beside ``weights``; ``per_set``: (set, its best) for a per-set checkpoint.

    ``launch``: processes, batch per process, backend and devices (:func:`_launch_record`).
    """
    chosen = best if per_set is None else per_set[1]
    selection: dict[str, Any] = (
        {"kind": "overall", "on": "all"}
        if per_set is None
        else {"kind": "per-set", "on": per_set[0], "run_on": per_set[0]}
    )
    if per_set is None:
        selection["per_set_steps"] = {k: v["step"] for k, v in best["per_set"].items()}
    record = {
        "config": asdict(cfg),
        **{k: v for k, v in settings.items() if k != "config"},
        "steps_done": step,
        "best_step": chosen["step"],
        "selection": selection,
        "val_benchmark": cfg.val_benchmark,
        "val_mean_percent_error": chosen["scores"],
        "cpu_time_s": round(float(best.get("cpu_s", 0.0)), 1),
        "wall_time_s": round(float(best.get("wall_s", 0.0)), 1),
        "command": command,
        "odmd_bench_version": odmd_bench.__version__,
        "generator_version": odmd_bench.GENERATOR_VERSION,
        "torch_version": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "cpu_kernels": "onednn" if use_onednn(True) else "plain",
        "precision": settings.get("precision", "fp32"),
        "data": settings.get("data", "host"),
        **dict(launch or {}),
        "weights_sha256": file_sha256(weights) if weights.exists() else None,
    }
    with atomic_write(weights.with_suffix(".json"), "w") as fh:
        fh.write(json.dumps(record, indent=2) + "\n")


def _save_state(
    path: Path,
    model: DBox,
    optimizer: torch.optim.Optimizer,
    rng: np.random.Generator,
    step: int,
    best: Mapping[str, Any],
    settings: Mapping[str, Any],
) -> None:
    state = {
        "model": model.state_dict(),
        "optimizer": plain_optimizer_state(optimizer),
        "rng": json.dumps(rng.bit_generator.state),
        "step": step,
        "best": json.dumps(best),
        "settings": dict(settings),
    }
    state["digest"] = _state_digest(state)
    with atomic_path(path) as tmp:
        torch.save(state, tmp)


def _state_digest(state: Mapping[str, Any]) -> str:
    """SHA-256 of a training state's contents (tensors by dtype, shape and bytes), without ``digest``.

    torch does not check the bytes of the tensors it loads; a state whose digest differs
    has been damaged since it was saved.
    """
    h = hashlib.sha256()

    def feed(value: Any) -> None:
        if isinstance(value, torch.Tensor):
            t = value.detach().to("cpu").contiguous()
            h.update(f"T{t.dtype}{tuple(t.shape)}".encode())
            h.update(t.numpy().tobytes())
        elif isinstance(value, Mapping):
            h.update(f"D{len(value)}".encode())
            for k in sorted(value, key=repr):
                h.update(repr(k).encode())
                feed(value[k])
        elif isinstance(value, list | tuple):
            h.update(f"L{len(value)}".encode())
            for v in value:
                feed(v)
        else:
            h.update(f"V{value!r}".encode())

    feed({k: v for k, v in state.items() if k != "digest"})
    return h.hexdigest()


def _load_state(path: Path) -> dict[str, Any]:
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises many kinds for a damaged file
        raise DataError(f"{path} is not a readable DBox training state: {load_failure(e)}") from None
    if not isinstance(state, dict) or not isinstance(state.get("settings"), dict):
        raise DataError(f"{path} is not a DBox training state (got {type(state).__name__})")
    missing = [k for k in ("model", "optimizer", "rng", "step", "best", "settings") if k not in state]
    if missing:
        raise DataError(f"{path} is not a DBox training state", [f"missing keys: {', '.join(missing)}"])
    # States saved before the digest have none; a state with one must match it.
    if "digest" in state and state["digest"] != _state_digest(state):
        raise DataError(
            f"{path} has been damaged since it was saved (its contents no longer match their SHA-256); "
            "start the run again in a new --out"
        )
    return dict(state)
