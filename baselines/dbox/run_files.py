"""The files of a DBox training run folder: the resumable state, the weights, their records, the log.

``last.pt`` (the whole training state, with the SHA-256 of its contents), ``dbox_<config>.pt``
and its per-set siblings (state dicts in the original release's layout, float32), the
JSON record beside each, and ``log.jsonl`` (one line per validation check). Every write
is atomic; :mod:`.train` says what each file holds.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch
from odmd_bench_baselines.dbox.configs import TrainConfig
from odmd_bench_baselines.dbox.graphs import plain_optimizer_state
from odmd_bench_baselines.dbox.kernels import cpu_kernels
from odmd_bench_baselines.dbox.loading import load_failure
from odmd_bench_baselines.dbox.model import DBox

import odmd_bench
from odmd_bench import DataError, atomic_path, atomic_write, file_sha256

STATE_FILE = "last.pt"


def original_state_dict(model: DBox) -> dict[str, torch.Tensor]:
    """The model's parameters in the original release's layout, float32, on the CPU."""
    return {k: v.detach().to("cpu", torch.float32).clone() for k, v in model.state_dict().items()}


def append_log(path: Path, entry: Mapping[str, Any]) -> None:
    """Add one line to the log, dropping lines of checks a resumed run repeats."""
    lines = path.read_text(encoding="utf-8").splitlines() if path.exists() else []
    kept = [line for line in lines if json.loads(line)["step"] < entry["step"]]
    with atomic_write(path, "w") as fh:
        fh.write("".join(line + "\n" for line in kept) + json.dumps(dict(entry)) + "\n")


def write_weights(model: DBox, path: Path) -> None:
    """The model's state dict at ``path`` (:func:`original_state_dict`), atomically."""
    with atomic_write(path) as fh:
        torch.save(original_state_dict(model), fh)


def write_record(
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

    ``launch``: processes, batch per process, backend and devices (:func:`.loop.launch_record`).
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
        "cpu_kernels": cpu_kernels(),
        "precision": settings.get("precision", "fp32"),
        "data": settings.get("data", "host"),
        **dict(launch or {}),
        "weights_sha256": file_sha256(weights) if weights.exists() else None,
    }
    with atomic_write(weights.with_suffix(".json"), "w") as fh:
        fh.write(json.dumps(record, indent=2) + "\n")


def save_state(
    path: Path,
    model: DBox,
    optimizer: torch.optim.Optimizer,
    rng: np.random.Generator,
    step: int,
    best: Mapping[str, Any],
    settings: Mapping[str, Any],
) -> None:
    """The resumable training state at ``path`` (``last.pt``), with its digest, atomically."""
    state = {
        "model": model.state_dict(),
        "optimizer": plain_optimizer_state(optimizer),
        "rng": json.dumps(rng.bit_generator.state),
        "step": step,
        "best": json.dumps(best),
        "settings": dict(settings),
    }
    state["digest"] = state_digest(state)
    with atomic_path(path) as tmp:
        torch.save(state, tmp)


def state_digest(state: Mapping[str, Any]) -> str:
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


def load_state(path: Path) -> dict[str, Any]:
    """A saved training state, its keys and digest checked.

    Raises:
        DataError: the file is not a readable, complete or intact training state.
    """
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
    if "digest" in state and state["digest"] != state_digest(state):
        raise DataError(
            f"{path} has been damaged since it was saved (its contents no longer match their SHA-256); "
            "start the run again in a new --out"
        )
    return dict(state)
