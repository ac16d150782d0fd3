"""DBox guard: DBox ``p-z`` with an inference step for the errors of real detectors (issue 37).

On z-only data (ODMS), each example's wrong start (one to five boxes of something else,
found by the width falling below ``tau`` times the previous one) is repaired by the
pinhole extrapolation of the other boxes; the shipped DBox ``p-z`` checkpoint runs on
the repaired boxes (the set's own where one ships, as ``selection="per-set"``); its depth
is blended with Box_LS's (weight ``alpha``) and capped at ``cap`` times the camera travel.
The parameters of each set were chosen on ODMS-detection val only
(``parameters.json``, written by :mod:`odmd_bench_baselines.dbox_guard.select`; the
pre-registration and the analysis: docs/odms-guard.md).

Importing this package does not import torch; the predictions do (through DBox).
"""

from __future__ import annotations

from odmd_bench_baselines.dbox_guard.method import (
    PARAMETERS_FILE,
    Parameters,
    load_parameters,
    predict,
    predict_report,
)
from odmd_bench_baselines.dbox_guard.steps import MAX_RUN, blend, cap, flag_wrong_starts, repair, travel

__all__ = [
    "MAX_RUN",
    "PARAMETERS_FILE",
    "Parameters",
    "blend",
    "cap",
    "flag_wrong_starts",
    "load_parameters",
    "predict",
    "predict_report",
    "repair",
    "travel",
]
