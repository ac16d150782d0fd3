"""DBox's training configurations and the network's sizes (no torch).

The lowest module of the DBox package: the kernels (:mod:`.kernels`), the network
(:mod:`.model`), the weights registry (:mod:`.weights`) and the training loop
(:mod:`.train`) all read these, and it imports none of them.
"""

from __future__ import annotations

from dataclasses import dataclass

from odmd_bench import UsageError

#: Observations per example the network takes (its input layer is sized for 10).
OBSERVATIONS = 10
#: Numbers per observation: x, y, w, h, dcx, dcy, dcz.
N_FEATURES = 7
#: The LSTM's hidden size, the fully connected layers' width and their number (before the output).
HIDDEN = 128
FC_WIDTH = 256
N_FC = 6


@dataclass(frozen=True)
class TrainConfig:
    """One of the paper's training configurations.

    Attributes:
        name: ``p``, ``ns``, ``abs``, ``p-z``, ``ns-z`` or ``abs-z``.
        preset: generator preset (``odmd`` or ``odms``).
        perturbation: generator perturbation (``normal`` or ``both``).
        formulation: ``rel`` (f_Rel) or ``abs`` (f_Abs).
        val_benchmark: benchmark whose ``val`` split selects the model.
    """

    name: str
    preset: str
    perturbation: str
    formulation: str
    val_benchmark: str


CONFIGS: dict[str, TrainConfig] = {
    "p": TrainConfig("p", "odmd", "both", "rel", "odmd-v1"),
    "ns": TrainConfig("ns", "odmd", "normal", "rel", "odmd-v1"),
    "abs": TrainConfig("abs", "odmd", "both", "abs", "odmd-v1"),
    # z-only motion for ODMS (the paper's DBox_p^z, DBox_NS^z, DBox_Abs^z); selected on
    # the ODMS-detection val sets (imported).
    "p-z": TrainConfig("p-z", "odms", "both", "rel", "odms-detection"),
    "ns-z": TrainConfig("ns-z", "odms", "normal", "rel", "odms-detection"),
    "abs-z": TrainConfig("abs-z", "odms", "both", "abs", "odms-detection"),
}


def get_config(name: str) -> TrainConfig:
    """The training configuration called ``name``."""
    if name not in CONFIGS:
        raise UsageError(f"unknown DBox config {name!r}; expected one of {', '.join(CONFIGS)}")
    return CONFIGS[name]


__all__ = ["CONFIGS", "FC_WIDTH", "HIDDEN", "N_FC", "N_FEATURES", "OBSERVATIONS", "TrainConfig", "get_config"]
