"""Training on several processes: the distributed setup of ``train-dbox``, in one place.

``torchrun`` (``python -m torch.distributed.run``) starts the processes and tells each
who it is through the environment: ``RANK`` (0 ... ``WORLD_SIZE`` - 1 over all
machines), ``LOCAL_RANK`` (its index on this machine, which picks its GPU),
``WORLD_SIZE``, ``MASTER_ADDR`` and ``MASTER_PORT``. :func:`setup` reads them and joins
the process group: ``gloo`` on the CPU, ``nccl`` on CUDA. Without them (a plain
``odmd-bench train-dbox``), or with ``WORLD_SIZE=1``, nothing distributed happens.

The global batch of a step is the same examples whatever the number of processes: every
process draws the whole batch from the run's generator (all start from the same seed and
advance it alike) and trains on its own rows, :func:`shard` (process ``r`` of ``N`` takes
rows ``r B / N`` to ``(r + 1) B / N``): no example is repeated or skipped, and the data of
a step depend only on the seed and the step. DistributedDataParallel averages the
gradients, so ``N`` processes compute the gradient of one process's step to float
rounding.

A failed process stops the run: torchrun ends the others when one exits with an error,
and a collective operation that waits longer than ``timeout_s`` (a process that hangs
rather than dies, or a machine that vanishes) raises :class:`DistributedError` in the
processes still waiting, naming their rank and the step.

This module imports torch.
"""

from __future__ import annotations

import contextlib
import datetime
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NoReturn

import torch
import torch.distributed as tdist

from odmd_bench import OdmdError, UsageError

#: Seconds a collective operation (a gradient all-reduce, a barrier) waits for the
#: other processes before the run stops with an error (``--dist-timeout``).
DEFAULT_TIMEOUT_S = 600.0
#: The variables torchrun sets in every process it starts.
TORCHRUN_VARIABLES = ("RANK", "LOCAL_RANK", "WORLD_SIZE")


class DistributedError(OdmdError, RuntimeError):
    """A distributed run stopped: another process failed, hung or could not be reached."""


@dataclass(frozen=True)
class DistContext:
    """Where this process stands in a run.

    Attributes:
        rank: this process's rank, 0 ... ``world_size - 1`` (0 writes everything).
        world_size: number of processes (1: an ordinary run).
        local_rank: its index on this machine (its GPU on CUDA).
        backend: ``gloo``, ``nccl`` or None (one process).
        device: the device this process trains on.
        timeout_s: seconds a collective waits before the run stops.
    """

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0
    backend: str | None = None
    device: torch.device = torch.device("cpu")
    timeout_s: float = DEFAULT_TIMEOUT_S

    @property
    def is_main(self) -> bool:
        """Whether this process writes (validation, weights, records, log, state, progress)."""
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        """Whether there are other processes."""
        return self.world_size > 1


def launch_ranks(env: Mapping[str, str] | None = None) -> tuple[int, int, int]:
    """``(rank, world_size, local_rank)`` from torchrun's variables; ``(0, 1, 0)`` without them.

    Raises:
        UsageError: the variables are partly set or not integers in range, each problem named.
    """
    env = os.environ if env is None else env
    given = {k: env[k] for k in TORCHRUN_VARIABLES if k in env}
    if not given:
        return 0, 1, 0
    problems = [f"{k} is not set" for k in TORCHRUN_VARIABLES if k not in given]
    values: dict[str, int] = {}
    for k, v in given.items():
        try:
            values[k] = int(v)
        except ValueError:
            problems.append(f"{k}={v!r} is not an integer")
    if not problems:
        rank, world, local = values["RANK"], values["WORLD_SIZE"], values["LOCAL_RANK"]
        if world < 1:
            problems.append(f"WORLD_SIZE={world} must be at least 1")
        elif not 0 <= rank < world:
            problems.append(f"RANK={rank} must be in [0, {world - 1}] for WORLD_SIZE={world}")
        if local < 0:
            problems.append(f"LOCAL_RANK={local} must not be negative")
    if problems:
        raise UsageError(
            "the distributed launch variables are inconsistent (start several processes with torchrun)",
            problems,
        )
    return values["RANK"], values["WORLD_SIZE"], values["LOCAL_RANK"]


