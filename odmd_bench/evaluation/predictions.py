"""Writing the predictions format (docs/format.md, "Predictions").

Reading it is :mod:`odmd_bench.evaluation.parse`'s job, checking it against the sets
:mod:`odmd_bench.evaluation.coverage`'s.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping

import numpy as np

from odmd_bench.data.atomic import atomic_write
from odmd_bench.data.registry import check_split
from odmd_bench.errors import UsageError

COLUMNS = ("split", "set", "index", "depth")


def format_predictions(split: str, depths: Mapping[str, np.ndarray], benchmark: str | None = None) -> str:
    """The CSV text for ``{set name: (N,) depths}`` of one split.

    Depths are written with ``repr`` precision (17 significant digits), so a file read
    back gives exactly the same floats.
    """
    check_split(split)
    buf = io.StringIO()
    header = list(COLUMNS) + (["benchmark"] if benchmark else [])
    buf.write(",".join(header) + "\n")
    for set_name, values in depths.items():
        arr = np.asarray(values, dtype=np.float64)
        if arr.ndim != 1:
            raise UsageError(f"depths for set {set_name!r} must be 1-D, got shape {arr.shape}")
        tail = f",{benchmark}" if benchmark else ""
        for i, v in enumerate(arr.tolist()):
            buf.write(f"{split},{set_name},{i},{v!r}{tail}\n")
    return buf.getvalue()


def write_predictions(
    path: str | os.PathLike[str],
    split: str,
    depths: Mapping[str, np.ndarray],
    benchmark: str | None = None,
) -> None:
    """Write a predictions CSV atomically (see :func:`format_predictions`)."""
    text = format_predictions(split, depths, benchmark)
    with atomic_write(path, "w") as fh:
        fh.write(text)
