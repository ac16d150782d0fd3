"""DBox (Griffin and Corso, CVPR 2021): an LSTM with peepholes over the observations.

``predict(examples)`` runs the shipped weights of a training configuration
(``config=``: ``p``, ``abs``, ``ns`` for x,y,z camera motion; ``p-z``, ``ns-z``,
``abs-z`` for z-axis motion only). The default follows the data (:func:`default_config`):
``p-z`` for the ``odms-detection`` benchmark or any z-only camera motion, ``p`` otherwise,
so the x,y,z model never runs on z-only data unless asked for by name.
``selection="per-set"`` runs the paper's per-set selection (one checkpoint per set,
each chosen on that set's val score) on the set named in ``examples.attrs["set"]``.
A configuration's weights are selected on the val split of the benchmark family they
run on when such weights ship: ``p-z`` (selected on ODMS-detection val) also ships
checkpoints of the same kind of training runs selected on ODMD val,
``weights/selected-on-odmd-v1/`` (overall and one per ODMD set), which run on the ODMD
benchmarks (the paper selects its Table 1 rows on ODMD val, overall; its Table 2 rows on
ODMS val, per set). Per-set files are always those beside the overall file the data's
benchmark selects.
``predict(examples, weights=FILE)`` runs any checkpoint in the original release's layout
(a state dict with keys ``W``, ``U``, ``bias``, ``V``, ``linears.0.weight`` ...
``linears.6.bias``), such as the release's ``DBox_pretrained_paper.pt``.

Every checkpoint is hashed before torch reads it (:func:`verify_weights`): a shipped one
must match the ``weights_sha256`` of the JSON record beside it; a user's file must match
its record when one is beside it, or ``weights_sha256=`` when given; :func:`provenance`
returns the hash checked, for the predictions' provenance. Files are then read
with ``torch.load(weights_only=True)`` (no code from a file is run) and checked key by key.

Importing this package does not import torch; the functions do.
"""

from __future__ import annotations

from odmd_bench_baselines.dbox.choice import (
    SELECTIONS,
    Z_ONLY_BENCHMARKS,
    Z_ONLY_RATIO,
    default_config,
    is_z_only,
    resolve_weights,
    selection_benchmark,
)
from odmd_bench_baselines.dbox.configs import OBSERVATIONS
from odmd_bench_baselines.dbox.loading import check_state_dict, load_failure, load_model
from odmd_bench_baselines.dbox.method import OPTIONS, predict, predict_report, provenance
from odmd_bench_baselines.dbox.weights import (
    CONFIGS,
    DEFAULT_WEIGHTS,
    MAX_WEIGHTS_BYTES,
    VAL_BENCHMARK,
    WEIGHTS_DIR,
    per_set_names,
    per_set_path,
    shipped,
    verify_weights,
    weights_path,
)

__all__ = [
    "OPTIONS",
    "CONFIGS",
    "DEFAULT_WEIGHTS",
    "MAX_WEIGHTS_BYTES",
    "OBSERVATIONS",
    "SELECTIONS",
    "VAL_BENCHMARK",
    "WEIGHTS_DIR",
    "Z_ONLY_BENCHMARKS",
    "Z_ONLY_RATIO",
    "check_state_dict",
    "default_config",
    "is_z_only",
    "load_failure",
    "load_model",
    "per_set_names",
    "per_set_path",
    "predict",
    "predict_report",
    "provenance",
    "resolve_weights",
    "selection_benchmark",
    "shipped",
    "verify_weights",
    "weights_path",
]
