"""A registered method run on a user's own sequences (:mod:`odmd_bench.predict.sequences`).

:func:`predict_sequences` gives each sequence's depth at its last observation, choosing
observations evenly for a method built for a fixed number of them
(:func:`select_observations`); :func:`format_depths` writes the result as the CSV that
``odmd-bench predict`` writes, with the percent error where the truth is known.

The rooms: :mod:`~odmd_bench.predict.run` the run, :mod:`~odmd_bench.predict.observations`
which observations a method gets, :mod:`~odmd_bench.predict.fallbacks` which sequences
fell back, :mod:`~odmd_bench.predict.checks` the checks and warnings, and
:mod:`~odmd_bench.predict.sequences` the reader.
"""

from __future__ import annotations

from odmd_bench.predict.checks import MIN_FORWARD_SHARE, SHAPE_TOLERANCE, forward_share, shape_warning
from odmd_bench.predict.fallbacks import LOCATE_RUNS, locate_fallbacks
from odmd_bench.predict.observations import (
    MISSING,
    Missing,
    observation_indices,
    omit_missing,
    select_observations,
)
from odmd_bench.predict.run import SequenceDepths, format_depths, method_observations, predict_sequences

__all__ = [
    "LOCATE_RUNS",
    "MISSING",
    "MIN_FORWARD_SHARE",
    "SHAPE_TOLERANCE",
    "Missing",
    "SequenceDepths",
    "format_depths",
    "forward_share",
    "locate_fallbacks",
    "method_observations",
    "observation_indices",
    "omit_missing",
    "predict_sequences",
    "select_observations",
    "shape_warning",
]