def resolve_device(device: str, local_rank: int = 0) -> torch.device:
    """``auto`` (CUDA when available, else CPU), ``cpu`` or ``cuda`` (this process's GPU)."""
    if device == "auto":
        device = "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cpu":
        return torch.device("cpu")
    if device == "cuda":
        if not torch.cuda.is_available():
            raise UsageError("--device cuda was asked for but torch sees no CUDA device; use auto or cpu")
        count = torch.cuda.device_count()
        if local_rank >= count:
            raise UsageError(
                f"process {local_rank} on this machine has no GPU of its own: torch sees {count}; "
                f"start at most {count} processes per machine (torchrun --nproc_per_node {count})"
            )
        return torch.device("cuda", local_rank)
    raise UsageError(f"unknown device {device!r}; expected one of auto, cpu, cuda")


def setup(device: str = "auto", timeout_s: float = DEFAULT_TIMEOUT_S) -> DistContext:
    """Join the run's process group when torchrun started this process; else a one-process context.

    Args:
        device: ``auto``, ``cpu`` or ``cuda``; on CUDA each process takes the GPU of its
            ``LOCAL_RANK``.
        timeout_s: seconds a collective operation waits before the run stops.

    Raises:
        UsageError: bad launch variables, a device that is not there, a bad timeout.
        DistributedError: the process group could not be joined.
    """
    if not timeout_s > 0:
        raise UsageError(f"the collective timeout must be positive, got {timeout_s!r} s")
    rank, world, local = launch_ranks()
    dev = resolve_device(device, local if world > 1 else 0)
    if world == 1:
        return DistContext(device=dev, timeout_s=timeout_s)
    if tdist.is_initialized():  # joined already (a test, or a caller that set it up)
        backend = str(tdist.get_backend())
    else:
        backend = "nccl" if dev.type == "cuda" else "gloo"
        if dev.type == "cuda":
            torch.cuda.set_device(dev)
        try:
            tdist.init_process_group(
                backend,
                timeout=datetime.timedelta(seconds=timeout_s),
                device_id=dev if dev.type == "cuda" else None,
            )
        except (RuntimeError, ValueError) as e:
            raise DistributedError(
                f"process {rank} of {world} could not join the run's process group ({backend})",
                [
                    _first_line(e),
                    "check MASTER_ADDR / MASTER_PORT (torchrun --rdzv-endpoint) and the network",
                ],
            ) from None
    return DistContext(rank, world, local, backend, dev, timeout_s)


def finish(ctx: DistContext) -> None:
    """Wait until every process has finished its run (a barrier; a no-op for one process).

    Called after a run that ended normally, before :func:`cleanup`: a failed run skips it,
    so that no process waits on one that is gone.
    """
    if ctx.distributed and tdist.is_initialized():
        tdist.barrier()


def cleanup(ctx: DistContext) -> None:
    """Leave the process group (a no-op for one process)."""
    if ctx.distributed and tdist.is_initialized():
        tdist.destroy_process_group()


def leave() -> NoReturn:
    """End this torchrun process after a run that finished: exit handlers, flush, exit 0.

    Skips only the C++ runtime's teardown at interpreter exit. There, about one run in
    twenty on a busy 2-core machine (2 of 40, and 1 of 12, in a loop of the two-process
    test), process 1 aborted after the run was done, its group left and its exit handlers
    run ("terminate called without an active exception", no Python frame left), and
    torchrun then reported the whole run as failed. Every file is written and closed by
    then; Python's exit handlers (``atexit``) still run here.
    """
    import atexit

    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed or broken pipe: nothing to keep
            stream.flush()
    os._exit(0)


def shard(n: int, rank: int, world_size: int) -> slice:
    """The rows of a batch of ``n`` that process ``rank`` of ``world_size`` trains on.

    Contiguous, in rank order, sizes differing by at most one: together they are the
    batch, each row once.

    Example:
        >>> [shard(10, r, 3) for r in range(3)]
        [slice(0, 3, None), slice(3, 6, None), slice(6, 10, None)]
    """
    return slice(rank * n // world_size, (rank + 1) * n // world_size)


def all_sum(ctx: DistContext, values: list[float]) -> list[float]:
    """The sums of ``values`` over all processes (``values`` itself for one process)."""
    if not ctx.distributed:
        return values
    t = torch.tensor(values, dtype=torch.float64, device=ctx.device)
    tdist.all_reduce(t)
    return [float(v) for v in t.tolist()]


def collective_failure(ctx: DistContext, step: int, e: BaseException) -> DistributedError:
    """The error a process reports when a collective operation of step ``step`` failed."""
    return DistributedError(
        f"process {ctx.rank} of {ctx.world_size} stopped at step {step}: the other processes did not "
        f"answer within {ctx.timeout_s:g} s (--dist-timeout) or one of them failed; the one that "
        "failed first reports its own error (torchrun names it)",
        [_first_line(e)],
    )


def _first_line(e: BaseException) -> str:
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0] if text else ''}"[:300]
