"""What every strict KITTI reader shares: a file's text, a located finite number, the refusal naming every problem."""

from __future__ import annotations

import math
from pathlib import Path

from odmd_bench.errors import ImportRefused
from odmd_bench.inputs.problems import Problems, show
from odmd_bench.inputs.records import NONFINITE_CELL, NUMBER

#: The largest text file read (the largest label file of KITTI tracking is about 1 MB).
MAX_FILE_BYTES = 64 * 2**20


def read_text(path: Path) -> str:
    """The text of ``path`` (ASCII or UTF-8), or :class:`ImportRefused` saying why not."""
    try:
        with path.open("rb") as fh:
            data = fh.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise ImportRefused(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ImportRefused(f"{path}: a folder, not a file") from None
    except OSError as e:
        raise ImportRefused(f"{path}: cannot read ({e.strerror})") from None
    if len(data) > MAX_FILE_BYTES:
        raise ImportRefused(f"{path}: larger than {MAX_FILE_BYTES // 2**20} MiB; not a KITTI file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ImportRefused(f"{path}: not text (byte {e.start} is not UTF-8)") from None


def number(cell: str, problems: Problems, where: str, what: str) -> float:
    """``cell`` as a finite float; adds a located problem and returns NaN if it is not one."""
    if NUMBER.fullmatch(cell):
        v = float(cell)
        if math.isfinite(v):
            return v
        problems.add(f"{what}: a number too large for a float", f"{where} ({show(cell)})")
    elif NONFINITE_CELL.fullmatch(cell):
        problems.add(f"{what}: not a finite number", f"{where} ({show(cell)})")
    else:
        problems.add(f"{what}: not a number", f"{where} ({show(cell)})")
    return math.nan


def refuse(path: Path, problems: Problems, what: str) -> None:
    """Raise :class:`ImportRefused` naming every problem found in ``path``, if any: "not a ``what``"."""
    if problems:
        raise ImportRefused(f"{path}: not a {what}", problems.lines())
